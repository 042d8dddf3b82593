/* recon/cnn/ffdnet.c — FFDNet inference (see ffdnet.h). */
#include "recon/cnn/ffdnet.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "recon/cnn/conv.h"
#include "recon/cnn/weights.h"

#define FFDNET_MAX_LAYERS 32
#define BN_EPS 1e-5 /* PyTorch's BatchNorm2d default, which the IPOL models were trained with */

struct cnn_ffdnet {
    int c, features, layers;
    cnn_conv *conv[FFDNET_MAX_LAYERS];
};

struct cnn_ffdnet_plan {
    const cnn_ffdnet *net;
    int w, h, w2, h2; /* image; half-size grid (after padding to even) */
    int threads;
    float *buf;       /* three activations: input (5c), two of F features, output reuses one of them */
    size_t bytes;
    cnn_act in, a, b;
    cnn_conv_ws *ws;
};

static const char *key_of(char *buf, size_t n, int layer, const char *what)
{
    snprintf(buf, n, "intermediate_dncnn.itermediate_dncnn.%d.%s", layer, what);
    return buf;
}

/* Conv `idx` (+ batch norm at idx + 1 when bn), folded into weights and bias. */
static int load_layer(const cnn_weights *w, int idx, int cin, int cout, int bn, int relu, cnn_conv **out,
                      sci_error *err)
{
    char key[128];
    const cnn_tensor *t, *g = NULL, *be = NULL, *mu = NULL, *var = NULL;
    const long ws[4] = {cout, cin, 3, 3}, cs[1] = {cout};
    int rc = cnn_weights_expect(w, key_of(key, sizeof key, idx, "weight"), 4, ws, &t, err);
    if (rc == 0 && bn) {
        if ((rc = cnn_weights_expect(w, key_of(key, sizeof key, idx + 1, "weight"), 1, cs, &g, err)) == 0 &&
            (rc = cnn_weights_expect(w, key_of(key, sizeof key, idx + 1, "bias"), 1, cs, &be, err)) == 0 &&
            (rc = cnn_weights_expect(w, key_of(key, sizeof key, idx + 1, "running_mean"), 1, cs, &mu, err)) == 0)
            rc = cnn_weights_expect(w, key_of(key, sizeof key, idx + 1, "running_var"), 1, cs, &var, err);
    }
    if (rc < 0)
        return rc;
    float *wf = malloc(t->count * sizeof *wf), *bf = calloc((size_t)cout, sizeof *bf);
    if (!wf || !bf) {
        free(wf);
        free(bf);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", w->source);
    }
    memcpy(wf, t->data, t->count * sizeof *wf);
    for (int k = 0; bn && k < cout; k++) {
        if (!(var->data[k] >= 0)) {
            free(wf);
            free(bf);
            return sci_error_set(err, SCI_EFORMAT, "%s: %s[%d] = %g: a variance must be >= 0", w->source,
                                 key_of(key, sizeof key, idx + 1, "running_var"), k, var->data[k]);
        }
        const double s = g->data[k] / sqrt((double)var->data[k] + BN_EPS);
        for (size_t i = 0; i < (size_t)cin * 9; i++)
            wf[(size_t)k * cin * 9 + i] = (float)(wf[(size_t)k * cin * 9 + i] * s);
        bf[k] = (float)(be->data[k] - mu->data[k] * s);
    }
    rc = cnn_conv_new(cin, cout, wf, bn ? bf : NULL, relu ? CNN_RELU : CNN_LINEAR, out, err);
    free(wf);
    free(bf);
    return rc;
}

int cnn_ffdnet_load(const char *path, cnn_ffdnet **out, sci_error *err)
{
    *out = NULL;
    cnn_weights *w = NULL;
    int rc = cnn_weights_read(path, &w, err);
    if (rc < 0)
        return rc;
    char key[128];
    const cnn_tensor *first = cnn_weights_find(w, key_of(key, sizeof key, 0, "weight"));
    cnn_ffdnet *net = calloc(1, sizeof *net);
    if (!net) {
        cnn_weights_free(w);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
    }
    if (!first || first->ndim != 4 || (first->shape[1] != 5 && first->shape[1] != 15)) {
        rc = sci_error_set(err, SCI_EFORMAT,
                           "%s: not an FFDNet state dict (tensor %s: want [F, 5 or 15, 3, 3], the grey or colour "
                           "network of the IPOL FFDNet that PnP-SCI uses)", path, key);
        goto fail;
    }
    net->c = (int)first->shape[1] / 5;
    net->features = (int)first->shape[0];
    /* Layer i ≥ 1 is a conv at index 3i − 1 with batch norm at 3i when that exists; the last has none. */
    int idx = 2, n = 1;
    while (cnn_weights_find(w, key_of(key, sizeof key, idx + 1, "running_mean")) && n < FFDNET_MAX_LAYERS - 1)
        idx += 3, n++;
    net->layers = n + 1;
    if ((rc = load_layer(w, 0, 5 * net->c, net->features, 0, 1, &net->conv[0], err)) < 0)
        goto fail;
    for (int i = 1; i < n; i++)
        if ((rc = load_layer(w, 3 * i - 1, net->features, net->features, 1, 1, &net->conv[i], err)) < 0)
            goto fail;
    if ((rc = load_layer(w, idx, net->features, 4 * net->c, 0, 0, &net->conv[n], err)) < 0)
        goto fail;
    cnn_weights_free(w);
    *out = net;
    return 0;
fail:
    cnn_weights_free(w);
    cnn_ffdnet_free(net);
    return rc;
}

void cnn_ffdnet_free(cnn_ffdnet *net)
{
    if (!net)
        return;
    for (int i = 0; i < FFDNET_MAX_LAYERS; i++)
        cnn_conv_free(net->conv[i]);
    free(net);
}

int cnn_ffdnet_channels(const cnn_ffdnet *net) { return net->c; }
int cnn_ffdnet_layers(const cnn_ffdnet *net) { return net->layers; }
int cnn_ffdnet_features(const cnn_ffdnet *net) { return net->features; }

double cnn_ffdnet_macs(const cnn_ffdnet *net, int w, int h)
{
    const double px = (double)((w + 1) / 2) * ((h + 1) / 2), f = net->features, c = net->c;
    return px * 9 * (5 * c * f + (net->layers - 2) * f * f + f * 4 * c);
}

int cnn_ffdnet_plan_new(const cnn_ffdnet *net, int w, int h, int threads, cnn_ffdnet_plan **out, sci_error *err)
{
    *out = NULL;
    if (w < 1 || h < 1 || w > 65536 || h > 65536)
        return sci_error_set(err, -EINVAL, "ffdnet: bad image size %dx%d", w, h);
    cnn_ffdnet_plan *p = calloc(1, sizeof *p);
    if (!p)
        return sci_error_set(err, -ENOMEM, "ffdnet: out of memory");
    p->net = net, p->w = w, p->h = h, p->w2 = (w + 1) / 2, p->h2 = (h + 1) / 2;
    p->threads = threads > 0 ? threads : omp_get_max_threads();
    const int f = net->features, cin = 5 * net->c;
    const size_t nin = cnn_act_floats(cin, p->h2, p->w2), nf = cnn_act_floats(f, p->h2, p->w2);
    p->bytes = (nin + 2 * nf) * sizeof(float);
    p->buf = calloc(nin + 2 * nf, sizeof(float));
    p->ws = cnn_conv_ws_new(f > cin ? f : cin, p->threads);
    if (!p->buf || !p->ws) {
        cnn_ffdnet_plan_free(p);
        return sci_error_set(err, -ENOMEM, "ffdnet: out of memory for %dx%d images", w, h);
    }
    cnn_act_init(&p->in, cin, p->h2, p->w2, p->buf);
    cnn_act_init(&p->a, f, p->h2, p->w2, p->buf + nin);
    cnn_act_init(&p->b, f, p->h2, p->w2, p->buf + nin + nf);
    cnn_blas_single_thread();
    *out = p;
    return 0;
}

void cnn_ffdnet_plan_free(cnn_ffdnet_plan *p)
{
    if (!p)
        return;
    cnn_conv_ws_free(p->ws);
    free(p->buf);
    free(p);
}

size_t cnn_ffdnet_plan_bytes(const cnn_ffdnet_plan *p) { return p->bytes; }
void cnn_ffdnet_plan_portable(cnn_ffdnet_plan *p, int on) { cnn_conv_ws_portable(p->ws, on); }
const char *cnn_ffdnet_plan_kernel(const cnn_ffdnet_plan *p) { return cnn_conv_kernel(p->ws); }

void cnn_ffdnet_denoise(cnn_ffdnet_plan *p, const float *in, float sigma, float *out)
{
    const cnn_ffdnet *net = p->net;
    const int c = net->c, w = p->w, h = p->h;
    /* noise map, then the four phases of each colour; a missing last row or column repeats the one before */
    for (int ch = 0; ch < c; ch++)
        for (int y = 0; y < p->h2; y++)
            for (int x = 0; x < p->w2; x++)
                *cnn_act_at(&p->in, ch, y, x) = sigma;
    for (int ch = 0; ch < c; ch++)
        for (int k = 0; k < 4; k++) {
            const float *src = in + (size_t)ch * w * h;
            for (int y = 0; y < p->h2; y++) {
                const int sy = 2 * y + k / 2 < h ? 2 * y + k / 2 : h - 1;
                float *dst = cnn_act_at(&p->in, c + 4 * ch + k, y, 0);
                for (int x = 0; x < p->w2; x++) {
                    const int sx = 2 * x + k % 2 < w ? 2 * x + k % 2 : w - 1;
                    dst[x] = src[(size_t)sy * w + sx];
                }
            }
        }
    cnn_act *cur = &p->in, *next = &p->a;
    for (int i = 0; i < net->layers; i++) {
        next->c = cnn_conv_cout(net->conv[i]);
        cnn_conv_run(net->conv[i], cur, next, p->ws);
        cur = next;
        next = cur == &p->a ? &p->b : &p->a;
    }
    for (int ch = 0; ch < c; ch++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const size_t i = (size_t)ch * w * h + (size_t)y * w + x;
                out[i] = in[i] - *cnn_act_at(cur, 4 * ch + (y % 2) * 2 + x % 2, y / 2, x / 2);
            }
}
