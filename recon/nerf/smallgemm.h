/* recon/nerf/smallgemm.h — matrix products of narrow dense layers, in registers.
 *
 * The networks' layers are narrow (RayFormer: 32 → 96, 32 → 64, 64 → 32, 19 → 32 …) and run on about a thousand
 * rows at a time. For such shapes OpenBLAS spends much of its time packing and, under the Haswell kernels a host
 * may impose (OPENBLAS_CORETYPE), runs at half the vector width the CPU has. These kernels keep the small matrix in
 * a padded copy on the stack and the accumulators of one to four rows in vector registers (GCC vector extensions,
 * 16 floats: one zmm on the AVX-512 clone, two ymm on AVX2, four xmm otherwise).
 *
 * Shapes are row-major with leading dimensions; the narrow sizes (the layer's in and out) must be at most
 * NERF_SMALLGEMM_MAX (nerf_smallgemm_fits); the row count m is any. Outputs must not alias inputs.
 * Sums run over the inner index in order, in float (no FMA contraction under -std=c11, so every clone gives the
 * same bits). Reentrant, no allocation, no failure.
 */
#ifndef SCICAP_RECON_NERF_SMALLGEMM_H
#define SCICAP_RECON_NERF_SMALLGEMM_H

#define NERF_SMALLGEMM_MAX 128

/* 1 when both narrow sizes are in 1 … NERF_SMALLGEMM_MAX. */
static inline int nerf_smallgemm_fits(int a, int b)
{
    return a >= 1 && b >= 1 && a <= NERF_SMALLGEMM_MAX && b <= NERF_SMALLGEMM_MAX;
}

/* C (m × nb, ldc) = [C +] bias + A (m × ka, lda) · B, B being ka × nb: B[j][o] at B[j·ldb + o] (trans_b = 0) or
 * B[o·ldb + j] (trans_b = 1); bias nb floats or NULL (each row's sum starts from it). accumulate: 0 overwrites C,
 * 1 adds to it. ka, nb must fit. */
void nerf_smallgemm_rows(int m, int ka, int nb, const float *A, int lda, const float *B, int ldb, int trans_b,
                         const float *bias, int accumulate, float *C, int ldc);

/* D (nb × k, ldd) += Aᵀ·X: D[o][c] += Σ_i A[i·lda + o]·X[i·ldx + c], i = 0 … m − 1 in order. nb, k must fit. */
void nerf_smallgemm_atb(int m, int nb, int k, const float *A, int lda, const float *X, int ldx, float *D, int ldd);

#endif
