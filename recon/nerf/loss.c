/* recon/nerf/loss.c — measurement and TV losses (see loss.h). */
#include "recon/nerf/loss.h"

#include <math.h>
#include <stddef.h>

double nerf_loss_measurement(int P, int N, int ch, const float *Y, const float *M, const float *C, float *dC)
{
    double loss = 0.0;
    for (int p = 0; p < P; p++)
        for (int a = 0; a < ch; a++) {
            double r = Y[(size_t)p * ch + a];
            for (int i = 0; i < N; i++) r -= (double)M[(size_t)i * P + p] * C[((size_t)i * P + p) * ch + a];
            loss += r * r;
            if (dC)
                for (int i = 0; i < N; i++)
                    dC[((size_t)i * P + p) * ch + a] += (float)(-2.0 * M[(size_t)i * P + p] * r);
        }
    return loss;
}

static inline double rho(double d, double eps, double *g)
{
    if (eps > 0.0) {
        double s = sqrt(d * d + eps * eps);
        *g = d / s;
        return s - eps;
    }
    *g = d > 0 ? 1.0 : (d < 0 ? -1.0 : 0.0);
    return fabs(d);
}

double nerf_loss_tv(int n_patches, int W, int H, int ch, const float *C, double eps, double weight, float *dC)
{
    double tv = 0.0;
    for (int q = 0; q < n_patches; q++)
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                for (int a = 0; a < ch; a++) {
                    size_t i0 = (((size_t)q * H + y) * W + x) * ch + a;
                    for (int dir = 0; dir < 2; dir++) {
                        if (dir == 0 && x + 1 >= W) continue;
                        if (dir == 1 && y + 1 >= H) continue;
                        size_t i1 = dir == 0 ? i0 + ch : i0 + (size_t)W * ch;
                        double g, d = (double)C[i1] - C[i0];
                        tv += rho(d, eps, &g);
                        if (dC) {
                            dC[i1] += (float)(weight * g);
                            dC[i0] -= (float)(weight * g);
                        }
                    }
                }
    return weight * tv;
}
