/* recon/nerf/layernorm.h — layer normalisation over the C channels of each row.
 *
 * y = x̂·γ + β, x̂ = (x − μ)·rstd, rstd = 1/sqrt(var + eps), var the biased variance; mean and variance in double.
 * The forward saves x̂ (n×C, row stride C) and rstd (n) for the backward, which needs nothing else:
 *   dx = rstd·(g − mean(g) − x̂·mean(g·x̂)), g = dy·γ;  dγ += Σ dy·x̂;  dβ += Σ dy  (sums in double).
 * Rows with constant x give x̂ = 0 and dx = rstd·(g − mean g): finite for any eps > 0.
 * Runs on the calling thread; reentrant on disjoint outputs; gradients of γ, β accumulate (+=).
 */
#ifndef SCICAP_RECON_NERF_LAYERNORM_H
#define SCICAP_RECON_NERF_LAYERNORM_H

#define NERF_LAYERNORM_EPS 1e-5

/* x: n×C (stride ldx), y: n×C (stride ldy; may alias x when ldy == ldx), xhat: n×C (stride C), rstd: n. */
void nerf_layernorm_forward(int n, int C, const float *gamma, const float *beta, const float *x, int ldx, float *y,
                            int ldy, float *xhat, float *rstd);
/* Recompute y from the saved x̂ (cheaper than storing y twice). */
void nerf_layernorm_apply(int n, int C, const float *gamma, const float *beta, const float *xhat, float *y, int ldy);
/* dx overwritten (or += when accumulate_dx). dgamma/dbeta may be NULL. */
void nerf_layernorm_backward(int n, int C, const float *gamma, const float *xhat, const float *rstd,
                             const float *dy, int lddy, float *dx, int lddx, int accumulate_dx, float *dgamma,
                             float *dbeta);

#endif
