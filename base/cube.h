/* base/cube.h — the project's one array type: a float32 stack of n frames of h rows by w columns.
 *
 * Layout (docs/architecture.md, Contracts: Cube): frame-major, row-major within a frame, element (x, y, k) at
 * data[(k*h + y)*w + x]. MATLAB's column-major H×W×N is converted at the io boundary and nowhere else.
 * Storage is float32; reductions over a cube are done in double.
 *
 * Ownership: sci_cube_new/sci_cube_clone return a cube the caller frees with sci_cube_free (NULL is harmless).
 * The struct is visible on purpose: solvers index data directly.
 */
#ifndef SCICAP_BASE_CUBE_H
#define SCICAP_BASE_CUBE_H

#include <stddef.h>

#include "base/error.h"

typedef struct sci_cube {
    int w, h, n;  /* columns, rows, frames; each >= 1 */
    float *data;  /* w*h*n floats, 64-byte aligned, owned by the cube */
} sci_cube;

/* Largest element count a cube may hold (2^34 floats = 64 GiB): guards size arithmetic against overflow. */
#define SCI_CUBE_MAX_COUNT ((size_t)1 << 34)

/* A zero-filled cube. -EINVAL (w, h or n < 1, or the count overflows SCI_CUBE_MAX_COUNT) or -ENOMEM. */
int sci_cube_new(sci_cube **out, int w, int h, int n, sci_error *err);
/* A deep copy of `src`. */
int sci_cube_clone(sci_cube **out, const sci_cube *src, sci_error *err);
void sci_cube_free(sci_cube *c);

static inline size_t sci_cube_frame_size(const sci_cube *c) { return (size_t)c->w * (size_t)c->h; }
static inline size_t sci_cube_count(const sci_cube *c) { return sci_cube_frame_size(c) * (size_t)c->n; }
/* Pointer to frame k (0 <= k < n). Borrowed: lives as long as the cube. */
static inline float *sci_cube_frame(const sci_cube *c, int k) { return c->data + (size_t)k * sci_cube_frame_size(c); }

/* 0 if every element is finite, else SCI_ENONFINITE with a message naming `what` and the first bad
 * element as (x, y, frame) and its value. */
int sci_cube_check_finite(const sci_cube *c, const char *what, sci_error *err);
/* Same shape as `b`? */
int sci_cube_same_shape(const sci_cube *a, const sci_cube *b);
/* Minimum and maximum over the whole cube (NaN-free input assumed). */
void sci_cube_minmax(const sci_cube *c, float *min, float *max);
/* Multiply every element by s. */
void sci_cube_scale(sci_cube *c, float s);

#endif
