#include "recon/metrics.h"
#include "recon/metrics_ssim.h"
#include "recon/sci_ops.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

double sci_psnr_frame(const float *x, const float *ref, size_t n, double peak)
{
    double se = 0;
    for (size_t i = 0; i < n; i++) {
        double d = (double)x[i] - ref[i];
        se += d * d;
    }
    double mse = se / (double)n;
    if (mse == 0)
        return INFINITY;
    return 10.0 * log10(peak * peak / mse);
}

/* The mean of v[0..n), summed in frame order; v is freed unless it is the caller's per_frame. */
static double frames_mean(double *v, int n, const double *per_frame)
{
    double s = 0;
    for (int k = 0; k < n; k++)
        s += v[k];
    if (v != per_frame)
        free(v);
    return s / n;
}

double sci_psnr(const sci_cube *x, const sci_cube *truth, sci_peak conv, double peak, double *per_frame)
{
    const size_t fs = sci_cube_frame_size(x);
    double *v = per_frame ? per_frame : malloc((size_t)x->n * sizeof *v);
    if (!v)
        return NAN;
#pragma omp parallel for schedule(static) if (sci_cube_count(x) >= SCI_PARALLEL_MIN)
    for (int k = 0; k < x->n; k++) {
        const float *t = sci_cube_frame(truth, k);
        double p = peak;
        if (conv == SCI_PEAK_FRAME_MAX) {
            float m = t[0];
            for (size_t i = 1; i < fs; i++)
                m = t[i] > m ? t[i] : m;
            p = m;
        }
        v[k] = sci_psnr_frame(sci_cube_frame(x, k), t, fs, p);
    }
    return frames_mean(v, x->n, per_frame);
}

#define SSIM_RADIUS SCI_SSIM_RADIUS

/* Separable Gaussian filter with replicate padding (MATLAB imgaussfilt, 'Padding','replicate'), in double. */
/* One tap sum with edge replication: in[clamp(i + k) * stride] for k = -R..R, in order. */
static inline double gauss_tap_clamped(const double *in, int i, int len, size_t stride, const double *g)
{
    double s = 0;
    for (int k = -SSIM_RADIUS; k <= SSIM_RADIUS; k++) {
        int j = i + k < 0 ? 0 : (i + k >= len ? len - 1 : i + k);
        s += g[k + SSIM_RADIUS] * in[(size_t)j * stride];
    }
    return s;
}

/* Separable Gaussian with edge replication. Where the whole window is inside the frame the clamps are left out
 * (the loops then vectorise); every sum is formed in the same order as with the clamps, so the result is the
 * same, bit for bit. */
static void gauss_filter(const double *in, double *out, double *tmp, int w, int h, const double *g)
{
    const int R = SSIM_RADIUS;
    const int c0 = R < w ? R : w, c1 = w - R > c0 ? w - R : c0; /* interior columns [c0, c1) */
    for (int r = 0; r < h; r++) {
        const double *row = in + (size_t)r * w;
        double *t = tmp + (size_t)r * w;
        for (int c = 0; c < c0; c++)
            t[c] = gauss_tap_clamped(row, c, w, 1, g);
        for (int c = c0; c < c1; c++) {
            double s = 0;
            for (int k = -R; k <= R; k++)
                s += g[k + R] * row[c + k];
            t[c] = s;
        }
        for (int c = c1; c < w; c++)
            t[c] = gauss_tap_clamped(row, c, w, 1, g);
    }
    for (int r = 0; r < h; r++) {
        double *o = out + (size_t)r * w;
        if (r >= R && r + R < h) { /* interior rows: a whole row per tap */
            for (int c = 0; c < w; c++)
                o[c] = 0;
            for (int k = -R; k <= R; k++) {
                const double gk = g[k + R], *src = tmp + (size_t)(r + k) * w;
                for (int c = 0; c < w; c++)
                    o[c] += gk * src[c];
            }
        } else {
            for (int c = 0; c < w; c++)
                o[c] = gauss_tap_clamped(tmp + c, r, h, (size_t)w, g);
        }
    }
}

double sci_ssim_frame_filtered(const float *x, const float *ref, int w, int h, double range, sci_ssim_filter filter)
{
    const double sigma = 1.5, c1 = (0.01 * range) * (0.01 * range), c2 = (0.03 * range) * (0.03 * range);
    double g[2 * SSIM_RADIUS + 1], gs = 0;
    for (int k = -SSIM_RADIUS; k <= SSIM_RADIUS; k++)
        gs += g[k + SSIM_RADIUS] = exp(-(double)(k * k) / (2 * sigma * sigma));
    for (int k = 0; k < 2 * SSIM_RADIUS + 1; k++)
        g[k] /= gs;
    const size_t n = (size_t)w * h;
    double *buf = calloc(8 * n, sizeof *buf); /* zeroed only to keep -Wmaybe-uninitialized quiet */
    if (!buf)
        return NAN;
    double *a = buf, *b = buf + n, *tmp = buf + 2 * n, *mx = buf + 3 * n, *my = buf + 4 * n, *sxx = buf + 5 * n,
           *syy = buf + 6 * n, *sq = buf + 7 * n;
    for (size_t i = 0; i < n; i++) {
        a[i] = x[i];
        b[i] = ref[i];
    }
    filter(a, mx, tmp, w, h, g);
    filter(b, my, tmp, w, h, g);
    for (size_t i = 0; i < n; i++)
        sq[i] = a[i] * a[i];
    filter(sq, sxx, tmp, w, h, g);
    for (size_t i = 0; i < n; i++)
        sq[i] = b[i] * b[i];
    filter(sq, syy, tmp, w, h, g);
    for (size_t i = 0; i < n; i++)
        sq[i] = a[i] * b[i];
    filter(sq, b, tmp, w, h, g); /* b now holds the filtered product */
    double s = 0;
    for (size_t i = 0; i < n; i++) {
        double mux = mx[i], muy = my[i];
        double vx = sxx[i] - mux * mux, vy = syy[i] - muy * muy, cxy = b[i] - mux * muy;
        s += ((2 * mux * muy + c1) * (2 * cxy + c2)) / ((mux * mux + muy * muy + c1) * (vx + vy + c2));
    }
    free(buf);
    return s / (double)n;
}

double sci_ssim_frame(const float *x, const float *ref, int w, int h, double range)
{
    return sci_ssim_frame_filtered(x, ref, w, h, range, gauss_filter);
}

double sci_ssim(const sci_cube *x, const sci_cube *truth, double range, double *per_frame)
{
    double *v = per_frame ? per_frame : malloc((size_t)x->n * sizeof *v);
    if (!v)
        return NAN;
#pragma omp parallel for schedule(static) if (sci_cube_count(x) >= SCI_PARALLEL_MIN / 16)
    for (int k = 0; k < x->n; k++)
        v[k] = sci_ssim_frame(sci_cube_frame(x, k), sci_cube_frame(truth, k), x->w, x->h, range);
    return frames_mean(v, x->n, per_frame);
}

const char *sci_peak_name(sci_peak conv, double peak, char *buf, size_t n)
{
    if (conv == SCI_PEAK_FRAME_MAX)
        snprintf(buf, n, "peak = per-frame max of truth");
    else
        snprintf(buf, n, "peak = %g", peak);
    return buf;
}

double sci_psnr_rgb(const sci_cube *x, const sci_cube *truth, sci_peak conv, double peak, double *per_frame)
{
    const int n = x->n / 3;
    double *v = malloc((size_t)x->n * sizeof *v);
    if (!v || n < 1) {
        free(v);
        return NAN;
    }
    sci_psnr(x, truth, conv, peak, v);
    double s = 0;
    for (int f = 0; f < n; f++) {
        const double m = (v[3 * f] + v[3 * f + 1] + v[3 * f + 2]) / 3;
        if (per_frame)
            per_frame[f] = m;
        s += m;
    }
    free(v);
    return s / n;
}
