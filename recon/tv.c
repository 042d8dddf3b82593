#include "recon/tv.h"

#include <assert.h>
#include <errno.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#define TV_ALPHA 5.0f

struct sci_tv {
    int w, h, nthreads;
    float *work; /* per thread: zh h*(w-1), zv (h-1)*w, two row buffers of w */
    size_t per_thread;
};

int sci_tv_new(sci_tv **out, int w, int h, sci_error *err)
{
    *out = NULL;
    if (w < 1 || h < 1)
        return sci_error_set(err, -EINVAL, "tv: frame size %dx%d", w, h);
    sci_tv *tv = calloc(1, sizeof *tv);
    if (!tv)
        return sci_error_set(err, -ENOMEM, "tv: out of memory");
    tv->w = w;
    tv->h = h;
    tv->nthreads = omp_get_max_threads();
    /* Round each thread's block to 64 bytes so threads never share a cache line. */
    tv->per_thread = ((size_t)h * w * 2 + 2 * (size_t)w + 15) & ~(size_t)15;
    tv->work = aligned_alloc(64, tv->per_thread * tv->nthreads * sizeof(float));
    if (!tv->work) {
        free(tv);
        return sci_error_set(err, -ENOMEM, "tv: out of memory for %dx%d workspace", w, h);
    }
    *out = tv;
    return 0;
}

void sci_tv_free(sci_tv *tv)
{
    if (!tv)
        return;
    free(tv->work);
    free(tv);
}

static inline float clipf(float z, float t) { return z > t ? t : (z < -t ? -t : z); }

/* One fused sweep over the rows: u of row r from the current duals (D_hᵀ z_h needs z_h of row r, D_vᵀ z_v needs
 * z_v of rows r−1 and r), then z_h of row r and z_v of row r−1 updated from u. Each dual is read before it is
 * written within the sweep, so this equals the two-pass textbook form while touching each array once. */
void sci_tv_denoise_frame(const float *restrict f, float *u, int w, int h, float weight, int iters,
                          float *restrict zh, float *restrict zv, float *restrict rowbuf)
{
    const float t = weight * 0.5f, inv_alpha = 1.0f / TV_ALPHA;
    const int wh = w - 1; /* z_h row length */
    if (iters <= 1) {
        if (u != f)
            memcpy(u, f, (size_t)w * h * sizeof *u);
        return;
    }
    memset(zh, 0, (size_t)h * (wh > 0 ? wh : 0) * sizeof *zh);
    memset(zv, 0, (size_t)(h > 1 ? h - 1 : 0) * w * sizeof *zv);
    float *prev = rowbuf, *cur = rowbuf + w;
    for (int it = 0; it < iters; it++) {
        const int last = it == iters - 1;
        for (int r = 0; r < h; r++) {
            const float *fr = f + (size_t)r * w;
            const float *zhr = zh + (size_t)r * wh;
            const float *zvu = r > 0 ? zv + (size_t)(r - 1) * w : NULL; /* z_v row above */
            const float *zvd = r < h - 1 ? zv + (size_t)r * w : NULL;   /* z_v row at r */
            float *ur = last ? u + (size_t)r * w : cur;
            /* D_hᵀ z_h at c: z_h[c−1] − z_h[c] with zeros beyond the ends; likewise D_vᵀ z_v. */
            for (int c = 0; c < w; c++) {
                float dh = (c > 0 ? zhr[c - 1] : 0.0f) - (c < wh ? zhr[c] : 0.0f);
                float dv = (zvu ? zvu[c] : 0.0f) - (zvd ? zvd[c] : 0.0f);
                ur[c] = fr[c] - 0.5f * (dh + dv);
            }
            if (last)
                continue; /* the reference's final dual update is never used */
            float *zhw = zh + (size_t)r * wh;
            for (int c = 0; c < wh; c++)
                zhw[c] = clipf(zhw[c] + (ur[c + 1] - ur[c]) * inv_alpha, t);
            if (r > 0) {
                float *zvw = zv + (size_t)(r - 1) * w;
                for (int c = 0; c < w; c++)
                    zvw[c] = clipf(zvw[c] + (ur[c] - prev[c]) * inv_alpha, t);
            }
            float *tmp = prev;
            prev = cur;
            cur = tmp;
        }
    }
}

void sci_tv_denoise_with(sci_tv *tv, sci_cube *x, float weight, int iters,
                         void (*pre)(float *frame, int k, void *ctx), void *ctx)
{
    assert(x->w == tv->w && x->h == tv->h);
    const int w = tv->w, h = tv->h;
#pragma omp parallel for schedule(static) num_threads(tv->nthreads)
    for (int k = 0; k < x->n; k++) {
        float *work = tv->work + tv->per_thread * (size_t)omp_get_thread_num();
        float *zh = work, *zv = work + (size_t)h * w, *rows = zv + (size_t)h * w;
        float *frame = sci_cube_frame(x, k);
        if (pre)
            pre(frame, k, ctx);
        sci_tv_denoise_frame(frame, frame, w, h, weight, iters, zh, zv, rows);
    }
}

void sci_tv_denoise(sci_tv *tv, sci_cube *x, float weight, int iters)
{
    sci_tv_denoise_with(tv, x, weight, iters, NULL, NULL);
}
