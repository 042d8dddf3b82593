/* recon/nerf/loss.c — measurement and TV losses (see loss.h). */
#include "recon/nerf/loss.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>

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

double nerf_loss_distortion(int n_rays, int L, const float *sigma, const float *delta, double weight,
                            float *d_sigma)
{
    double total = 0.0;
    double buf[3 * 256 + 1], *heap = NULL;
    double *w = buf;
    if (L > 256) {
        heap = malloc((3 * (size_t)L + 1) * sizeof *heap);
        if (!heap)
            return NAN; /* the caller's divergence check stops the run */
        w = heap;
    }
    double *T = w + L, *g = T + L + 1;
    const int n = L;
    for (int k = 0; k < n_rays; k++) {
        const float *sg = sigma + (size_t)k * L, *dl = delta + (size_t)k * L;
        double loss = 0.0;
        double logT = 0.0;
        for (int i = 0; i < n; i++) {
            double tau = (double)sg[i] * dl[i];
            T[i] = exp(logT);
            w[i] = T[i] * -expm1(-tau);
            logT -= tau;
        }
        T[n] = exp(logT);
        /* Σ_j w_j |m_i − m_j| with prefix sums over the sorted midpoints m_i = (i + 0.5)/L */
        double Wtot = 0.0, WMtot = 0.0;
        for (int i = 0; i < n; i++) {
            Wtot += w[i];
            WMtot += w[i] * (i + 0.5) / L;
        }
        double Wlo = 0.0, WMlo = 0.0;
        for (int i = 0; i < n; i++) {
            double m = (i + 0.5) / L;
            double Whi = Wtot - Wlo - w[i], WMhi = WMtot - WMlo - w[i] * m;
            double d = m * Wlo - WMlo + WMhi - m * Whi; /* Σ_j w_j |m − m_j| */
            loss += w[i] * d + w[i] * w[i] / (3.0 * L);
            g[i] = 2.0 * d + 2.0 * w[i] / (3.0 * L);
            Wlo += w[i];
            WMlo += w[i] * m;
        }
        total += loss;
        if (d_sigma) {
            /* ∂/∂τ_j = g_j T_{j+1} − Σ_{i>j} g_i w_i */
            double suffix = 0.0;
            for (int i = n - 1; i >= 0; i--) {
                double dtau = g[i] * T[i + 1] - suffix;
                suffix += g[i] * w[i];
                d_sigma[(size_t)k * L + i] += (float)(weight * dtau * dl[i]);
            }
        }
    }
    free(heap);
    return weight * total;
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
