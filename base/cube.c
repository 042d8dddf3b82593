#include "base/cube.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

int sci_cube_new(sci_cube **out, int w, int h, int n, sci_error *err)
{
    *out = NULL;
    if (w < 1 || h < 1 || n < 1)
        return sci_error_set(err, -EINVAL, "cube size %dx%dx%d: every dimension must be at least 1", w, h, n);
    size_t count = (size_t)w * (size_t)h;
    if (count > SCI_CUBE_MAX_COUNT / (size_t)n)
        return sci_error_set(err, -EINVAL, "cube size %dx%dx%d is too large", w, h, n);
    count *= (size_t)n;
    sci_cube *c = calloc(1, sizeof *c);
    if (!c)
        return sci_error_set(err, -ENOMEM, "out of memory for a %dx%dx%d cube", w, h, n);
    size_t bytes = (count * sizeof(float) + 63) & ~(size_t)63;
    c->data = aligned_alloc(64, bytes);
    if (!c->data) {
        free(c);
        return sci_error_set(err, -ENOMEM, "out of memory for a %dx%dx%d cube (%zu bytes)", w, h, n, bytes);
    }
    memset(c->data, 0, bytes);
    c->w = w;
    c->h = h;
    c->n = n;
    *out = c;
    return 0;
}

int sci_cube_clone(sci_cube **out, const sci_cube *src, sci_error *err)
{
    int rc = sci_cube_new(out, src->w, src->h, src->n, err);
    if (rc < 0)
        return rc;
    memcpy((*out)->data, src->data, sci_cube_count(src) * sizeof(float));
    return 0;
}

void sci_cube_free(sci_cube *c)
{
    if (!c)
        return;
    free(c->data);
    free(c);
}

int sci_cube_check_finite(const sci_cube *c, const char *what, sci_error *err)
{
    size_t count = sci_cube_count(c);
    for (size_t i = 0; i < count; i++) {
        if (!isfinite(c->data[i])) {
            size_t fs = sci_cube_frame_size(c);
            int k = (int)(i / fs), y = (int)(i % fs / (size_t)c->w), x = (int)(i % (size_t)c->w);
            return sci_error_set(err, SCI_ENONFINITE, "%s: non-finite value %g at x=%d y=%d frame=%d", what,
                                 (double)c->data[i], x, y, k);
        }
    }
    return 0;
}

int sci_cube_same_shape(const sci_cube *a, const sci_cube *b)
{
    return a->w == b->w && a->h == b->h && a->n == b->n;
}

void sci_cube_minmax(const sci_cube *c, float *min, float *max)
{
    size_t count = sci_cube_count(c);
    float lo = c->data[0], hi = c->data[0];
    for (size_t i = 1; i < count; i++) {
        lo = fminf(lo, c->data[i]);
        hi = fmaxf(hi, c->data[i]);
    }
    *min = lo;
    *max = hi;
}

void sci_cube_scale(sci_cube *c, float s)
{
    size_t count = sci_cube_count(c);
    for (size_t i = 0; i < count; i++)
        c->data[i] *= s;
}
