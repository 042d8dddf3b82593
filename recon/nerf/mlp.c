/* recon/nerf/mlp.c — the SCINeRF-style MLP field (see mlp.h). */
#include "recon/nerf/mlp.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "recon/nerf/linear.h"
#include "recon/nerf/posenc.h"
#include "recon/nerf/shenc.h"

struct nerf_mlp {
    nerf_mlp_config cfg;
    nerf_hashgrid *grid;
    int E, Dd, W, F, Ch, Ci, depth, skip;
    int in[NERF_MLP_MAX_DEPTH];   /* fan-in of trunk layer l */
    int ldh[NERF_MLP_MAX_DEPTH];  /* row stride of the saved output of layer l (W, or W + E before the skip) */
    nerf_mlp_layout lo;
    size_t saved_per_point;
};

struct nerf_mlp_ws {
    int max_points, n_threads, n, dir_every;
    size_t bytes;
    float *mem;
    /* saved, max_points rows each */
    float *xin, *enc, *h[NERF_MLP_MAX_DEPTH], *sraw, *cin, *c1, *rgb, *denc;
    const float *dir; /* borrowed from the forward's caller until the backward */
    float **scratch, **tgrad;
    size_t scratch_floats;
};

nerf_mlp_config nerf_mlp_config_scinerf(void)
{
    nerf_mlp_config c = {
        .pos_enc = NERF_MLP_POS_FREQ, .pos_freqs = 10,
        .grid = {.n_levels = 16, .n_features = 2, .log2_table = 16, .base_res = 16, .finest_res = 1024},
        .depth = 8, .width = 256, .skip = 4, .density_act = NERF_ACT_RELU, .feature_dim = 256,
        .dir_enc = NERF_MLP_DIR_FREQ, .dir_freqs = 4, .sh_degree = 4, .color_hidden = 128,
        .aabb_min = {-1, -1, -1}, .aabb_max = {1, 1, 1}, .density_bias = 0.0f,
    };
    return c;
}

nerf_mlp_config nerf_mlp_config_hash(void)
{
    nerf_mlp_config c = nerf_mlp_config_scinerf();
    c.pos_enc = NERF_MLP_POS_HASH;
    c.depth = 2, c.width = 64, c.skip = -1, c.density_act = NERF_ACT_TRUNC_EXP, c.feature_dim = 15;
    c.dir_enc = NERF_MLP_DIR_SH, c.color_hidden = 64;
    return c;
}

int nerf_mlp_new(nerf_mlp **out, const nerf_mlp_config *c, sci_error *err)
{
    *out = NULL;
    if (c->pos_enc != NERF_MLP_POS_FREQ && c->pos_enc != NERF_MLP_POS_HASH)
        return sci_error_set(err, SCI_ECONFIG, "mlp: pos_enc %d is neither freq (0) nor hash (1)", (int)c->pos_enc);
    if (c->pos_enc == NERF_MLP_POS_FREQ && (c->pos_freqs < 1 || c->pos_freqs > 16))
        return sci_error_set(err, SCI_ECONFIG, "mlp: pos_freqs %d outside 1..16", c->pos_freqs);
    if (c->depth < 1 || c->depth > NERF_MLP_MAX_DEPTH)
        return sci_error_set(err, SCI_ECONFIG, "mlp: depth %d outside 1..%d", c->depth, NERF_MLP_MAX_DEPTH);
    if (c->width < 1 || c->width > 1024)
        return sci_error_set(err, SCI_ECONFIG, "mlp: width %d outside 1..1024", c->width);
    if (c->skip != -1 && (c->skip < 1 || c->skip >= c->depth))
        return sci_error_set(err, SCI_ECONFIG, "mlp: skip %d must be -1 or 1..depth-1 = %d", c->skip, c->depth - 1);
    if (c->density_act != NERF_ACT_RELU && c->density_act != NERF_ACT_TRUNC_EXP)
        return sci_error_set(err, SCI_ECONFIG, "mlp: density_act %s is neither relu nor trunc_exp",
                             nerf_act_name(c->density_act));
    if (c->feature_dim < 1 || c->feature_dim > 1024)
        return sci_error_set(err, SCI_ECONFIG, "mlp: feature_dim %d outside 1..1024", c->feature_dim);
    if (c->dir_enc != NERF_MLP_DIR_FREQ && c->dir_enc != NERF_MLP_DIR_SH)
        return sci_error_set(err, SCI_ECONFIG, "mlp: dir_enc %d is neither freq (0) nor sh (1)", (int)c->dir_enc);
    if (c->dir_enc == NERF_MLP_DIR_FREQ && (c->dir_freqs < 1 || c->dir_freqs > 16))
        return sci_error_set(err, SCI_ECONFIG, "mlp: dir_freqs %d outside 1..16", c->dir_freqs);
    if (c->dir_enc == NERF_MLP_DIR_SH && (c->sh_degree < 1 || c->sh_degree > NERF_SH_MAX_DEGREE))
        return sci_error_set(err, SCI_ECONFIG, "mlp: sh_degree %d outside 1..4", c->sh_degree);
    if (c->color_hidden < 0 || c->color_hidden > 1024)
        return sci_error_set(err, SCI_ECONFIG, "mlp: color_hidden %d outside 0..1024", c->color_hidden);
    for (int d = 0; d < 3; d++)
        if (!(c->aabb_max[d] > c->aabb_min[d]) || !isfinite(c->aabb_min[d]) || !isfinite(c->aabb_max[d]))
            return sci_error_set(err, SCI_ECONFIG, "mlp: aabb axis %d [%g, %g] empty or not finite", d,
                                 c->aabb_min[d], c->aabb_max[d]);
    if (!isfinite(c->density_bias))
        return sci_error_set(err, SCI_ECONFIG, "mlp: density_bias %g not finite", c->density_bias);
    nerf_mlp *n = calloc(1, sizeof *n);
    if (!n) return sci_error_set(err, -ENOMEM, "mlp: out of memory");
    n->cfg = *c;
    size_t k = 0;
    if (c->pos_enc == NERF_MLP_POS_HASH) {
        int rc = nerf_hashgrid_new(&n->grid, &c->grid, err);
        if (rc < 0) {
            free(n);
            sci_error_prefix(err, "mlp: ");
            return rc;
        }
        n->E = nerf_hashgrid_out_dim(n->grid);
        k = nerf_hashgrid_param_count(n->grid);
    } else {
        n->E = nerf_posenc_dim(3, c->pos_freqs, 1);
    }
    n->Dd = c->dir_enc == NERF_MLP_DIR_SH ? nerf_sh_dim(c->sh_degree) : nerf_posenc_dim(3, c->dir_freqs, 1);
    n->W = c->width, n->F = c->feature_dim, n->Ch = c->color_hidden, n->Ci = n->F + n->Dd;
    n->depth = c->depth, n->skip = c->skip;
    nerf_mlp_layout *lo = &n->lo;
    lo->hash = 0;
    n->saved_per_point = 3 + (size_t)n->E;
    for (int l = 0; l < n->depth; l++) {
        n->in[l] = l == 0 ? n->E : (l == n->skip ? n->W + n->E : n->W);
        lo->trunk_in[l] = n->in[l];
        lo->trunk_w[l] = k, k += (size_t)n->W * n->in[l];
        lo->trunk_b[l] = k, k += (size_t)n->W;
        n->ldh[l] = l + 1 == n->skip ? n->W + n->E : n->W;
        n->saved_per_point += (size_t)n->ldh[l];
    }
    lo->ws = k, k += (size_t)n->W;
    lo->bs = k, k += 1;
    lo->wf = k, k += (size_t)n->F * n->W;
    lo->bf = k, k += (size_t)n->F;
    if (n->Ch) {
        lo->wc1 = k, k += (size_t)n->Ch * n->Ci;
        lo->bc1 = k, k += (size_t)n->Ch;
        lo->wc2 = k, k += 3 * (size_t)n->Ch;
    } else {
        lo->wc2 = k, k += 3 * (size_t)n->Ci;
    }
    lo->bc2 = k, k += 3;
    lo->total = k;
    /* sraw, cin, c1, rgb, and the encoding gradient of the backward */
    n->saved_per_point += 1 + (size_t)n->Ci + (size_t)n->Ch + 3 + (size_t)n->E;
    *out = n;
    return 0;
}

void nerf_mlp_free(nerf_mlp *net)
{
    if (!net) return;
    nerf_hashgrid_free(net->grid);
    free(net);
}

const nerf_mlp_config *nerf_mlp_config_of(const nerf_mlp *net) { return &net->cfg; }
size_t nerf_mlp_param_count(const nerf_mlp *net) { return net->lo.total; }
size_t nerf_mlp_hash_param_count(const nerf_mlp *net) { return net->grid ? nerf_hashgrid_param_count(net->grid) : 0; }
const nerf_hashgrid *nerf_mlp_grid(const nerf_mlp *net) { return net->grid; }
int nerf_mlp_enc_dim(const nerf_mlp *net) { return net->E; }
int nerf_mlp_dir_dim(const nerf_mlp *net) { return net->Dd; }
nerf_mlp_layout nerf_mlp_layout_of(const nerf_mlp *net) { return net->lo; }
size_t nerf_mlp_saved_floats_per_point(const nerf_mlp *net) { return net->saved_per_point; }

void nerf_mlp_init(const nerf_mlp *n, float *P, uint64_t seed)
{
    sci_rng rng;
    sci_rng_seed(&rng, seed, 0x4d4c50u); /* stream "MLP" */
    if (n->grid) nerf_hashgrid_init(n->grid, P, &rng);
    for (int l = 0; l < n->depth; l++)
        nerf_linear_init(n->in[l], n->W, P + n->lo.trunk_w[l], P + n->lo.trunk_b[l], sqrt(2.0), &rng);
    nerf_linear_init(n->W, 1, P + n->lo.ws, P + n->lo.bs, 1.0, &rng);
    nerf_linear_init(n->W, n->F, P + n->lo.wf, P + n->lo.bf, 1.0, &rng);
    if (n->Ch) {
        nerf_linear_init(n->Ci, n->Ch, P + n->lo.wc1, P + n->lo.bc1, sqrt(2.0), &rng);
        nerf_linear_init(n->Ch, 3, P + n->lo.wc2, P + n->lo.bc2, 1.0, &rng);
    } else {
        nerf_linear_init(n->Ci, 3, P + n->lo.wc2, P + n->lo.bc2, 1.0, &rng);
    }
}

static size_t max_i(size_t a, size_t b) { return a > b ? a : b; }

int nerf_mlp_ws_new(nerf_mlp_ws **out, const nerf_mlp *n, int max_points, int n_threads, sci_error *err)
{
    *out = NULL;
    if (max_points < 1 || max_points > (1 << 26))
        return sci_error_set(err, -EINVAL, "mlp: max_points %d outside 1..2^26", max_points);
    if (n_threads < 1 || n_threads > 256)
        return sci_error_set(err, -EINVAL, "mlp: n_threads %d outside 1..256", n_threads);
    nerf_mlp_ws *w = calloc(1, sizeof *w);
    if (!w) return sci_error_set(err, -ENOMEM, "mlp: out of memory");
    w->max_points = max_points, w->n_threads = n_threads;
    const size_t rows = (size_t)max_points, m = NERF_MLP_CHUNK;
    size_t wide = max_i((size_t)n->W + n->E, (size_t)n->Ci);
    /* backward: two gradient planes (m × wide), dcin, dc1, drgb, ds; forward: rgb pre-activation */
    w->scratch_floats = m * (2 * wide + (size_t)n->Ci + (size_t)n->Ch + 3 + 1) + 64;
    size_t total = rows * n->saved_per_point + (size_t)n_threads * w->scratch_floats +
                   (size_t)(n_threads - 1) * n->lo.total;
    w->mem = malloc(total * sizeof *w->mem);
    w->scratch = calloc((size_t)n_threads, sizeof *w->scratch);
    w->tgrad = calloc((size_t)n_threads, sizeof *w->tgrad);
    if (!w->mem || !w->scratch || !w->tgrad) {
        nerf_mlp_ws_free(w);
        return sci_error_set(err, -ENOMEM, "mlp: workspace of %zu MiB for %d points", total * 4 >> 20, max_points);
    }
    w->bytes = total * sizeof *w->mem;
    float *p = w->mem;
    w->xin = p, p += rows * 3;
    w->enc = p, p += rows * n->E;
    for (int l = 0; l < n->depth; l++) w->h[l] = p, p += rows * n->ldh[l];
    w->sraw = p, p += rows;
    w->cin = p, p += rows * n->Ci;
    w->c1 = p, p += rows * n->Ch;
    w->rgb = p, p += rows * 3;
    w->denc = p, p += rows * n->E;
    for (int t = 0; t < n_threads; t++) w->scratch[t] = p, p += w->scratch_floats;
    for (int t = 1; t < n_threads; t++) w->tgrad[t] = p, p += n->lo.total;
    *out = w;
    return 0;
}

void nerf_mlp_ws_free(nerf_mlp_ws *w)
{
    if (!w) return;
    free(w->mem);
    free(w->scratch);
    free(w->tgrad);
    free(w);
}

size_t nerf_mlp_ws_bytes(const nerf_mlp_ws *w) { return w->bytes; }

/* Thread t's points: whole direction groups, so that d_dir sums stay inside one thread. */
static void point_range(int n, int every, int nt, int t, int *i0, int *i1)
{
    long groups = ((long)n + every - 1) / every;
    long g0 = groups * t / nt, g1 = groups * (t + 1) / nt;
    long a = g0 * every, b = g1 * every;
    *i0 = (int)(a < n ? a : n);
    *i1 = (int)(b < n ? b : n);
}

static void relu_rows(int m, int w, float *x, int ld)
{
    for (int i = 0; i < m; i++) {
        float *r = x + (size_t)i * ld;
#pragma omp simd
        for (int c = 0; c < w; c++) r[c] = r[c] > 0.0f ? r[c] : 0.0f;
    }
}

/* dy[i][c] = 0 where the ReLU output y[i][c] was 0 */
static void relu_mask_rows(int m, int w, const float *y, int ldy, float *dy, int lddy)
{
    for (int i = 0; i < m; i++) {
        const float *r = y + (size_t)i * ldy;
        float *g = dy + (size_t)i * lddy;
#pragma omp simd
        for (int c = 0; c < w; c++) g[c] = r[c] > 0.0f ? g[c] : 0.0f;
    }
}

static void dir_encode(const nerf_mlp *n, const float *d, float *y)
{
    if (n->cfg.dir_enc == NERF_MLP_DIR_SH)
        nerf_sh_forward(1, n->cfg.sh_degree, d, y, n->Dd);
    else
        nerf_posenc_forward(1, 3, n->cfg.dir_freqs, 1, d, y, n->Dd);
}

/* Encoding of points [i0, i1): xin (2u − 1 for freq, clamped-by-the-grid u for hash) and e. */
static void encode_range(const nerf_mlp *n, const float *P, nerf_mlp_ws *w, int i0, int i1, const float *pos)
{
    const nerf_mlp_config *c = &n->cfg;
    const int E = n->E, cnt = i1 - i0;
    float *xin = w->xin + (size_t)i0 * 3, *enc = w->enc + (size_t)i0 * E;
    int hash = c->pos_enc == NERF_MLP_POS_HASH;
    for (int i = 0; i < cnt; i++)
        for (int d = 0; d < 3; d++) {
            float u = (pos[((size_t)i0 + i) * 3 + d] - c->aabb_min[d]) / (c->aabb_max[d] - c->aabb_min[d]);
            xin[3 * i + d] = hash ? u : 2.0f * u - 1.0f;
        }
    if (hash)
        nerf_hashgrid_forward(n->grid, P, cnt, xin, enc, E);
    else
        nerf_posenc_forward(cnt, 3, c->pos_freqs, 1, xin, enc, E);
}

static void chunk_forward(const nerf_mlp *n, const float *P, nerf_mlp_ws *w, int r0, int m, float *sigma,
                          float *rgb_out, float *scr)
{
    const nerf_mlp_config *c = &n->cfg;
    const nerf_mlp_layout *lo = &n->lo;
    const int E = n->E, W = n->W, F = n->F, Ch = n->Ch, Ci = n->Ci, D = n->depth;
    const size_t R = (size_t)r0;
    const float *in = w->enc + R * E;
    int ld_in = E;
    for (int l = 0; l < D; l++) {
        float *h = w->h[l] + R * n->ldh[l];
        nerf_linear_forward(m, n->in[l], W, P + lo->trunk_w[l], P + lo->trunk_b[l], in, ld_in, h, n->ldh[l]);
        relu_rows(m, W, h, n->ldh[l]);
        if (l + 1 == n->skip)
            for (int i = 0; i < m; i++) /* the next layer's input is [h, e] */
                memcpy(h + (size_t)i * n->ldh[l] + W, w->enc + (R + i) * E, (size_t)E * sizeof *h);
        in = h, ld_in = n->ldh[l];
    }
    float *sraw = w->sraw + R, *cin = w->cin + R * Ci, *c1 = w->c1 + R * Ch, *rp = scr;
    nerf_linear_forward(m, W, 1, P + lo->ws, P + lo->bs, in, ld_in, sraw, 1);
    for (int i = 0; i < m; i++) {
        float s = sraw[i] + c->density_bias;
        nerf_act_forward(c->density_act, 1, &s, &sigma[R + i]);
    }
    nerf_linear_forward(m, W, F, P + lo->wf, P + lo->bf, in, ld_in, cin, Ci);
    for (int i = 0; i < m; i++) dir_encode(n, w->dir + (size_t)((R + i) / w->dir_every) * 3, cin + (size_t)i * Ci + F);
    if (Ch) {
        nerf_linear_forward(m, Ci, Ch, P + lo->wc1, P + lo->bc1, cin, Ci, c1, Ch);
        relu_rows(m, Ch, c1, Ch);
        nerf_linear_forward(m, Ch, 3, P + lo->wc2, P + lo->bc2, c1, Ch, rp, 3);
    } else {
        nerf_linear_forward(m, Ci, 3, P + lo->wc2, P + lo->bc2, cin, Ci, rp, 3);
    }
    nerf_act_forward(NERF_ACT_SIGMOID, (size_t)m * 3, rp, w->rgb + R * 3);
    memcpy(rgb_out + R * 3, w->rgb + R * 3, (size_t)m * 3 * sizeof *rgb_out);
}

int nerf_mlp_forward(const nerf_mlp *n, const float *P, nerf_mlp_ws *w, int np, const float *pos, const float *dir,
                     int dir_every, float *sigma, float *rgb)
{
    if (np < 1 || np > w->max_points || dir_every < 1) return -EINVAL;
    w->n = np, w->dir_every = dir_every, w->dir = dir;
    nerf_blas_single_thread();
    const int nt = w->n_threads;
#pragma omp parallel num_threads(nt)
    {
        int t = omp_get_thread_num(), i0, i1;
        point_range(np, dir_every, omp_get_num_threads(), t, &i0, &i1);
        if (i1 > i0) encode_range(n, P, w, i0, i1, pos);
        for (int r = i0; r < i1; r += NERF_MLP_CHUNK) {
            int m = i1 - r < NERF_MLP_CHUNK ? i1 - r : NERF_MLP_CHUNK;
            chunk_forward(n, P, w, r, m, sigma, rgb, w->scratch[t]);
        }
    }
    return 0;
}

static void chunk_backward(const nerf_mlp *n, const float *P, nerf_mlp_ws *w, int r0, int m, const float *d_sigma,
                           const float *d_rgb, float *Gr, float *d_dir, float *scr)
{
    const nerf_mlp_config *c = &n->cfg;
    const nerf_mlp_layout *lo = &n->lo;
    const int E = n->E, W = n->W, F = n->F, Ch = n->Ch, Ci = n->Ci, D = n->depth, Dd = n->Dd;
    const size_t R = (size_t)r0, wide = max_i((size_t)W + E, (size_t)Ci);
    float *gA = scr, *gB = gA + (size_t)m * wide, *dcin = gB + (size_t)m * wide, *dc1 = dcin + (size_t)m * Ci;
    float *drp = dc1 + (size_t)m * Ch, *ds = drp + (size_t)m * 3;
    const float *cin = w->cin + R * Ci, *c1 = w->c1 + R * Ch, *rgbs = w->rgb + R * 3, *sraw = w->sraw + R;
    for (size_t i = 0; i < (size_t)m * 3; i++) drp[i] = d_rgb ? d_rgb[R * 3 + i] : 0.0f;
    nerf_act_backward(NERF_ACT_SIGMOID, (size_t)m * 3, NULL, rgbs, drp, drp);
    if (Ch) {
        nerf_linear_backward(m, Ch, 3, P + lo->wc2, c1, Ch, drp, 3, dc1, Ch, 0, Gr + lo->wc2, Gr + lo->bc2);
        relu_mask_rows(m, Ch, c1, Ch, dc1, Ch);
        nerf_linear_backward(m, Ci, Ch, P + lo->wc1, cin, Ci, dc1, Ch, dcin, Ci, 0, Gr + lo->wc1, Gr + lo->bc1);
    } else {
        nerf_linear_backward(m, Ci, 3, P + lo->wc2, cin, Ci, drp, 3, dcin, Ci, 0, Gr + lo->wc2, Gr + lo->bc2);
    }
    if (d_dir)
        for (int i = 0; i < m; i++) {
            size_t g = (R + i) / w->dir_every;
            const float *d = w->dir + g * 3, *gi = dcin + (size_t)i * Ci + F;
            if (c->dir_enc == NERF_MLP_DIR_SH)
                nerf_sh_backward(1, c->sh_degree, d, gi, Dd, d_dir + g * 3, 1);
            else
                nerf_posenc_backward(1, 3, c->dir_freqs, 1, d, gi, Dd, d_dir + g * 3, 1);
        }
    for (int i = 0; i < m; i++) {
        float s = sraw[i] + c->density_bias, dsi = d_sigma ? d_sigma[R + i] : 0.0f;
        nerf_act_backward(c->density_act, 1, &s, NULL, &dsi, &ds[i]);
    }
    const float *hL = w->h[D - 1] + R * n->ldh[D - 1];
    nerf_linear_backward(m, W, 1, P + lo->ws, hL, n->ldh[D - 1], ds, 1, gA, W, 0, Gr + lo->ws, Gr + lo->bs);
    nerf_linear_backward(m, W, F, P + lo->wf, hL, n->ldh[D - 1], dcin, Ci, gA, W, 1, Gr + lo->wf, Gr + lo->bf);
    int lda = W;
    float *denc = w->denc + R * E;
    for (int l = D - 1; l >= 0; l--) {
        relu_mask_rows(m, W, w->h[l] + R * n->ldh[l], n->ldh[l], gA, lda);
        const float *in = l == 0 ? w->enc + R * E : w->h[l - 1] + R * n->ldh[l - 1];
        int ld_in = l == 0 ? E : n->ldh[l - 1];
        if (l == 0) {
            nerf_linear_backward(m, n->in[0], W, P + lo->trunk_w[0], in, ld_in, gA, lda, denc, E, n->skip >= 1,
                                 Gr + lo->trunk_w[0], Gr + lo->trunk_b[0]);
        } else {
            nerf_linear_backward(m, n->in[l], W, P + lo->trunk_w[l], in, ld_in, gA, lda, gB, n->in[l], 0,
                                 Gr + lo->trunk_w[l], Gr + lo->trunk_b[l]);
            if (l == n->skip)
                for (int i = 0; i < m; i++)
                    memcpy(denc + (size_t)i * E, gB + (size_t)i * n->in[l] + W, (size_t)E * sizeof *denc);
            float *t = gA;
            gA = gB, gB = t, lda = n->in[l];
        }
    }
}

int nerf_mlp_backward(const nerf_mlp *n, const float *P, nerf_mlp_ws *w, const float *d_sigma, const float *d_rgb,
                      float *grad, float *d_pos, float *d_dir)
{
    if (w->n < 1 || !grad) return -EINVAL;
    const int nt = w->n_threads, np = w->n, every = w->dir_every;
    const size_t npar = n->lo.total;
    const nerf_mlp_config *c = &n->cfg;
    nerf_blas_single_thread();
#pragma omp parallel num_threads(nt)
    {
        int t = omp_get_thread_num(), nth = omp_get_num_threads(), i0, i1;
        float *Gr = t == 0 ? grad : w->tgrad[t];
        memset(Gr, 0, npar * sizeof *Gr);
        point_range(np, every, nth, t, &i0, &i1);
        if (d_dir && i1 > i0) {
            size_t g0 = (size_t)i0 / every, g1 = ((size_t)i1 + every - 1) / every;
            memset(d_dir + g0 * 3, 0, (g1 - g0) * 3 * sizeof *d_dir);
        }
        for (int r = i0; r < i1; r += NERF_MLP_CHUNK) {
            int m = i1 - r < NERF_MLP_CHUNK ? i1 - r : NERF_MLP_CHUNK;
            chunk_backward(n, P, w, r, m, d_sigma, d_rgb, Gr, d_dir, w->scratch[t]);
        }
        /* the encoding over the whole range (the hash grid's level-major loop wants many points) */
        const int cnt = i1 - i0;
        const float *xin = w->xin + (size_t)i0 * 3, *denc = w->denc + (size_t)i0 * n->E;
        float *dp = d_pos ? d_pos + (size_t)i0 * 3 : NULL;
        if (cnt > 0) {
            if (n->grid)
                nerf_hashgrid_backward(n->grid, P, cnt, xin, denc, n->E, Gr, dp);
            else if (dp)
                nerf_posenc_backward(cnt, 3, c->pos_freqs, 1, xin, denc, n->E, dp, 0);
        }
        if (dp)
            for (int i = 0; i < cnt; i++)
                for (int d = 0; d < 3; d++) {
                    float ext = c->aabb_max[d] - c->aabb_min[d], *g = &dp[3 * i + d];
                    if (n->grid) {
                        float u = xin[3 * i + d];
                        *g = (u >= 0.0f && u <= 1.0f) ? *g / ext : 0.0f;
                    } else {
                        *g = *g * (2.0f / ext);
                    }
                }
#pragma omp barrier
#pragma omp for schedule(static)
        for (size_t j = 0; j < npar; j++) {
            float s = grad[j];
            for (int q = 1; q < nth; q++) s += w->tgrad[q][j];
            grad[j] = s;
        }
    }
    return 0;
}
