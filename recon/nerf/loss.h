/* recon/nerf/loss.h — training losses with gradients, sums in double.
 *
 * Measurement loss (SCI forward model, eq. "loss" of rayformer.tex): for P pixels, N frames, ch channels,
 *   L = Σ_p Σ_ch (Y[p][ch] − Σ_i M[i][p]·C[i][p][ch])²,   ∂L/∂C[i][p][ch] = −2·M[i][p]·r[p][ch].
 * Layouts: Y P×ch, M N×P, C N×P×ch. A non-finite C makes the loss non-finite (it is not masked away: masks multiply
 * only values the caller has checked, §13 of sci-reconstruction.md).
 *
 * Anisotropic TV over rendered patches: patches of W×H pixels (pixel (x, y) of patch q at (q·H + y)·W + x, ch
 * channels), TV = Σ over horizontal and vertical neighbour differences d of ρ(d), ρ(d) = sqrt(d² + ε²) − ε
 * (ε = 0: |d|, with the subgradient 0 at d = 0). Returned already multiplied by `weight`.
 * Gradients accumulate (+=) into dC (NULL: loss only). Reentrant; single-threaded (these are tiny next to the net).
 */
#ifndef SCICAP_RECON_NERF_LOSS_H
#define SCICAP_RECON_NERF_LOSS_H

double nerf_loss_measurement(int P, int N, int ch, const float *Y, const float *M, const float *C, float *dC);
double nerf_loss_tv(int n_patches, int W, int H, int ch, const float *C, double eps, double weight, float *dC);

#endif
