/* recon/nerf/block.h — the I²R transformer block of RayFormer (pre-norm):
 *
 *   x1  = x  + W_o · I2R-MSA(W_qkv · LN1(x) + b_qkv) + b_o
 *   out = x1 + W_2 · GELU(W_1 · LN2(x1) + b_1) + b_2
 *
 * (with inter_gate, the inter-ray channels of I2R-MSA's output are v + g_h·(o − v), head h's gate g_h)
 *
 * on rows of whole patches (row layout of attention.h). Parameters are one float array of nerf_block_param_count
 * floats, laid out as below (offsets in nerf_block_offsets); gradients use the same layout and accumulate (+=).
 *
 * The forward saves, per row: x̂₁ (C), rstd₁, qkv (3C), lse (2·heads), attention output (C), x̂₂ (C), rstd₂, the
 * FFN activation GELU(h) and its derivative GELU'(h) (hidden each) — nerf_block_saved_floats() per row — and
 * recomputes the LN outputs in the backward instead of storing them (GELU is kept: recomputing it cost more than
 * the 2·hidden floats). Per-thread scratch: nerf_block_scratch_floats(rows_per_call).
 * Runs on the calling thread (sgemm must be single-threaded inside OpenMP regions, see linear.h); reentrant.
 */
#ifndef SCICAP_RECON_NERF_BLOCK_H
#define SCICAP_RECON_NERF_BLOCK_H

#include <stddef.h>

#include "base/rng.h"
#include "recon/nerf/attention.h"

typedef struct nerf_block_shape {
    nerf_i2r_shape att; /* C, heads, L, R */
    int hidden;         /* feed-forward width */
    int inter_gate;     /* 1: the inter-ray path's output is v + g_h·(attention − v), a learned gate per head
                           (parameters `gate`, heads floats, 0 at init: the path starts as its pass-through and
                           mixes rays only as far as the loss asks); 0: the attention as it is (no gate parameters) */
} nerf_block_shape;

typedef struct nerf_block_offsets {
    size_t ln1_g, ln1_b, w_qkv, b_qkv, w_o, b_o, ln2_g, ln2_b, w_1, b_1, w_2, b_2, gate, total;
} nerf_block_offsets;

/* Saved activations of a whole batch: each array has rows × width floats, row r at r·width. */
typedef struct nerf_block_saved {
    float *xhat1, *rstd1, *qkv, *lse, *att, *xhat2, *rstd2, *h, *dgelu;
} nerf_block_saved;

nerf_block_offsets nerf_block_layout(const nerf_block_shape *s);
static inline size_t nerf_block_param_count(const nerf_block_shape *s) { return nerf_block_layout(s).total; }
size_t nerf_block_saved_floats(const nerf_block_shape *s); /* per row */
/* Point the saved arrays into `mem` (rows × nerf_block_saved_floats floats). */
void nerf_block_saved_bind(const nerf_block_shape *s, size_t rows, float *mem, nerf_block_saved *sv);
size_t nerf_block_scratch_floats(const nerf_block_shape *s, size_t rows);

/* LN γ = 1, β = 0; linear weights Kaiming-uniform, biases 0; the two residual-branch outputs scaled by 1/sqrt(2·depth)
 * (GPT-2 style) so a deep stack starts near the identity; inter-ray gates 0. */
void nerf_block_init(const nerf_block_shape *s, float *params, int depth, sci_rng *rng);

/* Rows [row0, row0 + n_patches·R·L) of x (n×C, stride C) → out (same rows, stride C; must not alias x). */
void nerf_block_forward(const nerf_block_shape *s, const float *params, int n_patches, size_t row0, const float *x,
                        float *out, const nerf_block_saved *sv, float *scratch);
/* d_out → d_in (both stride C, same rows; d_in may alias d_out); grad += parameter gradients. */
void nerf_block_backward(const nerf_block_shape *s, const float *params, int n_patches, size_t row0,
                         const nerf_block_saved *sv, const float *d_out, float *d_in, float *grad, float *scratch);

#endif
