/* recon/nerf/linear.h — dense layer y = x·Wᵀ + b: narrow layers (in and out at most 128) through the register
 * kernels of smallgemm.h, wider ones through OpenBLAS cblas_sgemm.
 *
 * Shapes (row-major): x n×in (leading dimension ldx >= in), W out×in, b out, y n×out (ldy >= out).
 * Weights are borrowed pointers into the caller's parameter array; gradients are *accumulated* (+=) into the
 * caller's gradient arrays, so a thread can run many row blocks into its own gradient buffer and the buffers
 * are summed in a fixed order afterwards (bitwise determinism for a given thread count).
 *
 * Threading: these functions run on the calling thread (sgemm with whatever thread count OpenBLAS is set to).
 * Inside an OpenMP region call nerf_blas_single_thread() first: Debian's OpenBLAS is the pthread build and would
 * otherwise oversubscribe the cores. Reentrant on disjoint outputs.
 *
 * Precision: float32 storage and arithmetic; the bias gradient is summed in double.
 */
#ifndef SCICAP_RECON_NERF_LINEAR_H
#define SCICAP_RECON_NERF_LINEAR_H

#include <stddef.h>

/* y = x·Wᵀ + b (b may be NULL: no bias). */
void nerf_linear_forward(int n, int in, int out, const float *W, const float *b, const float *x, int ldx,
                         float *y, int ldy);
/* y += x·Wᵀ + b (residual connections; b may be NULL). */
void nerf_linear_forward_add(int n, int in, int out, const float *W, const float *b, const float *x, int ldx,
                             float *y, int ldy);
/* dx = dy·W (overwritten, or += when accumulate_dx; dx NULL skips it), dW += dyᵀ·x, db += Σ_rows dy
 * (dW, db may be NULL: no parameter gradient). */
void nerf_linear_backward(int n, int in, int out, const float *W, const float *x, int ldx, const float *dy,
                          int ldy, float *dx, int lddx, int accumulate_dx, float *dW, float *db);
/* Kaiming-uniform-style init used by the models: W ~ U(−a, a), a = gain·sqrt(3/in); b = 0 (b may be NULL);
 * draws from the caller's seeded stream. */
struct sci_rng;
void nerf_linear_init(int in, int out, float *W, float *b, double gain, struct sci_rng *rng);

/* Set OpenBLAS to one thread (process-wide setting of the library; see header comment). */
void nerf_blas_single_thread(void);
void nerf_blas_set_threads(int n);

#endif
