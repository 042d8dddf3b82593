/* recon/nerf/hashgrid.h — 3-D multiresolution hash encoding (Instant-NGP; tiny-cuda-nn grid.h, docs/conventions.md
 * §8).
 *
 * Level l (0 … L−1) has scale s_l = N_min·b^l − 1 with b = exp((ln N_max − ln N_min)/(L − 1)), so the finest
 * level reaches N_max; a point x ∈ [0, 1]³ sits at p = s_l·x + 0.5 (the 0.5 staggers levels), corner cell
 * floor(p), trilinear weights from frac(p). A level whose vertex grid (ceil(s_l) + 2)³ fits the table is stored
 * densely (index x + y·R + z·R², 64-bit arithmetic; one more vertex per side than tiny-cuda-nn so that x = 1
 * never aliases); otherwise the corner is hashed with the standard primes {1, 2654435761, 805459861} (xor, mod T).
 * Entries per level: min(next multiple of 8 of R³, T). Features F per entry; output y[l·F + f], dim L·F.
 *
 * Parameters live in the caller's float array (`table`, nerf_hashgrid_param_count floats); the object only holds
 * the level plan and is immutable after _new, so every function is reentrant and thread-safe.
 * Coordinates outside [0, 1] are clamped (their gradient is 0 in the clamped dimension). On an exact cell border
 * the upper cell is used, so the position gradient there is the one-sided derivative from above.
 * Table gradients are sparse: only the 8·L entries a point touches are written, accumulated (+=) into the
 * caller's buffer (one per thread, summed in a fixed order, for determinism).
 * Cost: both directions run level-major (one level's slice of the table, at most T·F floats, stays in the caches
 * while every point visits it), so call them with many points at once — a thread's whole range, not one patch (4×
 * faster than point-major on 65,536 random points). A slice of RayFormer's 2^19-entry table is 4 MiB, more than
 * L2: each point's 8 corners are prefetched 16 points ahead of their use. The position gradient is summed over
 * levels in float.
 */
#ifndef SCICAP_RECON_NERF_HASHGRID_H
#define SCICAP_RECON_NERF_HASHGRID_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "base/rng.h"

typedef struct nerf_hashgrid_config {
    int n_levels;      /* L, 1 … 32 (default 16) */
    int n_features;    /* F per level, 1 … 8 (default 2) */
    int log2_table;    /* log2 T, 10 … 24 (default 19; RayFormer uses 16) */
    double base_res;   /* N_min >= 2 (default 16) */
    double finest_res; /* N_max >= N_min (default 2048) */
} nerf_hashgrid_config;

#define NERF_HASHGRID_MAX_LEVELS 32

typedef struct nerf_hashgrid nerf_hashgrid;

/* Validates the config (SCI_ECONFIG naming the field) and plans the levels. -ENOMEM. */
int nerf_hashgrid_new(nerf_hashgrid **out, const nerf_hashgrid_config *cfg, sci_error *err);
void nerf_hashgrid_free(nerf_hashgrid *g);

size_t nerf_hashgrid_param_count(const nerf_hashgrid *g); /* floats in the table */
const nerf_hashgrid_config *nerf_hashgrid_config_of(const nerf_hashgrid *g);
int nerf_hashgrid_out_dim(const nerf_hashgrid *g);        /* L·F */
/* Per-level facts for printouts and tests: scale s_l, vertices per side, entries, dense or hashed. */
void nerf_hashgrid_level(const nerf_hashgrid *g, int l, double *scale, uint64_t *res, size_t *entries, int *dense);

/* Table init U(−1e-4, 1e-4) from the caller's stream. */
void nerf_hashgrid_init(const nerf_hashgrid *g, float *table, sci_rng *rng);

/* x: n×3 in [0, 1]; y: n×(L·F) (stride ldy). */
void nerf_hashgrid_forward(const nerf_hashgrid *g, const float *table, int n, const float *x, float *y, int ldy);
/* dy: n×(L·F) (stride lddy). dtable: += (NULL: skip); dx: n×3 overwritten (NULL: skip). */
void nerf_hashgrid_backward(const nerf_hashgrid *g, const float *table, int n, const float *x, const float *dy,
                            int lddy, float *dtable, float *dx);

/* One level at a time, for splitting the work between threads by level: levels write disjoint outputs (forward)
 * and disjoint slices of the table gradient (backward), so any assignment of levels to threads gives the same bits
 * with no per-thread buffer and no reduction. y and dy hold this level's F features only: y[i·ldy + f] (a
 * level-major buffer with ldy = F keeps each level's outputs contiguous). The level's table-gradient entries get
 * the points' contributions in point order, as in nerf_hashgrid_backward. */
void nerf_hashgrid_forward_level(const nerf_hashgrid *g, const float *table, int n, const float *x, float *y,
                                 int ldy, int level);
void nerf_hashgrid_backward_level(const nerf_hashgrid *g, int n, const float *x, const float *dy, int lddy,
                                  float *dtable, int level);

#endif
