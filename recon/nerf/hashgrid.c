/* recon/nerf/hashgrid.c — multiresolution hash encoding (see hashgrid.h). */
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
 * per-dimension clamp flags and fractions needed for the position gradient. */
typedef struct corners {
    uint64_t idx[8];
    float w[8];
    float frac[3];
    int inside[3];
} corners;

static inline void level_corners(const level *v, uint64_t T, const float *x, corners *c)
{
    uint32_t cell[3];
    for (int d = 0; d < 3; d++) {
        float xd = x[d];
        c->inside[d] = xd >= 0.0f && xd <= 1.0f;
        xd = xd < 0.0f ? 0.0f : (xd > 1.0f ? 1.0f : xd);
        if (xd != xd) xd = 0.0f, c->inside[d] = 0; /* NaN: a safe index; the caller validated inputs */
        double p = v->scale * (double)xd + 0.5;
        double fl = (double)(uint32_t)p; /* p >= 0.5: truncation is floor, without a libm call */
        cell[d] = (uint32_t)fl;
        c->frac[d] = (float)(p - fl);
    }
    for (int k = 0; k < 8; k++) {
        uint32_t q[3];
        float w = 1.0f;
        for (int d = 0; d < 3; d++) {
            int bit = (k >> d) & 1;
            q[d] = cell[d] + (uint32_t)bit;
            w *= bit ? c->frac[d] : 1.0f - c->frac[d];
        }
        uint64_t id;
        if (v->dense)
            id = (uint64_t)q[0] + (uint64_t)q[1] * v->res + (uint64_t)q[2] * v->res * v->res;
        else
            id = (uint64_t)((q[0] * PRIMES[0]) ^ (q[1] * PRIMES[1]) ^ (q[2] * PRIMES[2])) & (T - 1);
        c->idx[k] = v->offset + id;
        c->w[k] = w;
    }
}

void nerf_hashgrid_forward(const nerf_hashgrid *g, const float *table, int n, const float *x, float *y, int ldy)
{
    const int L = g->cfg.n_levels, F = g->cfg.n_features;
    const uint64_t T = (uint64_t)1 << g->cfg.log2_table;
    for (int i = 0; i < n; i++) {
        const float *xi = x + 3 * (size_t)i;
        float *yi = y + (size_t)i * ldy;
        for (int l = 0; l < L; l++) {
            corners c;
            level_corners(&g->lv[l], T, xi, &c);
            float acc[8] = {0};
            for (int k = 0; k < 8; k++) {
                const float *e = table + c.idx[k] * F;
                for (int f = 0; f < F; f++) acc[f] += c.w[k] * e[f];
            }
            for (int f = 0; f < F; f++) yi[l * F + f] = acc[f];
        }
    }
}

void nerf_hashgrid_backward(const nerf_hashgrid *g, const float *table, int n, const float *x, const float *dy,
                            int lddy, float *dtable, float *dx)
{
    const int L = g->cfg.n_levels, F = g->cfg.n_features;
    const uint64_t T = (uint64_t)1 << g->cfg.log2_table;
    for (int i = 0; i < n; i++) {
        const float *xi = x + 3 * (size_t)i, *gi = dy + (size_t)i * lddy;
        double gx[3] = {0, 0, 0};
        for (int l = 0; l < L; l++) {
            const level *v = &g->lv[l];
            corners c;
            level_corners(v, T, xi, &c);
            const float *gl = gi + l * F;
            if (dtable)
                for (int k = 0; k < 8; k++) {
                    float *e = dtable + c.idx[k] * F;
                    for (int f = 0; f < F; f++) e[f] += c.w[k] * gl[f];
                }
            if (dx) {
                double gl3[3] = {0, 0, 0};
                for (int k = 0; k < 8; k++) {
                    const float *e = table + c.idx[k] * F;
                    double dot = 0.0;
                    for (int f = 0; f < F; f++) dot += (double)e[f] * gl[f];
                    for (int d = 0; d < 3; d++) {
                        double wd = ((k >> d) & 1) ? 1.0 : -1.0;
                        for (int o = 0; o < 3; o++)
                            if (o != d) wd *= ((k >> o) & 1) ? c.frac[o] : 1.0f - c.frac[o];
                        gl3[d] += wd * dot;
                    }
                }
                for (int d = 0; d < 3; d++)
                    if (c.inside[d]) gx[d] += v->scale * gl3[d];
            }
        }
        if (dx)
            for (int d = 0; d < 3; d++) dx[3 * (size_t)i + d] = (float)gx[d];
    }
}
