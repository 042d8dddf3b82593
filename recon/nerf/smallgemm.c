/* recon/nerf/smallgemm.c — narrow matrix products in registers (see smallgemm.h).
 *
 * rows: C_i = Σ_j A_ij·B_j, B_j a padded row of nb floats in ⌈nb/16⌉ vectors; RB rows of A at a time share each
 * load of B_j, with RB·NV accumulators (NV vectors per row) kept at most 16, so they stay in zmm registers.
 * atb: D_o += Σ_i A_io·X_i, X_i a row of k floats; OB outputs o at a time, each with KV vectors of accumulators,
 * over every row i in order.
 * NV, RB and KV, OB are compile-time constants in each specialisation (switch below), so the accumulator arrays
 * become registers.
 */
#include "recon/nerf/smallgemm.h"
#include "recon/nerf/vec16.h"

#include <string.h>

/* clang before 16 exports a target_clones function as NAME.ifunc, which other files' calls do not link to
 * (the fuzzers are built with clang): a single version there */
#if defined(__clang__) && __clang_major__ < 16
#define CLONES
#else
#define CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#endif
#define INLINE static inline __attribute__((always_inline))

#define MAXV (NERF_SMALLGEMM_MAX / VW)

/* Vector v of a row of n floats: the tail vector through a zero-padded copy, so nothing past the row is read. */
INLINE vf vload_row(const float *row, int n, int v)
{
    const int rem = n - v * VW;
    if (rem >= VW) return vload(row + v * VW);
    float t[VW] = {0};
    if (rem > 0) memcpy(t, row + v * VW, (size_t)rem * sizeof *t);
    return vload(t);
}

INLINE void vstore_row(float *row, int n, int v, const vf *x)
{
    const int rem = n - v * VW;
    if (rem >= VW) {
        vstore(row + v * VW, *x);
        return;
    }
    float t[VW];
    vstore(t, *x);
    if (rem > 0) memcpy(row + v * VW, t, (size_t)rem * sizeof *t);
}

INLINE void rows_block(int m, int ka, int nb, const float *A, int lda, const float *Bp, const float *bp,
                       int accumulate, float *C, int ldc, const int NV, const int RB)
{
    int i = 0;
    for (; i + RB <= m; i += RB) {
        vf acc[4][MAXV];
        for (int r = 0; r < RB; r++)
            for (int v = 0; v < NV; v++) acc[r][v] = vload(bp + v * VW);
        for (int j = 0; j < ka; j++) {
            vf b[MAXV];
            for (int v = 0; v < NV; v++) b[v] = vload(Bp + ((size_t)j * NV + v) * VW);
            for (int r = 0; r < RB; r++) {
                const float a = A[(size_t)(i + r) * lda + j];
                for (int v = 0; v < NV; v++) acc[r][v] += a * b[v];
            }
        }
        for (int r = 0; r < RB; r++)
            for (int v = 0; v < NV; v++) {
                float *c = C + (size_t)(i + r) * ldc;
                vf x = accumulate ? vload_row(c, nb, v) + acc[r][v] : acc[r][v];
                vstore_row(c, nb, v, &x);
            }
    }
    for (; i < m; i++) { /* the rows left over, one at a time */
        vf acc[MAXV];
        for (int v = 0; v < NV; v++) acc[v] = vload(bp + v * VW);
        for (int j = 0; j < ka; j++) {
            const float a = A[(size_t)i * lda + j];
            for (int v = 0; v < NV; v++) acc[v] += a * vload(Bp + ((size_t)j * NV + v) * VW);
        }
        for (int v = 0; v < NV; v++) {
            float *c = C + (size_t)i * ldc;
            vf x = accumulate ? vload_row(c, nb, v) + acc[v] : acc[v];
            vstore_row(c, nb, v, &x);
        }
    }
}

CLONES void nerf_smallgemm_rows(int m, int ka, int nb, const float *A, int lda, const float *B, int ldb,
                                int trans_b, const float *bias, int accumulate, float *C, int ldc)
{
    const int nv = (nb + VW - 1) / VW;
    float Bp[NERF_SMALLGEMM_MAX * NERF_SMALLGEMM_MAX] __attribute__((aligned(64)));
    float bp[NERF_SMALLGEMM_MAX] __attribute__((aligned(64)));
    for (int o = 0; o < nv * VW; o++) bp[o] = bias && o < nb ? bias[o] : 0.0f;
    for (int j = 0; j < ka; j++) {
        float *row = Bp + (size_t)j * nv * VW;
        for (int o = 0; o < nb; o++) row[o] = trans_b ? B[(size_t)o * ldb + j] : B[(size_t)j * ldb + o];
        for (int o = nb; o < nv * VW; o++) row[o] = 0.0f;
    }
    switch (nv) {
    case 1: rows_block(m, ka, nb, A, lda, Bp, bp, accumulate, C, ldc, 1, 4); break;
    case 2: rows_block(m, ka, nb, A, lda, Bp, bp, accumulate, C, ldc, 2, 4); break;
    case 3: rows_block(m, ka, nb, A, lda, Bp, bp, accumulate, C, ldc, 3, 4); break;
    case 4: rows_block(m, ka, nb, A, lda, Bp, bp, accumulate, C, ldc, 4, 3); break;
    case 5: rows_block(m, ka, nb, A, lda, Bp, bp, accumulate, C, ldc, 5, 2); break;
    case 6: rows_block(m, ka, nb, A, lda, Bp, bp, accumulate, C, ldc, 6, 2); break;
    case 7: rows_block(m, ka, nb, A, lda, Bp, bp, accumulate, C, ldc, 7, 2); break;
    default: rows_block(m, ka, nb, A, lda, Bp, bp, accumulate, C, ldc, 8, 1); break;
    }
}

INLINE void atb_block(int m, int nb, int k, const float *A, int lda, const float *X, int ldx, float *D, int ldd,
                      const int KV, const int OB)
{
    int o = 0;
    for (; o < nb; o += OB) {
        const int ob = nb - o < OB ? nb - o : OB;
        vf acc[8][MAXV];
        for (int q = 0; q < OB; q++)
            for (int v = 0; v < KV; v++) acc[q][v] = q < ob ? vload_row(D + (size_t)(o + q) * ldd, k, v) : (vf){0};
        for (int i = 0; i < m; i++) {
            const float *x = X + (size_t)i * ldx, *a = A + (size_t)i * lda + o;
            vf xv[MAXV];
            for (int v = 0; v < KV; v++) xv[v] = vload_row(x, k, v);
            for (int q = 0; q < OB; q++) {
                const float s = q < ob ? a[q] : 0.0f;
                for (int v = 0; v < KV; v++) acc[q][v] += s * xv[v];
            }
        }
        for (int q = 0; q < ob; q++)
            for (int v = 0; v < KV; v++) vstore_row(D + (size_t)(o + q) * ldd, k, v, &acc[q][v]);
    }
}

CLONES void nerf_smallgemm_atb(int m, int nb, int k, const float *A, int lda, const float *X, int ldx, float *D,
                               int ldd)
{
    switch ((k + VW - 1) / VW) {
    case 1: atb_block(m, nb, k, A, lda, X, ldx, D, ldd, 1, 8); break;
    case 2: atb_block(m, nb, k, A, lda, X, ldx, D, ldd, 2, 6); break;
    case 3: atb_block(m, nb, k, A, lda, X, ldx, D, ldd, 3, 4); break;
    case 4: atb_block(m, nb, k, A, lda, X, ldx, D, ldd, 4, 3); break;
    case 5: atb_block(m, nb, k, A, lda, X, ldx, D, ldd, 5, 2); break;
    case 6: atb_block(m, nb, k, A, lda, X, ldx, D, ldd, 6, 2); break;
    case 7: atb_block(m, nb, k, A, lda, X, ldx, D, ldd, 7, 2); break;
    default: atb_block(m, nb, k, A, lda, X, ldx, D, ldd, 8, 1); break;
    }
}
