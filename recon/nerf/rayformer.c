/* recon/nerf/rayformer.c — the RayFormer network (see rayformer.h). */
#include "recon/nerf/rayformer.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "recon/nerf/act.h"
#include "recon/nerf/block.h"
#include "recon/nerf/layernorm.h"
#include "recon/nerf/linear.h"
#include "recon/nerf/shenc.h"

#define MAX_BLOCKS 8

struct nerf_rayformer {
    nerf_rayformer_config cfg;
    nerf_hashgrid *grid;
    nerf_block_shape bs;
    int C, G, S, Hc, Hh, R, L, cin; /* cin = G + S; Hh = head_hidden */
    size_t n_hash, off_block[MAX_BLOCKS], off_lnf_g, off_lnf_b, off_wh1, off_bh1, off_wh, off_bh, off_wc1, off_bc1, off_wc2,
        off_bc2, n_params;
};

struct nerf_rayformer_ws {
    int max_patches, n_threads, n_patches;
    int group; /* patches per work item (GROUP_ROWS rows or one patch): sets the order of the gradient sums */
    size_t rows_max, bytes;
    float *mem;
    /* saved activations (rows_max rows each) */
    float *u, *xhatf, *rstdf, *hpre, *hout, *cin, *c1pre, *rgb, *dir;
    float *enc; /* the hash features level-major (level l's n×F block at l·n·F): each level writes or reads one
                 * contiguous block instead of F floats of every 128-byte row */
    nerf_block_saved sv[MAX_BLOCKS];
    float *act[2];
    float **scratch;   /* per thread */
    float *pgrad;      /* per group: gradient of the parameters after the hash table (n_params − n_hash) */
    size_t scratch_floats;
    int n_levels, n_features;
    float level_w[NERF_HASHGRID_MAX_LEVELS];
};

nerf_rayformer_config nerf_rayformer_config_default(void)
{
    nerf_rayformer_config c = {
        .grid = {.n_levels = 16, .n_features = 2, .log2_table = 16, .base_res = 16, .finest_res = 1024},
        .width = 32, .n_blocks = 2, .heads = 2, .ffn_hidden = 64, .geo_dim = 15, .sh_degree = 4,
        .color_hidden = 32, .patch_w = 8, .patch_h = 8, .samples = 32,
        .aabb_min = {-1, -1, -1}, .aabb_max = {1, 1, 1}, .density_bias = 0.0f, .intra_ray = 1, .inter_ray = 1,
        .final_norm = 1,
    };
    return c;
}

int nerf_rayformer_new(nerf_rayformer **out, const nerf_rayformer_config *cfg, sci_error *err)
{
    *out = NULL;
    const nerf_rayformer_config *c = cfg;
    if (c->width < 2 || c->width > 256 || c->width % 2)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: width %d must be even, 2..256", c->width);
    if (c->grid.n_levels * c->grid.n_features != c->width)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: grid levels·features %d·%d must equal width %d",
                             c->grid.n_levels, c->grid.n_features, c->width);
    if (c->n_blocks < 1 || c->n_blocks > MAX_BLOCKS)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: n_blocks %d outside 1..%d", c->n_blocks, MAX_BLOCKS);
    if (c->heads < 1 || (c->width / 2) % c->heads)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: heads %d must divide width/2 = %d", c->heads,
                             c->width / 2);
    if (!(c->intra_slope >= 0.0f && c->intra_slope <= 100.0f))
        return sci_error_set(err, SCI_ECONFIG, "rayformer: intra_slope %g outside 0..100", (double)c->intra_slope);
    if (!(c->inter_slope >= 0.0f && c->inter_slope <= 100.0f))
        return sci_error_set(err, SCI_ECONFIG, "rayformer: inter_slope %g outside 0..100", (double)c->inter_slope);
    if (c->inter_slope > 0.0f && (c->patch_w & (c->patch_w - 1)))
        return sci_error_set(err, SCI_ECONFIG, "rayformer: inter_slope needs a window width that is a power of two "
                             "(got %d)", c->patch_w);
    if (c->ffn_hidden < 1 || c->ffn_hidden > 4096)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: ffn_hidden %d outside 1..4096", c->ffn_hidden);
    if (c->geo_dim < 0 || c->geo_dim > 256)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: geo_dim %d outside 0..256", c->geo_dim);
    if (c->sh_degree < 1 || c->sh_degree > NERF_SH_MAX_DEGREE)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: sh_degree %d outside 1..4", c->sh_degree);
    if (c->head_hidden < 0 || c->head_hidden > 4096)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: head_hidden %d outside 0..4096", c->head_hidden);
    if (c->color_hidden < 0 || c->color_hidden > 4096)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: color_hidden %d outside 0..4096", c->color_hidden);
    if (c->patch_w < 1 || c->patch_h < 1 || c->patch_w * c->patch_h > 4096 || c->samples < 1 || c->samples > 4096)
        return sci_error_set(err, SCI_ECONFIG, "rayformer: patch %d×%d × %d samples out of range", c->patch_w,
                             c->patch_h, c->samples);
    for (int d = 0; d < 3; d++)
        if (!(c->aabb_max[d] > c->aabb_min[d]) || !isfinite(c->aabb_min[d]) || !isfinite(c->aabb_max[d]))
            return sci_error_set(err, SCI_ECONFIG, "rayformer: aabb axis %d [%g, %g] empty or not finite", d,
                                 c->aabb_min[d], c->aabb_max[d]);
    nerf_rayformer *n = calloc(1, sizeof *n);
    if (!n) return sci_error_set(err, -ENOMEM, "rayformer: out of memory");
    n->cfg = *c;
    int rc = nerf_hashgrid_new(&n->grid, &c->grid, err);
    if (rc < 0) {
        free(n);
        return sci_error_prefix(err, "rayformer: ");
    }
    n->C = c->width, n->G = c->geo_dim, n->S = nerf_sh_dim(c->sh_degree), n->Hc = c->color_hidden;
    n->Hh = c->head_hidden;
    n->R = c->patch_w * c->patch_h, n->L = c->samples, n->cin = n->G + n->S;
    n->bs = (nerf_block_shape){.att = {.C = n->C, .heads = c->heads, .L = n->L, .R = n->R,
                                       .intra_off = !c->intra_ray, .inter_off = !c->inter_ray,
                                       .intra_slope = c->intra_slope, .inter_slope = c->inter_slope,
                                       .win_w = c->patch_w},
                               .hidden = c->ffn_hidden,
                               .inter_gate = c->inter_gate && c->inter_ray};
    size_t k = nerf_hashgrid_param_count(n->grid);
    n->n_hash = k;
    for (int b = 0; b < c->n_blocks; b++) n->off_block[b] = k, k += nerf_block_param_count(&n->bs);
    const size_t C = (size_t)n->C, G1 = (size_t)n->G + 1, Ci = (size_t)n->cin, Hc = (size_t)n->Hc;
    const size_t Hh = (size_t)n->Hh;
    n->off_lnf_g = k, k += C;
    n->off_lnf_b = k, k += C;
    if (Hh) {
        n->off_wh1 = k, k += Hh * C;
        n->off_bh1 = k, k += Hh;
    }
    n->off_wh = k, k += G1 * (Hh ? Hh : C);
    n->off_bh = k, k += G1;
    if (Hc) {
        n->off_wc1 = k, k += Hc * Ci;
        n->off_bc1 = k, k += Hc;
        n->off_wc2 = k, k += 3 * Hc;
    } else {
        n->off_wc2 = k, k += 3 * Ci;
    }
    n->off_bc2 = k, k += 3;
    n->n_params = k;
    *out = n;
    return 0;
}

void nerf_rayformer_free(nerf_rayformer *net)
{
    if (!net) return;
    nerf_hashgrid_free(net->grid);
    free(net);
}

const nerf_rayformer_config *nerf_rayformer_config_of(const nerf_rayformer *net) { return &net->cfg; }
size_t nerf_rayformer_param_count(const nerf_rayformer *net) { return net->n_params; }
size_t nerf_rayformer_hash_param_count(const nerf_rayformer *net) { return net->n_hash; }
const nerf_hashgrid *nerf_rayformer_grid(const nerf_rayformer *net) { return net->grid; }

nerf_rayformer_layout nerf_rayformer_layout_of(const nerf_rayformer *n)
{
    nerf_rayformer_layout l = {.hash = 0, .lnf_g = n->off_lnf_g, .lnf_b = n->off_lnf_b, .wh1 = n->off_wh1,
                               .bh1 = n->off_bh1, .wh = n->off_wh,
                               .bh = n->off_bh, .wc1 = n->off_wc1, .bc1 = n->off_bc1, .wc2 = n->off_wc2,
                               .bc2 = n->off_bc2, .total = n->n_params};
    for (int b = 0; b < n->cfg.n_blocks; b++) l.block[b] = n->off_block[b];
    return l;
}

void nerf_rayformer_init(const nerf_rayformer *net, float *P, uint64_t seed)
{
    sci_rng rng;
    sci_rng_seed(&rng, seed, 0x4e455246u); /* stream "NERF" */
    nerf_hashgrid_init(net->grid, P, &rng);
    for (int b = 0; b < net->cfg.n_blocks; b++) {
        nerf_block_init(&net->bs, P + net->off_block[b], net->cfg.n_blocks, &rng);
        if (net->cfg.zero_gates) { /* the residual branches start at zero: the block is the identity */
            nerf_block_offsets o = nerf_block_layout(&net->bs);
            memset(P + net->off_block[b] + o.w_o, 0, (size_t)net->C * net->C * sizeof *P);
            memset(P + net->off_block[b] + o.w_2, 0, (size_t)net->C * net->bs.hidden * sizeof *P);
        }
    }
    for (int c = 0; c < net->C; c++) P[net->off_lnf_g + c] = 1.0f, P[net->off_lnf_b + c] = 0.0f;
    if (net->Hh) {
        nerf_linear_init(net->C, net->Hh, P + net->off_wh1, P + net->off_bh1, sqrt(2.0), &rng);
        nerf_linear_init(net->Hh, net->G + 1, P + net->off_wh, P + net->off_bh, 1.0, &rng);
    } else {
        nerf_linear_init(net->C, net->G + 1, P + net->off_wh, P + net->off_bh, 1.0, &rng);
    }
    if (net->Hc) {
        nerf_linear_init(net->cin, net->Hc, P + net->off_wc1, P + net->off_bc1, sqrt(2.0), &rng);
        nerf_linear_init(net->Hc, 3, P + net->off_wc2, P + net->off_bc2, 1.0, &rng);
    } else {
        nerf_linear_init(net->cin, 3, P + net->off_wc2, P + net->off_bc2, 1.0, &rng);
    }
}

static size_t head_scratch_floats(const nerf_rayformer *n, size_t rows)
{
    /* forward: y (C), c1 (Hc), rgb_pre (3), sh (S per ray), head hidden (Hh); backward: y, dy (C), drgb (3), c1,
     * dc1 (Hc), dcin, dhout, du (3), head hidden and its gradient (Hh each) */
    return rows * (2 * (size_t)n->C + 3 + 2 * (size_t)n->Hc + (size_t)n->cin + (size_t)n->G + 1 + 3 +
                   2 * (size_t)n->Hh) +
           rows / (size_t)n->L * n->S + 64;
}

/* Rows per work item: patches are taken GROUP_ROWS rows at a time, so each layer is one sgemm of ~1024 rows
 * instead of eight of 128 (the default 2 × 2 patch), and the gradient slices summed after the backward are 8×
 * fewer (they were 77 MB a step at 1024 patches). */
#define GROUP_ROWS 1024

int nerf_rayformer_ws_new(nerf_rayformer_ws **out, const nerf_rayformer *n, int max_patches, int n_threads,
                          sci_error *err)
{
    *out = NULL;
    if (max_patches < 1 || max_patches > (1 << 20))
        return sci_error_set(err, -EINVAL, "rayformer: max_patches %d outside 1..2^20", max_patches);
    if (n_threads < 1 || n_threads > 256)
        return sci_error_set(err, -EINVAL, "rayformer: n_threads %d outside 1..256", n_threads);
    nerf_rayformer_ws *w = calloc(1, sizeof *w);
    if (!w) return sci_error_set(err, -ENOMEM, "rayformer: out of memory");
    w->max_patches = max_patches, w->n_threads = n_threads;
    w->n_levels = n->cfg.grid.n_levels, w->n_features = n->cfg.grid.n_features;
    for (int l = 0; l < NERF_HASHGRID_MAX_LEVELS; l++) w->level_w[l] = 1.0f;
    const size_t rows = (size_t)max_patches * n->R * n->L, C = (size_t)n->C;
    w->group = n->R * n->L >= GROUP_ROWS ? 1 : GROUP_ROWS / (n->R * n->L);
    const size_t chunk = (size_t)w->group * n->R * n->L, n_groups = ((size_t)max_patches + w->group - 1) / w->group;
    w->rows_max = rows;
    size_t per_row = 3 + C + C + 1 + (size_t)n->Hh + (size_t)n->G + 1 + (size_t)n->cin + (size_t)n->Hc + 3 + 2 * C +
                     (size_t)n->cfg.n_blocks * nerf_block_saved_floats(&n->bs);
    size_t bs = nerf_block_scratch_floats(&n->bs, chunk), hs = head_scratch_floats(n, chunk);
    w->scratch_floats = (bs > hs ? bs : hs) + 16;
    size_t total = rows * per_row + (size_t)max_patches * n->R * 3 + (size_t)n_threads * w->scratch_floats +
                   n_groups * (n->n_params - n->n_hash);
    w->mem = malloc(total * sizeof *w->mem);
    w->scratch = calloc((size_t)n_threads, sizeof *w->scratch);
    if (!w->mem || !w->scratch) {
        nerf_rayformer_ws_free(w);
        return sci_error_set(err, -ENOMEM, "rayformer: workspace of %zu MiB for %d patches", total * 4 >> 20,
                             max_patches);
    }
    w->bytes = total * sizeof *w->mem;
    float *m = w->mem;
    w->u = m, m += rows * 3;
    w->xhatf = m, m += rows * C;
    w->enc = m, m += rows * C;
    w->rstdf = m, m += rows;
    w->hpre = m, m += rows * (size_t)n->Hh;
    w->hout = m, m += rows * ((size_t)n->G + 1);
    w->cin = m, m += rows * (size_t)n->cin;
    w->c1pre = m, m += rows * (size_t)n->Hc;
    w->rgb = m, m += rows * 3;
    w->act[0] = m, m += rows * C;
    w->act[1] = m, m += rows * C;
    for (int b = 0; b < n->cfg.n_blocks; b++) {
        nerf_block_saved_bind(&n->bs, rows, m, &w->sv[b]);
        m += rows * nerf_block_saved_floats(&n->bs);
    }
    w->dir = m, m += (size_t)max_patches * n->R * 3;
    for (int t = 0; t < n_threads; t++) w->scratch[t] = m, m += w->scratch_floats;
    w->pgrad = m, m += n_groups * (n->n_params - n->n_hash);
    *out = w;
    return 0;
}

void nerf_rayformer_ws_free(nerf_rayformer_ws *w)
{
    if (!w) return;
    free(w->mem);
    free(w->scratch);
    free(w);
}

size_t nerf_rayformer_ws_bytes(const nerf_rayformer_ws *w) { return w->bytes; }

void nerf_rayformer_ws_set_levels(nerf_rayformer_ws *w, double alpha)
{
    if (!(alpha >= 1.0)) alpha = 1.0;
    for (int l = 0; l < w->n_levels; l++) {
        double a = alpha - l, x = a <= 0 ? 0.0 : a >= 1 ? 1.0 : a;
        w->level_w[l] = (float)((1.0 - cos(M_PI * x)) / 2.0);
    }
}

/* Level-major features enc (level l: n×F at l·n·F) → rows y (n×C), scaled by the coarse-to-fine weights; rows
 * [i0, i1). */
static void levels_to_rows(const nerf_rayformer_ws *w, long n, long i0, long i1, const float *enc, float *y, int C)
{
    const int F = w->n_features;
    for (int l = 0; l < w->n_levels; l++) {
        const float s = w->level_w[l], *e = enc + (size_t)l * n * F;
        for (long i = i0; i < i1; i++)
            for (int f = 0; f < F; f++) y[(size_t)i * C + l * F + f] = s * e[(size_t)i * F + f];
    }
}

/* The reverse: rows of gradients → level-major, scaled by the same weights; a level whose weight is below 1 is
 * scaled in y too, where the position gradient reads it. */
static void rows_to_levels(const nerf_rayformer_ws *w, long n, long i0, long i1, float *y, int C, float *enc)
{
    const int F = w->n_features;
    for (int l = 0; l < w->n_levels; l++) {
        const float s = w->level_w[l];
        float *e = enc + (size_t)l * n * F;
        for (long i = i0; i < i1; i++)
            for (int f = 0; f < F; f++) e[(size_t)i * F + f] = s * y[(size_t)i * C + l * F + f];
        if (s != 1.0f)
            for (long i = i0; i < i1; i++)
                for (int f = 0; f < F; f++) y[(size_t)i * C + l * F + f] *= s;
    }
}

/* Forward of patches [p, p + np) (rows [row0, row0 + np·R·L)) on the calling thread, after the hash encoding of
 * their rows. */
static void patch_forward(const nerf_rayformer *n, const float *P, nerf_rayformer_ws *w, int p, int np,
                          float *sigma, float *rgb_out, float *scr)
{
    const int C = n->C, G = n->G, S = n->S, Hc = n->Hc, R = np * n->R, L = n->L, Ci = n->cin, rows = R * L;
    const size_t row0 = (size_t)p * n->R * L;
    const nerf_rayformer_config *cf = &n->cfg;
    int cur = 0;
    for (int b = 0; b < cf->n_blocks; b++) {
        nerf_block_forward(&n->bs, P + n->off_block[b], np, row0, w->act[cur], w->act[cur ^ 1], &w->sv[b], scr);
        cur ^= 1;
    }
    const int Hh = n->Hh;
    float *y = scr, *c1 = y + (size_t)rows * C, *rp = c1 + (size_t)rows * Hc, *sh = rp + (size_t)rows * 3;
    const float *head_in = y;
    float *ha = sh + (size_t)R * S;
    float *hout = w->hout + row0 * (G + 1), *cin = w->cin + row0 * Ci, *c1pre = w->c1pre + row0 * Hc;
    if (cf->final_norm) {
        nerf_layernorm_forward(rows, C, P + n->off_lnf_g, P + n->off_lnf_b, w->act[cur] + row0 * C, C, y, C,
                               w->xhatf + row0 * C, w->rstdf + row0);
    } else { /* the head's input is h_B itself, kept in xhatf for the backward */
        head_in = w->xhatf + row0 * C;
        memcpy(w->xhatf + row0 * C, w->act[cur] + row0 * C, (size_t)rows * C * sizeof *y);
    }
    if (Hh) {
        float *hpre = w->hpre + row0 * Hh;
        nerf_linear_forward(rows, C, Hh, P + n->off_wh1, P + n->off_bh1, head_in, C, hpre, Hh);
        nerf_act_forward(NERF_ACT_RELU, (size_t)rows * Hh, hpre, ha);
        nerf_linear_forward(rows, Hh, G + 1, P + n->off_wh, P + n->off_bh, ha, Hh, hout, G + 1);
    } else {
        nerf_linear_forward(rows, C, G + 1, P + n->off_wh, P + n->off_bh, head_in, C, hout, G + 1);
    }
    for (int i = 0; i < rows; i++) {
        float s = hout[(size_t)i * (G + 1)] + cf->density_bias;
        nerf_act_forward(NERF_ACT_TRUNC_EXP, 1, &s, &sigma[row0 + i]);
    }
    nerf_sh_forward(R, cf->sh_degree, w->dir + (size_t)p * n->R * 3, sh, S);
    for (int i = 0; i < rows; i++) {
        memcpy(cin + (size_t)i * Ci, hout + (size_t)i * (G + 1) + 1, (size_t)G * sizeof *cin);
        memcpy(cin + (size_t)i * Ci + G, sh + (size_t)(i / L) * S, (size_t)S * sizeof *cin);
    }
    if (Hc) {
        nerf_linear_forward(rows, Ci, Hc, P + n->off_wc1, P + n->off_bc1, cin, Ci, c1pre, Hc);
        nerf_act_forward(NERF_ACT_RELU, (size_t)rows * Hc, c1pre, c1);
        nerf_linear_forward(rows, Hc, 3, P + n->off_wc2, P + n->off_bc2, c1, Hc, rp, 3);
    } else {
        nerf_linear_forward(rows, Ci, 3, P + n->off_wc2, P + n->off_bc2, cin, Ci, rp, 3);
    }
    nerf_act_forward(NERF_ACT_SIGMOID, (size_t)rows * 3, rp, w->rgb + row0 * 3);
    memcpy(rgb_out + row0 * 3, w->rgb + row0 * 3, (size_t)rows * 3 * sizeof *rgb_out);
}

/* Points per dynamically scheduled chunk of the position gradient (4 patches of the default network). */
#define HASH_CHUNK 8192

int nerf_rayformer_forward(const nerf_rayformer *n, const float *P, nerf_rayformer_ws *w, int n_patches,
                           const float *pos, const float *dir, float *sigma, float *rgb)
{
    if (n_patches < 1 || n_patches > w->max_patches) return -EINVAL;
    w->n_patches = n_patches;
    memcpy(w->dir, dir, (size_t)n_patches * n->R * 3 * sizeof *w->dir);
    nerf_blas_single_thread();
    const int nt = w->n_threads;
    const long N = (long)n_patches * n->R * n->L;
    const nerf_rayformer_config *cf = &n->cfg;
    const int levels = cf->grid.n_levels;
    /* Dynamic schedules: a thread whose core is shared with another job takes fewer levels or groups instead of
     * holding the other at the barrier. Nothing here reduces across them, so the bits do not depend on the schedule.
     * The encoding runs level-major over every point: one level's slice of the table (4 MiB at 2^19 entries) is
     * fetched once, where point chunks each walking all levels fetched every slice once per chunk. */
#pragma omp parallel num_threads(nt)
    {
#pragma omp for schedule(static)
        for (long i = 0; i < N; i++)
            for (int d = 0; d < 3; d++)
                w->u[3 * i + d] = (pos[i * 3 + d] - cf->aabb_min[d]) / (cf->aabb_max[d] - cf->aabb_min[d]);
#pragma omp for schedule(dynamic, 1)
        for (int l = 0; l < levels; l++)
            nerf_hashgrid_forward_level(n->grid, P, (int)N, w->u, w->enc + (size_t)l * N * w->n_features,
                                        w->n_features, l);
#pragma omp for schedule(static)
        for (long c0 = 0; c0 < N; c0 += HASH_CHUNK)
            levels_to_rows(w, N, c0, N - c0 < HASH_CHUNK ? N : c0 + HASH_CHUNK, w->enc, w->act[0], n->C);
#pragma omp for schedule(dynamic, 1)
        for (int p = 0; p < n_patches; p += w->group)
            patch_forward(n, P, w, p, n_patches - p < w->group ? n_patches - p : w->group, sigma, rgb,
                          w->scratch[omp_get_thread_num()]);
    }
    return 0;
}

/* Backward of patches [p, p + np). Gd: their gradient of the parameters after the hash table (offsets shifted by
 * n_hash). */
#define GD(off) (Gd + ((off) - n->n_hash))
static void patch_backward(const nerf_rayformer *n, const float *P, nerf_rayformer_ws *w, int p, int np,
                           const float *d_sigma, const float *d_rgb, float *Gd, float *d_dir,
                           float *scr)
{
    const int C = n->C, G = n->G, S = n->S, Hc = n->Hc, R = np * n->R, L = n->L, Ci = n->cin, rows = R * L;
    const size_t row0 = (size_t)p * n->R * L;
    const nerf_rayformer_config *cf = &n->cfg;
    float *y = scr, *dy = y + (size_t)rows * C, *drp = dy + (size_t)rows * C, *c1 = drp + (size_t)rows * 3;
    float *dc1 = c1 + (size_t)rows * Hc, *dcin = dc1 + (size_t)rows * Hc, *dhout = dcin + (size_t)rows * Ci;
    const int Hh = n->Hh;
    float *ha = dhout + (size_t)rows * (G + 1), *dha = ha + (size_t)rows * Hh;
    const float *hout = w->hout + row0 * (G + 1), *cin = w->cin + row0 * Ci, *c1pre = w->c1pre + row0 * Hc;
    const float *rgbs = w->rgb + row0 * 3;
    for (size_t i = 0; i < (size_t)rows * 3; i++) drp[i] = d_rgb ? d_rgb[row0 * 3 + i] : 0.0f;
    nerf_act_backward(NERF_ACT_SIGMOID, (size_t)rows * 3, NULL, rgbs, drp, drp);
    if (Hc) {
        nerf_act_forward(NERF_ACT_RELU, (size_t)rows * Hc, c1pre, c1);
        nerf_linear_backward(rows, Hc, 3, P + n->off_wc2, c1, Hc, drp, 3, dc1, Hc, 0, GD(n->off_wc2),
                             GD(n->off_bc2));
        nerf_act_backward(NERF_ACT_RELU, (size_t)rows * Hc, c1pre, NULL, dc1, dc1);
        nerf_linear_backward(rows, Ci, Hc, P + n->off_wc1, cin, Ci, dc1, Hc, dcin, Ci, 0, GD(n->off_wc1),
                             GD(n->off_bc1));
    } else {
        nerf_linear_backward(rows, Ci, 3, P + n->off_wc2, cin, Ci, drp, 3, dcin, Ci, 0, GD(n->off_wc2),
                             GD(n->off_bc2));
    }
    for (int i = 0; i < rows; i++) {
        float s = hout[(size_t)i * (G + 1)] + cf->density_bias, ds = d_sigma ? d_sigma[row0 + i] : 0.0f;
        nerf_act_backward(NERF_ACT_TRUNC_EXP, 1, &s, NULL, &ds, &dhout[(size_t)i * (G + 1)]);
        memcpy(dhout + (size_t)i * (G + 1) + 1, dcin + (size_t)i * Ci, (size_t)G * sizeof *dhout);
    }
    if (d_dir) {
        for (int r = 0; r < R; r++) {
            float dsh[16];
            for (int k = 0; k < S; k++) {
                double s = 0.0;
                for (int q = 0; q < L; q++) s += dcin[((size_t)r * L + q) * Ci + G + k];
                dsh[k] = (float)s;
            }
            nerf_sh_backward(1, cf->sh_degree, w->dir + ((size_t)p * n->R + r) * 3, dsh, S,
                             d_dir + ((size_t)p * n->R + r) * 3, 0);
        }
    }
    /* head and final LN; the block chain runs in place on act[0] as the gradient buffer */
    const float *head_in = w->xhatf + row0 * C; /* without the final LN, the head's input itself */
    if (cf->final_norm) {
        nerf_layernorm_apply(rows, C, P + n->off_lnf_g, P + n->off_lnf_b, w->xhatf + row0 * C, y, C);
        head_in = y;
    }
    if (Hh) {
        const float *hpre = w->hpre + row0 * Hh;
        nerf_act_forward(NERF_ACT_RELU, (size_t)rows * Hh, hpre, ha);
        nerf_linear_backward(rows, Hh, G + 1, P + n->off_wh, ha, Hh, dhout, G + 1, dha, Hh, 0, GD(n->off_wh),
                             GD(n->off_bh));
        nerf_act_backward(NERF_ACT_RELU, (size_t)rows * Hh, hpre, NULL, dha, dha);
        nerf_linear_backward(rows, C, Hh, P + n->off_wh1, head_in, C, dha, Hh, dy, C, 0, GD(n->off_wh1),
                             GD(n->off_bh1));
    } else {
        nerf_linear_backward(rows, C, G + 1, P + n->off_wh, head_in, C, dhout, G + 1, dy, C, 0, GD(n->off_wh),
                             GD(n->off_bh));
    }
    float *g = w->act[0] + row0 * C;
    if (cf->final_norm)
        nerf_layernorm_backward(rows, C, P + n->off_lnf_g, w->xhatf + row0 * C, w->rstdf + row0, dy, C, g, C, 0,
                                GD(n->off_lnf_g), GD(n->off_lnf_b));
    else
        memcpy(g, dy, (size_t)rows * C * sizeof *g);
    for (int b = cf->n_blocks - 1; b >= 0; b--)
        nerf_block_backward(&n->bs, P + n->off_block[b], np, row0, &w->sv[b], w->act[0], w->act[0],
                            GD(n->off_block[b]), scr);
}

int nerf_rayformer_backward(const nerf_rayformer *n, const float *P, nerf_rayformer_ws *w, const float *d_sigma,
                            const float *d_rgb, float *grad, float *d_pos, float *d_dir)
{
    if (w->n_patches < 1 || !grad) return -EINVAL;
    const int nt = w->n_threads, n_patches = w->n_patches, C = n->C;
    const int n_groups = (n_patches + w->group - 1) / w->group;
    const size_t nh = n->n_hash, nd = n->n_params - n->n_hash;
    const long N = (long)n_patches * n->R * n->L;
    const int levels = n->cfg.grid.n_levels;
    nerf_blas_single_thread();
    /* Determinism without per-thread buffers, for any thread count and schedule: each patch writes its own
     * gradient slice (the parameters after the table, ~75 KB), summed in patch order; the table gradient is split
     * by level (levels own disjoint slices of the table) and each level takes the points in order. */
#pragma omp parallel num_threads(nt)
    {
#pragma omp for schedule(dynamic, 1)
        for (int p = 0; p < n_patches; p += w->group) {
            float *Gd = w->pgrad + (size_t)(p / w->group) * nd;
            memset(Gd, 0, nd * sizeof *Gd);
            patch_backward(n, P, w, p, n_patches - p < w->group ? n_patches - p : w->group, d_sigma, d_rgb, Gd,
                           d_dir, w->scratch[omp_get_thread_num()]);
        }
#pragma omp for schedule(static)
        for (size_t j = 0; j < nh; j += 4096) memset(grad + j, 0, (nh - j < 4096 ? nh - j : 4096) * sizeof *grad);
#pragma omp for schedule(static)
        for (long c0 = 0; c0 < N; c0 += HASH_CHUNK)
            rows_to_levels(w, N, c0, N - c0 < HASH_CHUNK ? N : c0 + HASH_CHUNK, w->act[0], C, w->enc);
#pragma omp for schedule(dynamic, 1)
        for (int l = 0; l < levels; l++)
            nerf_hashgrid_backward_level(n->grid, (int)N, w->u, w->enc + (size_t)l * N * w->n_features,
                                         w->n_features, grad, l);
        if (d_pos) {
#pragma omp for schedule(dynamic, 1)
            for (long c0 = 0; c0 < N; c0 += HASH_CHUNK) {
                long cnt = N - c0 < HASH_CHUNK ? N - c0 : HASH_CHUNK;
                const float *u = w->u + c0 * 3;
                nerf_hashgrid_backward(n->grid, P, (int)cnt, u, w->act[0] + c0 * C, C, NULL, d_pos + c0 * 3);
                for (long i = 0; i < cnt; i++)
                    for (int d = 0; d < 3; d++) {
                        float ud = u[3 * i + d], *dp = &d_pos[(c0 + i) * 3 + d];
                        *dp = (ud >= 0.0f && ud <= 1.0f) ? *dp / (n->cfg.aabb_max[d] - n->cfg.aabb_min[d]) : 0.0f;
                    }
            }
        }
        /* the patch sum, row by row over blocks of columns: the same additions in the same order as a sum per
         * column, but streaming (a column walk strides 75 KB per add: 9 % of a step in cache misses) */
#pragma omp for schedule(static)
        for (size_t j0 = 0; j0 < nd; j0 += 1024) {
            const size_t cnt = nd - j0 < 1024 ? nd - j0 : 1024;
            float *g = grad + nh + j0;
            memcpy(g, w->pgrad + j0, cnt * sizeof *g);
            for (int q = 1; q < n_groups; q++) {
                const float *src = w->pgrad + (size_t)q * nd + j0;
                for (size_t j = 0; j < cnt; j++) g[j] += src[j];
            }
        }
    }
    return 0;
}
