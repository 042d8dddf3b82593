/* recon/nerf/posenc.h — frequency (positional) encoding of NeRF / SCINeRF (nerf-pytorch `Embedder`).
 *
 * For D input dims and K frequencies 2^0 … 2^(K−1) (no factor π, as in nerf-pytorch):
 *   out = [x (if include_input), sin(2^0·x), cos(2^0·x), sin(2^1·x), cos(2^1·x), …]  each block D wide,
 * so out_dim = D·(include_input + 2K). Backward: dx = d_raw + Σ_k 2^k·(cos(2^k x)·d_sin − sin(2^k x)·d_cos).
 * Arithmetic in double per element (the high frequencies amplify rounding of x), stored float; sin and cos of
 * 2^k·x come from one libm sin/cos per value by the double-angle formulas (absolute error ≤ 2^K·1e-16). K <= 32.
 * Runs on the calling thread; reentrant.
 */
#ifndef SCICAP_RECON_NERF_POSENC_H
#define SCICAP_RECON_NERF_POSENC_H

static inline int nerf_posenc_dim(int D, int K, int include_input) { return D * ((include_input ? 1 : 0) + 2 * K); }

/* x: n×D (stride D); y: n×out_dim (stride ldy). */
void nerf_posenc_forward(int n, int D, int K, int include_input, const float *x, float *y, int ldy);
/* dy: n×out_dim (stride lddy); dx: n×D overwritten (or += when accumulate). */
void nerf_posenc_backward(int n, int D, int K, int include_input, const float *x, const float *dy, int lddy,
                          float *dx, int accumulate);

#endif
