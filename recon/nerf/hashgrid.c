/* recon/nerf/hashgrid.c — multiresolution hash encoding (see hashgrid.h). */
/* The clamps in level_cells must be if-converted to vectorise; this changes no value, it only lets gcc assume no FP
 * trap is enabled (the project never enables one). */
#pragma GCC optimize("no-trapping-math")

#include "recon/nerf/hashgrid.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct level {
    double scale;
    uint64_t res;    /* vertices per side of the dense grid */
    uint64_t size;   /* entries */
    uint64_t offset; /* entries before this level */
    int dense;
} level;

struct nerf_hashgrid {
    nerf_hashgrid_config cfg;
    level lv[NERF_HASHGRID_MAX_LEVELS];
    size_t n_params;
};

static const uint32_t PRIMES[3] = {1u, 2654435761u, 805459861u};

int nerf_hashgrid_new(nerf_hashgrid **out, const nerf_hashgrid_config *cfg, sci_error *err)
{
    *out = NULL;
    if (cfg->n_levels < 1 || cfg->n_levels > NERF_HASHGRID_MAX_LEVELS)
        return sci_error_set(err, SCI_ECONFIG, "hashgrid: n_levels %d outside 1..%d", cfg->n_levels,
                             NERF_HASHGRID_MAX_LEVELS);
    if (cfg->n_features < 1 || cfg->n_features > 8)
        return sci_error_set(err, SCI_ECONFIG, "hashgrid: n_features %d outside 1..8", cfg->n_features);
    if (cfg->log2_table < 10 || cfg->log2_table > 24)
        return sci_error_set(err, SCI_ECONFIG, "hashgrid: log2_table %d outside 10..24", cfg->log2_table);
    if (!(cfg->base_res >= 2.0 && cfg->base_res <= 1e6))
        return sci_error_set(err, SCI_ECONFIG, "hashgrid: base_res %g outside 2..1e6", cfg->base_res);
    if (!(cfg->finest_res >= cfg->base_res && cfg->finest_res <= 1e7))
        return sci_error_set(err, SCI_ECONFIG, "hashgrid: finest_res %g below base_res %g or above 1e7",
                             cfg->finest_res, cfg->base_res);
    nerf_hashgrid *g = calloc(1, sizeof *g);
    if (!g) return sci_error_set(err, -ENOMEM, "hashgrid: out of memory");
    g->cfg = *cfg;
    double lnb = cfg->n_levels > 1 ? (log(cfg->finest_res) - log(cfg->base_res)) / (cfg->n_levels - 1) : 0.0;
    uint64_t T = (uint64_t)1 << cfg->log2_table, off = 0;
    for (int l = 0; l < cfg->n_levels; l++) {
        level *v = &g->lv[l];
        v->scale = exp(l * lnb) * cfg->base_res - 1.0;
        v->res = (uint64_t)ceil(v->scale) + 2;
        /* res <= 1e7 + 2, so res³ < 2^70 could overflow: compare per factor instead */
        int fits = v->res <= T && v->res * v->res <= T && v->res * v->res * v->res <= T;
        uint64_t n3 = fits ? v->res * v->res * v->res : T;
        v->dense = fits;
        v->size = fits ? ((n3 + 7) / 8) * 8 : T;
        if (v->size > T) v->size = T, v->dense = 0; /* rounding up to 8 crossed T: hash (never aliases) */
        v->offset = off;
        off += v->size;
    }
    g->n_params = (size_t)off * cfg->n_features;
    *out = g;
    return 0;
}

void nerf_hashgrid_free(nerf_hashgrid *g) { free(g); }
size_t nerf_hashgrid_param_count(const nerf_hashgrid *g) { return g->n_params; }
const nerf_hashgrid_config *nerf_hashgrid_config_of(const nerf_hashgrid *g) { return &g->cfg; }
int nerf_hashgrid_out_dim(const nerf_hashgrid *g) { return g->cfg.n_levels * g->cfg.n_features; }

void nerf_hashgrid_level(const nerf_hashgrid *g, int l, double *scale, uint64_t *res, size_t *entries, int *dense)
{
    const level *v = &g->lv[l];
    if (scale) *scale = v->scale;
    if (res) *res = v->res;
    if (entries) *entries = (size_t)v->size;
    if (dense) *dense = v->dense;
}

void nerf_hashgrid_init(const nerf_hashgrid *g, float *table, sci_rng *rng)
{
    for (size_t i = 0; i < g->n_params; i++) table[i] = (float)((2.0 * sci_rng_uniform(rng) - 1.0) * 1e-4);
}

/* Corner indices (entry index within the whole table) and trilinear weights of one point at one level, plus the
 * per-dimension clamp flags and fractions needed for the position gradient. Corner k has bit d of k set when it
 * is the upper vertex in dimension d; its weight is the product over d in the order x, y, z. */
typedef struct corners {
    uint64_t idx[8];
    float w[8];
    float frac[3];
    int inside[3];
} corners;

/* Cells and fractions of m points at one level from their 3m coordinates (flat: every coordinate is treated
 * alike), clamped to [0, 1], NaN → 0 (a safe index; the caller validated inputs). Vectorises. */
static inline __attribute__((always_inline)) void level_cells(const level *v, int m3, const float *x,
                                                              uint32_t *cell, float *frac)
{
    const double sc = v->scale;
    for (int k = 0; k < m3; k++) {
        float xd = x[k];
        xd = xd < 0.0f ? 0.0f : (xd > 1.0f ? 1.0f : xd);
        xd = xd != xd ? 0.0f : xd;
        double p = sc * (double)xd + 0.5;
        uint32_t c = (uint32_t)(int32_t)p; /* 0.5 <= p < 2^31: truncation is floor, without a libm call */
        cell[k] = c;
        frac[k] = (float)(p - (double)c);
    }
}

/* Corner indices and weights from a point's cell and fractions. */
static inline __attribute__((always_inline)) void corners_from(const level *v, uint64_t T, const uint32_t *cell,
                                                               const float *frac, corners *c)
{
    const float fx = frac[0], fy = frac[1], fz = frac[2];
    const float wx[2] = {1.0f - fx, fx}, wy[2] = {1.0f - fy, fy}, wz[2] = {1.0f - fz, fz};
    uint64_t hx[2], hy[2], hz[2];
    if (v->dense) {
        const uint64_t r = v->res, r2 = r * r;
        for (int b = 0; b < 2; b++)
            hx[b] = cell[0] + (uint64_t)b, hy[b] = (cell[1] + (uint64_t)b) * r, hz[b] = (cell[2] + (uint64_t)b) * r2;
        for (int k = 0; k < 8; k++)
            c->idx[k] = v->offset + hx[k & 1] + hy[(k >> 1) & 1] + hz[k >> 2];
    } else {
        for (int b = 0; b < 2; b++)
            hx[b] = (uint32_t)((cell[0] + (uint32_t)b) * PRIMES[0]), hy[b] = (uint32_t)((cell[1] + (uint32_t)b) * PRIMES[1]),
            hz[b] = (uint32_t)((cell[2] + (uint32_t)b) * PRIMES[2]);
        for (int k = 0; k < 8; k++)
            c->idx[k] = v->offset + ((hx[k & 1] ^ hy[(k >> 1) & 1] ^ hz[k >> 2]) & (T - 1));
    }
    for (int k = 0; k < 8; k++) c->w[k] = wx[k & 1] * wy[(k >> 1) & 1] * wz[k >> 2];
}

static inline __attribute__((always_inline)) void level_corners(const level *v, uint64_t T, const float *x,
                                                                corners *c)
{
    uint32_t cell[3];
    level_cells(v, 3, x, cell, c->frac);
    for (int d = 0; d < 3; d++) c->inside[d] = x[d] >= 0.0f && x[d] <= 1.0f;
    corners_from(v, T, cell, c->frac, c);
}

#define BLK 256 /* points per block of level_cells */
#define AHEAD 16  /* points between a corner's prefetch and its use */

/* Level-major loops: one level's table slice stays in the caches while every point visits it; point-major order
 * would sweep the whole table per point. The order in which points add into one gradient entry is still the point
 * order, so results equal the point-major ones. A block's corners are computed first and fetched AHEAD points before
 * their use: the gathers then overlap instead of each waiting on its cache miss (the hashed levels of a 2^19 table
 * are 4 MiB each, larger than L2). */
typedef struct level_walk {
    const level *v;
    uint64_t T;
    int i0, cnt; /* the block held: points [i0, i0 + cnt) */
    uint32_t cell[3 * BLK];
    float frac[3 * BLK];
    uint64_t idx[BLK][8];
    float w[BLK][8];
} level_walk;

static inline void walk_start(level_walk *lw, const nerf_hashgrid *g, int l)
{
    lw->v = &g->lv[l];
    lw->T = (uint64_t)1 << g->cfg.log2_table;
    lw->i0 = lw->cnt = 0;
}

/* Fills the block that starts at point i of x[3n] with its corners. */
static inline __attribute__((always_inline)) void walk_block(level_walk *lw, int n, const float *x, int i)
{
    lw->i0 = i;
    lw->cnt = n - i < BLK ? n - i : BLK;
    level_cells(lw->v, 3 * lw->cnt, x + 3 * (size_t)i, lw->cell, lw->frac);
    for (int j = 0; j < lw->cnt; j++) {
        corners c;
        corners_from(lw->v, lw->T, lw->cell + 3 * j, lw->frac + 3 * j, &c);
        memcpy(lw->idx[j], c.idx, sizeof c.idx);
        memcpy(lw->w[j], c.w, sizeof c.w);
    }
}

/* Corner indices and weights of point i (points in order 0, 1, …; a new block is filled at each BLK), after
 * prefetching point i + AHEAD's entries in table (F floats each; write: for a scatter-add). */
static inline __attribute__((always_inline)) int walk_next(level_walk *lw, int n, const float *x, int i,
                                                           const float *table, int F, int write)
{
    if (i == lw->i0 + lw->cnt || i == 0) walk_block(lw, n, x, i);
    const int j = i - lw->i0;
    if (j + AHEAD < lw->cnt)
        for (int k = 0; k < 8; k++) {
            const float *e = table + lw->idx[j + AHEAD][k] * F;
            if (write) __builtin_prefetch(e, 1, 3);
            else __builtin_prefetch(e, 0, 3);
        }
    return j;
}

/* clang before 16 exports a target_clones function as NAME.ifunc, which other files' calls do not link to
 * (the fuzzers are built with clang): a single version there */
#if defined(__clang__) && __clang_major__ < 16
#define CLONES
#else
#define CLONES __attribute__((target_clones("avx2", "default")))
#endif

/* One level of the forward: y[i·ldy + col + f] for every point. */
CLONES static void level_forward(const nerf_hashgrid *g, const float *table, int n, const float *x, float *y,
                                 int ldy, int col, int l)
{
    const int F = g->cfg.n_features;
    level_walk lw;
    walk_start(&lw, g, l);
    for (int i = 0; i < n; i++) {
        const int j = walk_next(&lw, n, x, i, table, F, 0);
        const uint64_t *idx = lw.idx[j];
        const float *w = lw.w[j];
        float *yi = y + (size_t)i * ldy + col;
        if (F == 2) {
            float a0 = 0.0f, a1 = 0.0f;
            for (int k = 0; k < 8; k++) {
                const float *e = table + idx[k] * 2;
                a0 += w[k] * e[0];
                a1 += w[k] * e[1];
            }
            yi[0] = a0, yi[1] = a1;
        } else {
            float acc[8] = {0};
            for (int k = 0; k < 8; k++) {
                const float *e = table + idx[k] * F;
                for (int f = 0; f < F; f++) acc[f] += w[k] * e[f];
            }
            for (int f = 0; f < F; f++) yi[f] = acc[f];
        }
    }
}

/* One level of the table gradient (dy[i·lddy + col + f]): the entries of level l only, points in order. */
CLONES static void level_backward_table(const nerf_hashgrid *g, int n, const float *x, const float *dy, int lddy,
                                        int col, float *dtable, int l)
{
    const int F = g->cfg.n_features;
    level_walk lw;
    walk_start(&lw, g, l);
    for (int i = 0; i < n; i++) {
        const int j = walk_next(&lw, n, x, i, dtable, F, 1);
        const uint64_t *idx = lw.idx[j];
        const float *w = lw.w[j];
        const float *gl = dy + (size_t)i * lddy + col;
        if (F == 2) {
            const float g0 = gl[0], g1 = gl[1];
            for (int k = 0; k < 8; k++) {
                float *e = dtable + idx[k] * 2;
                e[0] += w[k] * g0;
                e[1] += w[k] * g1;
            }
        } else {
            for (int k = 0; k < 8; k++) {
                float *e = dtable + idx[k] * F;
                for (int f = 0; f < F; f++) e[f] += w[k] * gl[f];
            }
        }
    }
}

/* One level's contribution to the position gradient, added to dx. */
CLONES static void level_backward_pos(const nerf_hashgrid *g, const float *table, int n, const float *x,
                                      const float *dy, int lddy, float *dx, int l)
{
    const int F = g->cfg.n_features;
    const uint64_t T = (uint64_t)1 << g->cfg.log2_table;
    const level *v = &g->lv[l];
    const float sc = (float)v->scale;
    for (int i = 0; i < n; i++) {
        corners c;
        level_corners(v, T, x + 3 * (size_t)i, &c);
        const float *gl = dy + (size_t)i * lddy + l * F;
        /* ∂y/∂p_d = Σ_k ±(product of the other two weights)·e_k; float sums over 8 corners */
        float gl3[3] = {0, 0, 0};
        const float fr[3][2] = {{1.0f - c.frac[0], c.frac[0]}, {1.0f - c.frac[1], c.frac[1]},
                                {1.0f - c.frac[2], c.frac[2]}};
        for (int k = 0; k < 8; k++) {
            const float *e = table + c.idx[k] * F;
            float dot = 0.0f;
            for (int f = 0; f < F; f++) dot += e[f] * gl[f];
            const int b0 = k & 1, b1 = (k >> 1) & 1, b2 = k >> 2;
            gl3[0] += (b0 ? 1.0f : -1.0f) * fr[1][b1] * fr[2][b2] * dot;
            gl3[1] += (b1 ? 1.0f : -1.0f) * fr[0][b0] * fr[2][b2] * dot;
            gl3[2] += (b2 ? 1.0f : -1.0f) * fr[0][b0] * fr[1][b1] * dot;
        }
        for (int d = 0; d < 3; d++)
            if (c.inside[d]) dx[3 * (size_t)i + d] += sc * gl3[d];
    }
}

void nerf_hashgrid_forward(const nerf_hashgrid *g, const float *table, int n, const float *x, float *y, int ldy)
{
    for (int l = 0; l < g->cfg.n_levels; l++) level_forward(g, table, n, x, y, ldy, l * g->cfg.n_features, l);
}

void nerf_hashgrid_forward_level(const nerf_hashgrid *g, const float *table, int n, const float *x, float *y,
                                 int ldy, int l)
{
    level_forward(g, table, n, x, y, ldy, 0, l);
}

void nerf_hashgrid_backward(const nerf_hashgrid *g, const float *table, int n, const float *x, const float *dy,
                            int lddy, float *dtable, float *dx)
{
    if (dx) memset(dx, 0, 3 * (size_t)n * sizeof *dx);
    for (int l = 0; l < g->cfg.n_levels; l++) {
        if (dtable) level_backward_table(g, n, x, dy, lddy, l * g->cfg.n_features, dtable, l);
        if (dx) level_backward_pos(g, table, n, x, dy, lddy, dx, l);
    }
}

void nerf_hashgrid_backward_level(const nerf_hashgrid *g, int n, const float *x, const float *dy, int lddy,
                                  float *dtable, int l)
{
    level_backward_table(g, n, x, dy, lddy, 0, dtable, l);
}
