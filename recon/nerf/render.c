/* recon/nerf/render.c — volume rendering (see render.h). */
#include "recon/nerf/render.h"

#include <math.h>
#include <stddef.h>

typedef struct totals {
    double c[3], d, logT_end;
    int used;
} totals;

static void march(const nerf_render_rays *r, int k, totals *tot)
{
    const int L = r->L, n = r->n_valid ? r->n_valid[k] : L;
    const float *sg = r->sigma + (size_t)k * L, *dl = r->delta + (size_t)k * L, *c = r->rgb + (size_t)k * L * 3;
    const float *t = r->t ? r->t + (size_t)k * L : NULL;
    const double log_stop = r->t_stop > 0.0f ? log((double)r->t_stop) : -INFINITY;
    double logT = 0.0, C0 = 0, C1 = 0, C2 = 0, D = 0;
    int i = 0;
    while (i < n) {
        double tau = (double)sg[i] * dl[i];
        double w = exp(logT) * -expm1(-tau);
        C0 += w * c[3 * i];
        C1 += w * c[3 * i + 1];
        C2 += w * c[3 * i + 2];
        if (t) D += w * t[i];
        logT -= tau;
        i++;
        if (logT < log_stop) break;
    }
    tot->c[0] = C0, tot->c[1] = C1, tot->c[2] = C2, tot->d = D, tot->logT_end = logT, tot->used = i;
}

void nerf_render_forward(const nerf_render_rays *r, float *color, float *depth, float *opacity, int *n_used)
{
    for (int k = 0; k < r->n_rays; k++) {
        totals tt;
        march(r, k, &tt);
        if (color)
            for (int a = 0; a < 3; a++) color[3 * (size_t)k + a] = (float)tt.c[a];
        if (depth) depth[k] = (float)tt.d;
        if (opacity) opacity[k] = (float)-expm1(tt.logT_end);
        if (n_used) n_used[k] = tt.used;
    }
}

void nerf_render_backward(const nerf_render_rays *r, const float *d_color, const float *d_depth,
                          const float *d_opacity, float *d_sigma, float *d_rgb, float *d_delta)
{
    const int L = r->L;
    for (int k = 0; k < r->n_rays; k++) {
        totals tt;
        march(r, k, &tt);
        const float *sg = r->sigma + (size_t)k * L, *dl = r->delta + (size_t)k * L, *c = r->rgb + (size_t)k * L * 3;
        const float *t = r->t ? r->t + (size_t)k * L : NULL;
        double gc[3] = {0, 0, 0}, gd = d_depth ? d_depth[k] : 0.0, go = d_opacity ? d_opacity[k] : 0.0;
        if (d_color)
            for (int a = 0; a < 3; a++) gc[a] = d_color[3 * (size_t)k + a];
        double Tend = exp(tt.logT_end);
        double logT = 0.0, acc[3] = {0, 0, 0}, accd = 0.0;
        for (int i = 0; i < L; i++) {
            size_t s = (size_t)k * L + i;
            if (i >= tt.used) {
                if (d_sigma) d_sigma[s] = 0.0f;
                if (d_delta) d_delta[s] = 0.0f;
                if (d_rgb) d_rgb[3 * s] = d_rgb[3 * s + 1] = d_rgb[3 * s + 2] = 0.0f;
                continue;
            }
            double tau = (double)sg[i] * dl[i];
            double w = exp(logT) * -expm1(-tau);
            double Tnext = exp(logT - tau);
            double g = 0.0;
            for (int a = 0; a < 3; a++) {
                acc[a] += w * c[3 * i + a];
                g += gc[a] * (Tnext * c[3 * i + a] - (tt.c[a] - acc[a]));
                if (d_rgb) d_rgb[3 * s + a] = (float)(w * gc[a]);
            }
            if (t) {
                accd += w * t[i];
                g += gd * (Tnext * t[i] - (tt.d - accd));
            }
            g += go * Tend;
            if (d_sigma) d_sigma[s] = (float)(g * dl[i]);
            if (d_delta) d_delta[s] = (float)(g * sg[i]);
            logT -= tau;
        }
    }
}
