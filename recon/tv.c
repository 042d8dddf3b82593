#include "recon/tv.h"
#include "recon/sci_ops.h"

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
    tv->per_thread = (sci_tv_frame_work_floats(w, h) + 15) & ~(size_t)15;
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

/* Work layout per frame: z_h padded to w+1 columns (columns 0 and w stay zero) and z_v padded to h+1 rows (rows 0
 * and h stay zero), so D_hᵀ z_h at c is zp[c] − zp[c+1] and D_vᵀ z_v at row r is row r minus row r+1, with no
 * boundary cases inside the loops: they vectorise. */
size_t sci_tv_frame_work_floats(int w, int h) { return (size_t)h * (w + 1) + (size_t)(h + 1) * w + 2 * (size_t)w; }

/* One fused sweep over the rows per pass: u of row r from the current duals (z_h of row r, z_v of rows r−1 and r),
 * then z_h of row r and z_v between rows r−1 and r updated from u. Each dual is read before it is written within
 * the sweep, so this equals the two-pass textbook form while touching each array once per pass. */
/* Cloned for AVX2 and baseline x86-64, picked at load time: 8-wide rows where the CPU has them, and the same
 * results either way (ISO C mode keeps -ffp-contract=off, so no FMA changes the rounding). */
__attribute__((target_clones("avx2", "default")))
void sci_tv_denoise_frame(const float *f, float *u, int w, int h, float weight, int iters, float *restrict work)
{
    const float t = weight * 0.5f, inv_alpha = 1.0f / TV_ALPHA;
    if (iters <= 1) {
        if (u != f)
            memmove(u, f, (size_t)w * h * sizeof *u);
        return;
    }
    const size_t zw = (size_t)w + 1;
    float *restrict zh = work;                 /* h rows of w+1 */
    float *restrict zv = zh + (size_t)h * zw;  /* h+1 rows of w */
    float *rows = zv + (size_t)(h + 1) * w;    /* two rows of u */
    memset(zh, 0, ((size_t)h * zw + (size_t)(h + 1) * w) * sizeof *zh);
    float *prev = rows, *cur = rows + w;
    for (int it = 0; it < iters; it++) {
        const int last = it == iters - 1;
        for (int r = 0; r < h; r++) {
            const float *fr = f + (size_t)r * w;
            const float *zhr = zh + (size_t)r * zw;
            const float *zvu = zv + (size_t)r * w, *zvd = zvu + w;
            float *ur = last ? u + (size_t)r * w : cur;
            for (int c = 0; c < w; c++)
                ur[c] = fr[c] - 0.5f * ((zhr[c] - zhr[c + 1]) + (zvu[c] - zvd[c]));
            if (last)
                continue; /* the reference's final dual update is never used */
            float *zhw = zh + (size_t)r * zw + 1;
            for (int c = 0; c < w - 1; c++) {
                float z = zhw[c] + (ur[c + 1] - ur[c]) * inv_alpha;
                zhw[c] = z > t ? t : (z < -t ? -t : z);
            }
            if (r > 0) {
                float *zvw = zv + (size_t)r * w; /* between rows r−1 and r */
                for (int c = 0; c < w; c++) {
                    float z = zvw[c] + (ur[c] - prev[c]) * inv_alpha;
                    zvw[c] = z > t ? t : (z < -t ? -t : z);
                }
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
#pragma omp parallel for schedule(static) num_threads(tv->nthreads) if (sci_cube_count(x) >= SCI_PARALLEL_MIN)
    for (int k = 0; k < x->n; k++) {
        float *work = tv->work + tv->per_thread * (size_t)omp_get_thread_num();
        float *frame = sci_cube_frame(x, k);
        if (pre)
            pre(frame, k, ctx);
        sci_tv_denoise_frame(frame, frame, tv->w, tv->h, weight, iters, work);
    }
}

void sci_tv_denoise(sci_tv *tv, sci_cube *x, float weight, int iters)
{
    sci_tv_denoise_with(tv, x, weight, iters, NULL, NULL);
}
