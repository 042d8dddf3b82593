#include "recon/nerf/patch_sampler.h"

#include <math.h>

void nerf_strata_pick(int n, int span_x, int span_y, sci_rng *rng, int *x, int *y)
{
    int gx = (int)lround(sqrt((double)n * span_x / span_y));
    gx = gx < 1 ? 1 : gx > span_x ? span_x : gx;
    int gy = (n + gx - 1) / gx;
    gy = gy > span_y ? span_y : gy;
    const uint64_t cells = (uint64_t)gx * (uint64_t)gy, start = sci_rng_below(rng, cells);
    /* cells are real intervals span/g wide, not whole pixels: a pixel split between two cells gets its share from
     * each, so every pixel is equally likely however span divides by g */
    const double sx = (double)span_x / gx, sy = (double)span_y / gy;
    for (int k = 0; k < n; k++) {
        const uint64_t c = (start + (uint64_t)k * cells / (uint64_t)n) % cells;
        const double u = sci_rng_uniform(rng), v = sci_rng_uniform(rng);
        const int px = (int)(((double)(c % (uint64_t)gx) + u) * sx), py = (int)(((double)(c / (uint64_t)gx) + v) * sy);
        x[k] = px < span_x ? px : span_x - 1;
        y[k] = py < span_y ? py : span_y - 1;
    }
}

void nerf_patch_pixels(int x0, int y0, int pw, int ph, int d, int *px, int *py)
{
    for (int y = 0; y < ph; y++)
        for (int x = 0; x < pw; x++) {
            px[y * pw + x] = x0 + d * x;
            py[y * pw + x] = y0 + d * y;
        }
}

void nerf_windows_pick(int B, int w, int h, int pw, int ph, int d0, int d1, int stratify, sci_rng *rng, int *px,
                       int *py)
{
    const int R = pw * ph, dmax = d1 > d0 ? d1 : d0;
    const int sw = nerf_patch_span(pw, dmax), sh = nerf_patch_span(ph, dmax);
    if (stratify)
        nerf_strata_pick(B, w - sw + 1, h - sh + 1, rng, px, py);
    else
        for (int b = 0; b < B; b++) {
            px[b] = (int)sci_rng_below(rng, (uint64_t)(w - sw + 1));
            py[b] = (int)sci_rng_below(rng, (uint64_t)(h - sh + 1));
        }
    /* the corners sit in px[0..B); window b's pixels go to [b·R, b·R + R), at or after corner b, so filling from the
     * last window back reads every corner before it is overwritten */
    for (int b = B - 1; b >= 0; b--) {
        const int d = dmax > d0 ? d0 + (int)sci_rng_below(rng, (uint64_t)(dmax - d0 + 1)) : d0;
        const int ox = (dmax - d) * (pw - 1) / 2, oy = (dmax - d) * (ph - 1) / 2;
        nerf_patch_pixels(px[b] + ox, py[b] + oy, pw, ph, d, px + (size_t)b * R, py + (size_t)b * R);
    }
}

int nerf_stride_at(int d_end, int d_start, int it, int iters)
{
    if (d_start <= d_end || iters < 1)
        return d_end;
    const double f = (double)(it - 1) / iters;
    const int d = (int)lround(d_start - (d_start - d_end) * f);
    return d < d_end ? d_end : d > d_start ? d_start : d;
}

int nerf_tile_count(int w, int h, int pw, int ph, int d, int ox, int oy)
{
    const int bw = pw * d, bh = ph * d;
    return (w + ox + bw - 1) / bw * ((h + oy + bh - 1) / bh) * d * d;
}

void nerf_tile_window(int t, int w, int h, int pw, int ph, int d, int ox, int oy, int *x0, int *y0)
{
    const int bw = pw * d, bh = ph * d, nx = (w + ox + bw - 1) / bw, blk = t / (d * d), off = t % (d * d);
    int bx = blk % nx * bw - ox, by = blk / nx * bh - oy;
    bx = bx < 0 ? 0 : bx > w - bw ? w - bw : bx;
    by = by < 0 ? 0 : by > h - bh ? h - bh : by;
    *x0 = bx + off % d;
    *y0 = by + off / d;
}

double nerf_depth_at(nerf_spacing sp, double near, double far, double s)
{
    switch (sp) {
    case NERF_SPACING_DISPARITY: /* uniform in 1/t */
        return 1.0 / ((1.0 - s) / near + s / far);
    case NERF_SPACING_LOG: /* uniform in log t */
        return near * pow(far / near, s);
    default:
        return near + s * (far - near);
    }
}

void nerf_rays_camera(const sci_camera *cam, int n_rays, const int *px, const int *py, int L, double near,
                      double far, nerf_spacing spacing, sci_rng *jitter, int share, float *pcam, float *dcam,
                      float *delta)
{
    if (share < 1)
        share = 1;
    sci_rng run_start = {0}; /* the jitter stream at the start of the current run of `share` rays */
    if (spacing != NERF_SPACING_LINEAR && !(near > 0))
        spacing = NERF_SPACING_LINEAR; /* disparity and log spacing need near > 0 */
    const double step = (far - near) / L;
    for (int r = 0; r < n_rays; r++) {
        /* every ray of a run replays the run's L draws: one depth per sample index across the run */
        if (jitter && r % share == 0)
            run_start = *jitter;
        else if (jitter)
            *jitter = run_start;
        double d[3] = {(px[r] + 0.5 - cam->cx) / cam->fx, -(py[r] + 0.5 - cam->cy) / cam->fy, -1.0};
        double norm = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int c = 0; c < 3; c++)
            dcam[3 * r + c] = (float)(d[c] / norm);
        for (int s = 0; s < L; s++) {
            double u = jitter ? sci_rng_uniform(jitter) : 0.5;
            size_t k = (size_t)r * L + s;
            double t, bin;
            if (spacing == NERF_SPACING_LINEAR) {
                t = near + (s + u) * step;
                bin = step;
            } else {
                t = nerf_depth_at(spacing, near, far, (s + u) / L);
                bin = nerf_depth_at(spacing, near, far, (s + 1.0) / L) - nerf_depth_at(spacing, near, far, (double)s / L);
            }
            for (int c = 0; c < 3; c++)
                pcam[3 * k + c] = (float)(d[c] * t);
            delta[k] = (float)(bin * norm);
        }
    }
}

void nerf_rays_camera_depths(const sci_camera *cam, int n_rays, const int *px, const int *py, int L, const float *t,
                             double far, float *pcam, float *dcam, float *delta)
{
    for (int r = 0; r < n_rays; r++) {
        double d[3] = {(px[r] + 0.5 - cam->cx) / cam->fx, -(py[r] + 0.5 - cam->cy) / cam->fy, -1.0};
        double norm = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int c = 0; c < 3; c++)
            dcam[3 * r + c] = (float)(d[c] / norm);
        const float *tr = t + (size_t)r * L;
        for (int s = 0; s < L; s++) {
            size_t k = (size_t)r * L + s;
            for (int c = 0; c < 3; c++)
                pcam[3 * k + c] = (float)(d[c] * tr[s]);
            double next = s + 1 < L ? tr[s + 1] : far;
            delta[k] = (float)fmax(0.0, (next - tr[s]) * norm);
        }
    }
}

void nerf_rays_to_world(const double T[12], int n_rays, int L, const float *pcam, const float *dcam, float *pos,
                        float *dir)
{
    size_t np = (size_t)n_rays * L;
    for (size_t k = 0; k < np; k++) {
        const float *p = pcam + 3 * k;
        for (int r = 0; r < 3; r++)
            pos[3 * k + r] = (float)(T[4 * r] * p[0] + T[4 * r + 1] * p[1] + T[4 * r + 2] * p[2] + T[4 * r + 3]);
    }
    for (int k = 0; k < n_rays; k++) {
        const float *p = dcam + 3 * k;
        for (int r = 0; r < 3; r++)
            dir[3 * k + r] = (float)(T[4 * r] * p[0] + T[4 * r + 1] * p[1] + T[4 * r + 2] * p[2]);
    }
}

void nerf_rays_bounds(const sci_camera *cam, int w, int h, const double (*poses)[12], int n, double near, double far,
                      double pad, float lo[3], float hi[3])
{
    double mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
    const double cx[2] = {0, w}, cy[2] = {0, h}, depth[2] = {near, far};
    for (int j = 0; j < n; j++) {
        const double *T = poses[j];
        for (int c = 0; c < 9; c++) {
            double p[3] = {0, 0, 0};
            if (c < 8) {
                double t = depth[c >> 2];
                p[0] = (cx[c & 1] - cam->cx) / cam->fx * t;
                p[1] = -(cy[(c >> 1) & 1] - cam->cy) / cam->fy * t;
                p[2] = -t;
            }
            for (int r = 0; r < 3; r++) {
                double v = T[4 * r] * p[0] + T[4 * r + 1] * p[1] + T[4 * r + 2] * p[2] + T[4 * r + 3];
                mn[r] = fmin(mn[r], v);
                mx[r] = fmax(mx[r], v);
            }
        }
    }
    for (int r = 0; r < 3; r++) {
        double ext = fmax(mx[r] - mn[r], 1e-3);
        lo[r] = (float)(mn[r] - pad * ext);
        hi[r] = (float)(mx[r] + pad * ext);
    }
}
