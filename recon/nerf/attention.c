/* recon/nerf/attention.c — I²R-MSA core (see attention.h).
 *
 * Each (group, head) gathers its keys and values transposed ([channel][token]) into scratch so that the inner
 * loops run over tokens with unit stride and vectorise; the AVX2/AVX-512 clones differ only in vector width:
 * no FMA contraction under -std=c11 and reductions under `omp simd` have a fixed order per build, so results are
 * reproducible run to run.
 */
#include "recon/nerf/attention.h"

#include <math.h>
#include <string.h>

#include "recon/nerf/fastmath.h"

#define CLONES __attribute__((target_clones("avx512f", "avx2", "default")))

size_t nerf_i2r_scratch_floats(const nerf_i2r_shape *s)
{
    int n = s->L > s->R ? s->L : s->R;
    int d = s->C / (2 * s->heads);
    return (size_t)(6 * d + 4) * (size_t)n + 64;
}

/* One group of n tokens (row_of(j) = base + j·stride), one head at channel offset c0, width d. */
static inline __attribute__((always_inline)) void group_forward(int n, int d, size_t base, size_t stride, int c0, int C, const float *qkv, int ldq,
                                 float *o, int ldo, float *lse, int lse_ld, int lse_col, float *scr)
{
    float *Kt = scr, *Vt = Kt + (size_t)d * n, *p = Vt + (size_t)d * n;
    const float scale = 1.0f / sqrtf((float)d);
    for (int j = 0; j < n; j++) {
        const float *row = qkv + (base + (size_t)j * stride) * ldq;
        for (int c = 0; c < d; c++) {
            Kt[(size_t)c * n + j] = row[C + c0 + c];
            Vt[(size_t)c * n + j] = row[2 * C + c0 + c];
        }
    }
    for (int i = 0; i < n; i++) {
        size_t ri = base + (size_t)i * stride;
        const float *q = qkv + ri * ldq + c0;
#pragma omp simd
        for (int j = 0; j < n; j++) p[j] = 0.0f;
        for (int c = 0; c < d; c++) {
            float qc = q[c] * scale;
            const float *k = Kt + (size_t)c * n;
#pragma omp simd
            for (int j = 0; j < n; j++) p[j] += qc * k[j];
        }
        float m = p[0];
#pragma omp simd reduction(max : m)
        for (int j = 1; j < n; j++) m = p[j] > m ? p[j] : m;
        float sum = 0.0f;
#pragma omp simd reduction(+ : sum)
        for (int j = 0; j < n; j++) {
            p[j] = nerf_expf(p[j] - m);
            sum += p[j];
        }
        float inv = 1.0f / sum;
        float *oi = o + ri * ldo + c0;
        for (int c = 0; c < d; c++) {
            const float *v = Vt + (size_t)c * n;
            float acc = 0.0f;
#pragma omp simd reduction(+ : acc)
            for (int j = 0; j < n; j++) acc += p[j] * v[j];
            oi[c] = acc * inv;
        }
        lse[ri * lse_ld + lse_col] = m + logf(sum);
    }
}

static inline __attribute__((always_inline)) void group_backward(int n, int d, size_t base, size_t stride, int c0, int C, const float *qkv,
                                  int ldq, const float *o, int ldo, const float *lse, int lse_ld, int lse_col,
                                  const float *dout, int lddo, float *dqkv, int ldd, float *scr)
{
    float *Kt = scr, *Vt = Kt + (size_t)d * n, *dKt = Vt + (size_t)d * n, *dVt = dKt + (size_t)d * n;
    float *p = dVt + (size_t)d * n, *dp = p + n;
    const float scale = 1.0f / sqrtf((float)d);
    for (int j = 0; j < n; j++) {
        const float *row = qkv + (base + (size_t)j * stride) * ldq;
        for (int c = 0; c < d; c++) {
            Kt[(size_t)c * n + j] = row[C + c0 + c];
            Vt[(size_t)c * n + j] = row[2 * C + c0 + c];
        }
    }
    memset(dKt, 0, 2 * (size_t)d * n * sizeof *dKt);
    for (int i = 0; i < n; i++) {
        size_t ri = base + (size_t)i * stride;
        const float *q = qkv + ri * ldq + c0, *oi = o + ri * ldo + c0, *gi = dout + ri * lddo + c0;
        float Di = 0.0f;
        for (int c = 0; c < d; c++) Di += gi[c] * oi[c];
        float l0 = lse[ri * lse_ld + lse_col];
#pragma omp simd
        for (int j = 0; j < n; j++) p[j] = 0.0f, dp[j] = 0.0f;
        for (int c = 0; c < d; c++) {
            float qc = q[c] * scale, gc = gi[c];
            const float *k = Kt + (size_t)c * n, *v = Vt + (size_t)c * n;
#pragma omp simd
            for (int j = 0; j < n; j++) {
                p[j] += qc * k[j];
                dp[j] += gc * v[j];
            }
        }
#pragma omp simd
        for (int j = 0; j < n; j++) {
            p[j] = nerf_expf(p[j] - l0);
            dp[j] = p[j] * (dp[j] - Di) * scale; /* ds_ij · scale */
        }
        float *dq = dqkv + ri * ldd + c0;
        for (int c = 0; c < d; c++) {
            const float *k = Kt + (size_t)c * n;
            float acc = 0.0f;
#pragma omp simd reduction(+ : acc)
            for (int j = 0; j < n; j++) acc += dp[j] * k[j];
            dq[c] = acc;
            float qc = q[c], gc = gi[c];
            float *dk = dKt + (size_t)c * n, *dv = dVt + (size_t)c * n;
#pragma omp simd
            for (int j = 0; j < n; j++) {
                dk[j] += qc * dp[j];
                dv[j] += gc * p[j];
            }
        }
    }
    for (int j = 0; j < n; j++) {
        float *row = dqkv + (base + (size_t)j * stride) * ldd;
        for (int c = 0; c < d; c++) {
            row[C + c0 + c] = dKt[(size_t)c * n + j];
            row[2 * C + c0 + c] = dVt[(size_t)c * n + j];
        }
    }
}

CLONES void nerf_i2r_forward(const nerf_i2r_shape *s, int n_patches, const float *qkv, int ld_qkv, float *o,
                             int ldo, float *lse, float *scratch)
{
    const int C = s->C, H = s->heads, L = s->L, R = s->R, d = C / (2 * H), half = C / 2;
    for (int pa = 0; pa < n_patches; pa++) {
        size_t p0 = (size_t)pa * R * L;
        for (int h = 0; h < H; h++) {
            for (int r = 0; r < R; r++) /* intra-ray: the L samples of ray r */
                group_forward(L, d, p0 + (size_t)r * L, 1, h * d, C, qkv, ld_qkv, o, ldo, lse, 2 * H, h, scratch);
            for (int t = 0; t < L; t++) /* inter-ray: the R rays at sample t */
                group_forward(R, d, p0 + t, (size_t)L, half + h * d, C, qkv, ld_qkv, o, ldo, lse, 2 * H, H + h,
                              scratch);
        }
    }
}

CLONES void nerf_i2r_backward(const nerf_i2r_shape *s, int n_patches, const float *qkv, int ld_qkv, const float *o,
                              int ldo, const float *lse, const float *dout, int lddo, float *dqkv, int ld_dqkv,
                              float *scratch)
{
    const int C = s->C, H = s->heads, L = s->L, R = s->R, d = C / (2 * H), half = C / 2;
    for (int pa = 0; pa < n_patches; pa++) {
        size_t p0 = (size_t)pa * R * L;
        for (int h = 0; h < H; h++) {
            for (int r = 0; r < R; r++)
                group_backward(L, d, p0 + (size_t)r * L, 1, h * d, C, qkv, ld_qkv, o, ldo, lse, 2 * H, h, dout,
                               lddo, dqkv, ld_dqkv, scratch);
            for (int t = 0; t < L; t++)
                group_backward(R, d, p0 + t, (size_t)L, half + h * d, C, qkv, ld_qkv, o, ldo, lse, 2 * H, H + h,
                               dout, lddo, dqkv, ld_dqkv, scratch);
        }
    }
}
