/* recon/nerf/attention.h — the I²R-MSA core of RayFormer: split-channel intra-ray and inter-ray softmax attention.
 *
 * Rows are sample points of whole patches: patch p, ray r (0 … R−1, R = W·H rays of the patch), sample s
 * (0 … L−1) sits at row (p·R + r)·L + s. The input is the packed projection qkv (row = [Q | K | V], each C wide,
 * row stride ld_qkv >= 3C) made by the caller's linear layer. Channels [0, C/2) form path A: attention among the
 * L samples of one ray (intra-ray). Channels [C/2, C) form path B: attention among the R rays of the patch at the
 * same sample index (inter-ray). Each path is split into `heads` heads of d = C/(2·heads) channels (b_ij: the
 * distance biases below):
 *   o_i = Σ_j softmax_j(q_i·k_j / sqrt(d) + b_ij) v_j,   softmax with max subtraction, sums in float with the
 *   normaliser in double. The forward saves lse = max + log Σ exp per row and head (rows × 2·heads floats);
 *   the backward recomputes the probabilities from it (flash-attention style: O(n) memory, not O(n·L + n·R)),
 *   using D_i = dO_i·O_i for the softmax Jacobian, so logits of ±1e4 stay finite and exact.
 * The output o (rows × C, stride ldo) holds path A in channels [0, C/2) and path B in [C/2, C).
 * Ablation (the RayFormer paper, Table 2): a path switched off (intra_off / inter_off) passes its V channels through,
 * o_i = v_i, as if each point attended only to itself; its lse entries are 0, and the backward gives dv = do and
 * dq = dk = 0 there. The parameters stay the same, so a switched-off path is a per-point linear map.
 *
 * Runs on the calling thread over whole patches (the caller splits patches between threads); reentrant; needs
 * nerf_i2r_scratch_floats() floats of scratch per thread. Results do not depend on how patches are split.
 */
#ifndef SCICAP_RECON_NERF_ATTENTION_H
#define SCICAP_RECON_NERF_ATTENTION_H

#include <stddef.h>

typedef struct nerf_i2r_shape {
    int C;         /* channels, even, C/2 divisible by heads */
    int heads;     /* heads per path */
    int L;         /* samples per ray */
    int R;         /* rays per patch (W·H) */
    int intra_off; /* 1: path A passes V through (o_i = v_i: each point attends only to itself) — ablation */
    int inter_off; /* 1: path B passes V through — ablation */
    float intra_slope; /* >= 0: path A's head h adds −(intra_slope / 2^h)·|i − j| to the logit of sample i
                          attending to sample j (a fixed distance bias, ALiBi; 0: none — the paper's plain
                          attention). The samples of a ray carry no position otherwise: without it every sample
                          attends to the ray's samples as to a bag. */
    float inter_slope; /* >= 0: path B's head h adds −(inter_slope / 2^h)·(|xi − xj| + |yi − yj|) to the logit of
                          ray i attending to ray j, (x, y) the ray's pixel offset in its window (0: none). Without
                          it a ray cannot tell itself from its neighbours except by content. */
    int win_w;         /* the window's width in rays (rays in raster order, R a multiple of it); a power of two
                          (1, 2, 4 …) when inter_slope > 0; 0 or 1: one column */
} nerf_i2r_shape;

size_t nerf_i2r_scratch_floats(const nerf_i2r_shape *s);

/* qkv, o: rows = n_patches·R·L. lse: rows × 2·heads (path A heads first). */
void nerf_i2r_forward(const nerf_i2r_shape *s, int n_patches, const float *qkv, int ld_qkv, float *o, int ldo,
                      float *lse, float *scratch);
/* Given o and lse of the forward and the upstream do (stride lddo), write dqkv (overwritten, stride ld_dqkv). */
void nerf_i2r_backward(const nerf_i2r_shape *s, int n_patches, const float *qkv, int ld_qkv, const float *o,
                       int ldo, const float *lse, const float *dout, int lddo, float *dqkv, int ld_dqkv,
                       float *scratch);

#endif
