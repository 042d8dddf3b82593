#include "sim/masks.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "io/image.h"

static const char *const kinds[] = {"random", "shifting", "superpixel", "file", NULL};
static const char *const dirs[] = {"x", "y", NULL};

static int parse_dmd(const sci_json_doc *doc, const json_t *d, sim_mask_spec *s, sci_error *err)
{
    static const char *const allowed[] = {"width", "height", "scale", "offset", NULL};
    const char *p = "masks.dmd";
    long long dw = s->dmd_w, dh = s->dmd_h;
    int rc;
    if ((rc = sci_json_check_keys(doc, d, p, allowed, err)) < 0 ||
        (rc = sci_json_get_int(doc, d, p, "width", 0, 1, 65535, &dw, err)) < 0 ||
        (rc = sci_json_get_int(doc, d, p, "height", 0, 1, 65535, &dh, err)) < 0 ||
        (rc = sci_json_get_double(doc, d, p, "scale", 0, 1e-3, 1e3, &s->scale, err)) < 0)
        return rc;
    s->dmd_w = (int)dw;
    s->dmd_h = (int)dh;
    const json_t *o = json_object_get(d, "offset");
    if (o) {
        if (!json_is_array(o) || json_array_size(o) != 2 || !json_is_number(json_array_get(o, 0)) ||
            !json_is_number(json_array_get(o, 1)) || fabs(json_number_value(json_array_get(o, 0))) > 1e6 ||
            fabs(json_number_value(json_array_get(o, 1))) > 1e6)
            return sci_json_fail(doc, err, "masks.dmd.offset", "must be [x, y] in sensor pixels (within ±1e6)");
        s->off_x = json_number_value(json_array_get(o, 0));
        s->off_y = json_number_value(json_array_get(o, 1));
    }
    return 0;
}

int sim_masks_parse(const sci_json_doc *doc, const json_t *root, const char *base_dir, int w, int h,
                    sim_mask_spec *s, sci_error *err)
{
    static const char *const allowed[] = {"type", "density", "block", "step", "direction", "path", "dmd", NULL};
    memset(s, 0, sizeof *s);
    s->kind = SIM_MASK_RANDOM;
    s->density = 0.5;
    s->block = 4;
    s->step = 1;
    s->dir_y = 1;
    s->dmd_w = w;
    s->dmd_h = h;
    s->scale = 1;
    const json_t *m = json_object_get(root, "masks");
    if (!m)
        return 0;
    int rc, kind = 0, dir = 1;
    long long block = s->block, step = s->step;
    const char *path = NULL;
    if ((rc = sci_json_check_keys(doc, m, "masks", allowed, err)) < 0 ||
        (rc = sci_json_get_enum(doc, m, "masks", "type", 1, kinds, &kind, err)) < 0 ||
        (rc = sci_json_get_double(doc, m, "masks", "density", 0, 1e-6, 1, &s->density, err)) < 0 ||
        (rc = sci_json_get_int(doc, m, "masks", "block", 0, 1, 4096, &block, err)) < 0 ||
        (rc = sci_json_get_int(doc, m, "masks", "step", 0, -64, 64, &step, err)) < 0 ||
        (rc = sci_json_get_enum(doc, m, "masks", "direction", 0, dirs, &dir, err)) < 0 ||
        (rc = sci_json_get_string(doc, m, "masks", "path", kind == SIM_MASK_FILE, &path, err)) < 0)
        return rc;
    s->kind = (sim_mask_kind)kind;
    s->block = (int)block;
    s->step = (int)step;
    s->dir_y = dir;
    if (path) {
        if (path[0] != '/' && base_dir && *base_dir)
            snprintf(s->path, sizeof s->path, "%s/%s", base_dir, path);
        else
            snprintf(s->path, sizeof s->path, "%s", path);
    }
    const json_t *d = json_object_get(m, "dmd");
    if (d) {
        if ((rc = parse_dmd(doc, d, s, err)) < 0)
            return rc;
        s->mapped = !(s->dmd_w == w && s->dmd_h == h && s->scale == 1 && s->off_x == 0 && s->off_y == 0);
    }
    return 0;
}

static int load_file(const sim_mask_spec *s, int n, sci_cube **out, sci_error *err)
{
    sci_cube *c = NULL;
    int rc, bits = 32;
    size_t len = strlen(s->path);
    if (len > 5 && strcmp(s->path + len - 5, ".json") == 0)
        rc = sci_stack_read(s->path, &c, NULL, err);
    else {
        rc = sci_image_read(s->path, &c, &bits, err);
        if (rc == 0 && (bits == 8 || bits == 16))
            sci_cube_scale(c, (float)(1.0 / ((1 << bits) - 1)));
    }
    if (rc < 0)
        return rc;
    if (c->w != s->dmd_w || c->h != s->dmd_h || c->n < n) {
        rc = sci_error_set(err, SCI_ESHAPE, "%s: masks are %dx%dx%d, the scene needs %dx%dx%d (DMD size × frames)",
                           s->path, c->w, c->h, c->n, s->dmd_w, s->dmd_h, n);
        sci_cube_free(c);
        return rc;
    }
    size_t cnt = (size_t)c->w * c->h * (size_t)n;
    for (size_t i = 0; i < cnt; i++)
        if (!(c->data[i] >= 0 && c->data[i] <= 1)) {
            rc = sci_error_set(err, -EINVAL, "%s: mask value %g at index %zu is outside [0, 1]", s->path,
                               (double)c->data[i], i);
            sci_cube_free(c);
            return rc;
        }
    c->n = n; /* extra frames are ignored */
    *out = c;
    return 0;
}

static int make_dmd(const sim_mask_spec *s, int n, uint64_t seed, sci_cube **out, sci_error *err)
{
    if (s->kind == SIM_MASK_FILE)
        return load_file(s, n, out, err);
    int rc = sci_cube_new(out, s->dmd_w, s->dmd_h, n, err);
    if (rc < 0)
        return rc;
    sci_cube *c = *out;
    sci_rng rng;
    sci_rng_seed(&rng, seed, SIM_STREAM_MASKS);
    int dw = s->dmd_w, dh = s->dmd_h;
    switch (s->kind) {
    case SIM_MASK_RANDOM:
        for (size_t i = 0; i < sci_cube_count(c); i++)
            c->data[i] = sci_rng_uniform(&rng) < s->density ? 1.0f : 0.0f;
        break;
    case SIM_MASK_SUPERPIXEL: {
        int bw = (dw + s->block - 1) / s->block, bh = (dh + s->block - 1) / s->block;
        for (int k = 0; k < n; k++)
            for (int by = 0; by < bh; by++)
                for (int bx = 0; bx < bw; bx++) {
                    float v = sci_rng_uniform(&rng) < s->density ? 1.0f : 0.0f;
                    for (int y = by * s->block; y < dh && y < (by + 1) * s->block; y++)
                        for (int x = bx * s->block; x < dw && x < (bx + 1) * s->block; x++)
                            sci_cube_frame(c, k)[(size_t)y * dw + x] = v;
                }
        break;
    }
    case SIM_MASK_SHIFTING: {
        int span = abs(s->step) * (n - 1);
        int bw = dw + (s->dir_y ? 0 : span), bh = dh + (s->dir_y ? span : 0);
        float *base = malloc((size_t)bw * bh * sizeof *base);
        if (!base) {
            sci_cube_free(c);
            *out = NULL;
            return sci_error_set(err, -ENOMEM, "out of memory for a %dx%d shifting-mask pattern", bw, bh);
        }
        for (size_t i = 0; i < (size_t)bw * bh; i++)
            base[i] = sci_rng_uniform(&rng) < s->density ? 1.0f : 0.0f;
        /* M_k(x, y) = M_0(x − k·step, y): the pattern moves by step pixels per frame. */
        for (int k = 0; k < n; k++) {
            int sh = k * s->step, o = s->step >= 0 ? span : 0;
            for (int y = 0; y < dh; y++)
                for (int x = 0; x < dw; x++) {
                    int bx = s->dir_y ? x : x - sh + o;
                    int by = s->dir_y ? y - sh + o : y;
                    sci_cube_frame(c, k)[(size_t)y * dw + x] = base[(size_t)by * bw + bx];
                }
        }
        free(base);
        break;
    }
    default:
        break;
    }
    return 0;
}

/* Overlap length of [a0, a1) with [b0, b1). */
static double overlap(double a0, double a1, double b0, double b1)
{
    double lo = a0 > b0 ? a0 : b0, hi = a1 < b1 ? a1 : b1;
    return hi > lo ? hi - lo : 0;
}

int sim_masks_make(const sim_mask_spec *s, int w, int h, int n, uint64_t seed, sci_cube **out, sci_error *err)
{
    *out = NULL;
    sci_cube *dmd = NULL;
    int rc = make_dmd(s, n, seed, &dmd, err);
    if (rc < 0)
        return rc;
    if (!s->mapped) {
        *out = dmd;
        return 0;
    }
    sci_cube *c = NULL;
    if ((rc = sci_cube_new(&c, w, h, n, err)) < 0) {
        sci_cube_free(dmd);
        return rc;
    }
    /* Sensor pixel x spans mirror coordinates [(x − off)/scale, (x + 1 − off)/scale); the mapping is separable, so
     * the area weight of mirror (i, j) is the product of the two 1D overlaps. */
    double inv = 1 / s->scale;
#pragma omp parallel for schedule(static)
    for (int y = 0; y < h; y++) {
        double y0 = (y - s->off_y) * inv, y1 = (y + 1 - s->off_y) * inv;
        int j0 = (int)floor(y0), j1 = (int)ceil(y1);
        for (int x = 0; x < w; x++) {
            double x0 = (x - s->off_x) * inv, x1 = (x + 1 - s->off_x) * inv;
            int i0 = (int)floor(x0), i1 = (int)ceil(x1);
            for (int k = 0; k < n; k++) {
                double acc = 0;
                for (int j = j0 < 0 ? 0 : j0; j < j1 && j < s->dmd_h; j++) {
                    double wy = overlap(y0, y1, j, j + 1);
                    for (int i = i0 < 0 ? 0 : i0; i < i1 && i < s->dmd_w; i++)
                        acc += wy * overlap(x0, x1, i, i + 1) * sci_cube_frame(dmd, k)[(size_t)j * s->dmd_w + i];
                }
                sci_cube_frame(c, k)[(size_t)y * w + x] = (float)(acc / ((x1 - x0) * (y1 - y0)));
            }
        }
    }
    sci_cube_free(dmd);
    *out = c;
    return 0;
}
