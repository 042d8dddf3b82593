/* recon/nerf/layernorm.c — layer normalisation (see layernorm.h).
 *
 * Row sums run in double over four interleaved partial sums (channel c into partial c mod 4), combined as
 * (s0 + s1) + (s2 + s3): four independent add chains instead of one C-long chain (the single chain made LN
 * latency-bound, 4 cycles per channel), and a fixed order that no clone or vector width changes.
 */
#include "recon/nerf/layernorm.h"

#include <math.h>
#include <stddef.h>

/* clang before 16 exports a target_clones function as NAME.ifunc, which other files' calls do not link to
 * (the fuzzers are built with clang): a single version there */
#if defined(__clang__) && __clang_major__ < 16
#define CLONES
#else
#define CLONES __attribute__((target_clones("avx2", "default")))
#endif

static inline double sum4(const double s[4]) { return (s[0] + s[1]) + (s[2] + s[3]); }

CLONES void nerf_layernorm_forward(int n, int C, const float *gamma, const float *beta, const float *x, int ldx,
                                   float *y, int ldy, float *xhat, float *rstd)
{
    const int C4 = C & ~3;
    for (int i = 0; i < n; i++) {
        const float *xi = x + (size_t)i * ldx;
        double s[4] = {0, 0, 0, 0};
        for (int c = 0; c < C4; c += 4)
            for (int k = 0; k < 4; k++) s[k] += xi[c + k];
        for (int c = C4; c < C; c++) s[c & 3] += xi[c];
        double mu = sum4(s) / C;
        double v[4] = {0, 0, 0, 0};
        for (int c = 0; c < C4; c += 4)
            for (int k = 0; k < 4; k++) v[k] += (xi[c + k] - mu) * (xi[c + k] - mu);
        for (int c = C4; c < C; c++) v[c & 3] += (xi[c] - mu) * (xi[c] - mu);
        double r = 1.0 / sqrt(sum4(v) / C + NERF_LAYERNORM_EPS);
        float *hi = xhat + (size_t)i * C, *yi = y + (size_t)i * ldy;
        for (int c = 0; c < C; c++) {
            float h = (float)((xi[c] - mu) * r);
            hi[c] = h;
            yi[c] = h * gamma[c] + beta[c];
        }
        rstd[i] = (float)r;
    }
}

CLONES void nerf_layernorm_apply(int n, int C, const float *gamma, const float *beta, const float *xhat, float *y,
                                 int ldy)
{
    for (int i = 0; i < n; i++) {
        const float *hi = xhat + (size_t)i * C;
        float *yi = y + (size_t)i * ldy;
        for (int c = 0; c < C; c++) yi[c] = hi[c] * gamma[c] + beta[c];
    }
}

CLONES void nerf_layernorm_backward(int n, int C, const float *gamma, const float *xhat, const float *rstd,
                                    const float *dy, int lddy, float *dx, int lddx, int accumulate_dx,
                                    float *dgamma, float *dbeta)
{
    double dg[256], db[256]; /* C <= 256 (asserted by the callers' plans) */
    int track = dgamma || dbeta;
    const int C4 = C & ~3;
    if (track)
        for (int c = 0; c < C; c++) dg[c] = db[c] = 0.0;
    for (int i = 0; i < n; i++) {
        const float *hi = xhat + (size_t)i * C, *gi = dy + (size_t)i * lddy;
        double a[4] = {0, 0, 0, 0}, b[4] = {0, 0, 0, 0};
        for (int c = 0; c < C4; c += 4)
            for (int k = 0; k < 4; k++) {
                double g = (double)gi[c + k] * gamma[c + k];
                a[k] += g;
                b[k] += g * hi[c + k];
            }
        for (int c = C4; c < C; c++) {
            double g = (double)gi[c] * gamma[c];
            a[c & 3] += g;
            b[c & 3] += g * hi[c];
        }
        if (track)
            for (int c = 0; c < C; c++) {
                dg[c] += (double)gi[c] * hi[c];
                db[c] += gi[c];
            }
        double m1 = sum4(a) / C, m2 = sum4(b) / C;
        float *di = dx + (size_t)i * lddx;
        double r = rstd[i];
        if (accumulate_dx)
            for (int c = 0; c < C; c++) di[c] += (float)(r * ((double)gi[c] * gamma[c] - m1 - hi[c] * m2));
        else
            for (int c = 0; c < C; c++) di[c] = (float)(r * ((double)gi[c] * gamma[c] - m1 - hi[c] * m2));
    }
    if (dgamma)
        for (int c = 0; c < C; c++) dgamma[c] += (float)dg[c];
    if (dbeta)
        for (int c = 0; c < C; c++) dbeta[c] += (float)db[c];
}
