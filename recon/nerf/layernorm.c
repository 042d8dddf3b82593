/* recon/nerf/layernorm.c — layer normalisation (see layernorm.h). */
#include "recon/nerf/layernorm.h"

#include <math.h>
#include <stddef.h>

void nerf_layernorm_forward(int n, int C, const float *gamma, const float *beta, const float *x, int ldx, float *y,
                            int ldy, float *xhat, float *rstd)
{
    for (int i = 0; i < n; i++) {
        const float *xi = x + (size_t)i * ldx;
        double s = 0.0;
        for (int c = 0; c < C; c++) s += xi[c];
        double mu = s / C, v = 0.0;
        for (int c = 0; c < C; c++) v += (xi[c] - mu) * (xi[c] - mu);
        double r = 1.0 / sqrt(v / C + NERF_LAYERNORM_EPS);
        float *hi = xhat + (size_t)i * C, *yi = y + (size_t)i * ldy;
        for (int c = 0; c < C; c++) {
            float h = (float)((xi[c] - mu) * r);
            hi[c] = h;
            yi[c] = h * gamma[c] + beta[c];
        }
        rstd[i] = (float)r;
    }
}

void nerf_layernorm_apply(int n, int C, const float *gamma, const float *beta, const float *xhat, float *y, int ldy)
{
    for (int i = 0; i < n; i++) {
        const float *hi = xhat + (size_t)i * C;
        float *yi = y + (size_t)i * ldy;
        for (int c = 0; c < C; c++) yi[c] = hi[c] * gamma[c] + beta[c];
    }
}

void nerf_layernorm_backward(int n, int C, const float *gamma, const float *xhat, const float *rstd,
                             const float *dy, int lddy, float *dx, int lddx, int accumulate_dx, float *dgamma,
                             float *dbeta)
{
    double dg[256], db[256]; /* C <= 256 (asserted by the callers' plans) */
    int track = dgamma || dbeta;
    if (track)
        for (int c = 0; c < C; c++) dg[c] = db[c] = 0.0;
    for (int i = 0; i < n; i++) {
        const float *hi = xhat + (size_t)i * C, *gi = dy + (size_t)i * lddy;
        double m1 = 0.0, m2 = 0.0;
        for (int c = 0; c < C; c++) {
            double g = (double)gi[c] * gamma[c];
            m1 += g;
            m2 += g * hi[c];
            if (track) {
                dg[c] += (double)gi[c] * hi[c];
                db[c] += gi[c];
            }
        }
        m1 /= C;
        m2 /= C;
        float *di = dx + (size_t)i * lddx;
        double r = rstd[i];
        for (int c = 0; c < C; c++) {
            float v = (float)(r * ((double)gi[c] * gamma[c] - m1 - hi[c] * m2));
            di[c] = accumulate_dx ? di[c] + v : v;
        }
    }
    if (dgamma)
        for (int c = 0; c < C; c++) dgamma[c] += (float)dg[c];
    if (dbeta)
        for (int c = 0; c < C; c++) dbeta[c] += (float)db[c];
}
