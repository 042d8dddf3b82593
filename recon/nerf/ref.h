/* recon/nerf/ref.h — double-precision reference forwards of the NeRF blocks, for gradient checks.
 *
 * Straightforward loops, no threading, no tricks: the float kernels' analytic backwards are checked against
 * central finite differences of these functions (tests/unit/test_nerf_*.c), and the float forwards against their
 * values. Same shapes, layouts and parameter arrays as the float API (parameters as double copies). Exact math
 * (libm exp/erf) where the float path uses fastmath.h. Slow; not for production.
 */
#ifndef SCICAP_RECON_NERF_REF_H
#define SCICAP_RECON_NERF_REF_H

#include "recon/nerf/attention.h"
#include "recon/nerf/block.h"
#include "recon/nerf/hashgrid.h"
#include "recon/nerf/mlp.h"
#include "recon/nerf/rayformer.h"
#include "recon/nerf/render.h"

void nerf_ref_hashgrid_forward(const nerf_hashgrid *g, const double *table, int n, const double *x, double *y);
void nerf_ref_layernorm(int n, int C, const double *gamma, const double *beta, const double *x, double *y);
void nerf_ref_linear(int n, int in, int out, const double *W, const double *b, const double *x, double *y);
double nerf_ref_gelu(double x);
void nerf_ref_i2r_forward(const nerf_i2r_shape *s, int n_patches, const double *qkv, double *o);
void nerf_ref_block_forward(const nerf_block_shape *s, const double *P, int n_patches, const double *x, double *out);
/* sigma (N), rgb (N×3). */
void nerf_ref_rayformer_forward(const nerf_rayformer *net, const double *P, int n_patches, const double *pos,
                                const double *dir, double *sigma, double *rgb);
/* The MLP field (mlp.h): sigma (n), rgb (n×3); point i uses dir[(i / dir_every)·3]. */
void nerf_ref_mlp_forward(const nerf_mlp *net, const double *P, int n, const double *pos, const double *dir,
                          int dir_every, double *sigma, double *rgb);
/* Render with double inputs (same truncation rule as render.h). color n×3, depth, opacity n (nullable). */
void nerf_ref_render(int n_rays, int L, const double *sigma, const double *rgb, const double *delta,
                     const double *t, const int *n_valid, double t_stop, double *color, double *depth,
                     double *opacity);

#endif
