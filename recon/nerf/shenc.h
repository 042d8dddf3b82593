/* recon/nerf/shenc.h — real spherical-harmonics direction encoding up to degree 4 (16 outputs).
 *
 * Constants and sign convention of tiny-cuda-nn (`common_device.h`, docs/conventions.md §9), evaluated on the
 * unit direction (x, y, z) itself: this API takes the direction, not tiny-cuda-nn's (d + 1)/2, so there is no
 * factor 2 in the backward. degree 1…4 gives degree² outputs. The backward is the gradient of the polynomials
 * with respect to (x, y, z) as given (no projection onto the sphere: the caller normalised and owns that step).
 * Runs on the calling thread; reentrant.
 */
#ifndef SCICAP_RECON_NERF_SHENC_H
#define SCICAP_RECON_NERF_SHENC_H

#define NERF_SH_MAX_DEGREE 4

static inline int nerf_sh_dim(int degree) { return degree * degree; }

/* The 16 basis values and their gradients at (x, y, z), in double (also the tests' reference). */
void nerf_sh_eval(double x, double y, double z, double v[16], double g[16][3]);
/* d: n×3 unit directions; y: n×degree² (stride ldy). */
void nerf_sh_forward(int n, int degree, const float *d, float *y, int ldy);
/* dy: n×degree² (stride lddy); dd: n×3 overwritten (or += when accumulate). */
void nerf_sh_backward(int n, int degree, const float *d, const float *dy, int lddy, float *dd, int accumulate);

#endif
