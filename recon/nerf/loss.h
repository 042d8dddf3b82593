/* recon/nerf/loss.h — training losses with gradients, sums in double.
 *
 * Measurement loss (SCI forward model, the loss of the RayFormer paper): for P pixels, N frames, ch channels,
 *   L = Σ_p Σ_ch (Y[p][ch] − Σ_i M[i][p]·C[i][p][ch])²,   ∂L/∂C[i][p][ch] = −2·M[i][p]·r[p][ch].
 * Layouts: Y P×ch, M N×P, C N×P×ch. A non-finite C makes the loss non-finite (it is not masked away: masks multiply
 * only values the caller has checked, docs/conventions.md §13).
 *
 * Anisotropic TV over rendered patches: patches of W×H pixels (pixel (x, y) of patch q at (q·H + y)·W + x, ch
 * channels), TV = Σ over horizontal and vertical neighbour differences d of ρ(d), ρ(d) = sqrt(d² + ε²) − ε
 * (ε = 0: |d|, with the subgradient 0 at d = 0). Returned already multiplied by `weight`.
 * Gradients accumulate (+=) into dC (NULL: loss only). Reentrant; single-threaded (these are tiny next to the net).
 */
#ifndef SCICAP_RECON_NERF_LOSS_H
#define SCICAP_RECON_NERF_LOSS_H

double nerf_loss_measurement(int P, int N, int ch, const float *Y, const float *M, const float *C, float *dC);
/* Distortion loss (mip-NeRF 360, eq. 15) of n_rays rays of L samples each, on the rays' normalised bins: bin s
 * spans [s/L, (s+1)/L] (midpoint m_s, width 1/L) of the ray's spacing, whatever the depths:
 *   L_dist = Σ_i Σ_j w_i w_j |m_i − m_j| + (1/3) Σ_i w_i² / L,   w_i = T_i·(1 − exp(−σ_i δ_i)),
 * summed over rays and multiplied by `weight`. It is small only when a ray's weight sits in one compact interval
 * (a surface), large for fog. O(L) per ray (prefix sums). Gradient w.r.t. σ accumulates (+=) into d_sigma
 * (NULL: loss only): ∂/∂σ_j = δ_j·(g_j·T_{j+1} − Σ_{i>j} g_i w_i), g_i = ∂L/∂w_i. Every sample counts (no early
 * stop: past it the weights are below the render's 1e-4). */
double nerf_loss_distortion(int n_rays, int L, const float *sigma, const float *delta, double weight,
                            float *d_sigma);
double nerf_loss_tv(int n_patches, int W, int H, int ch, const float *C, double eps, double weight, float *dC);

#endif
