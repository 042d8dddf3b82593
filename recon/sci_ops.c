#include "recon/sci_ops.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>

void sci_op_adjoint(const sci_cube *mask, const sci_cube *y, sci_cube *x)
{
    assert(sci_cube_same_shape(mask, x) && y->w == x->w && y->h == x->h && y->n == 1);
    const long fs = (long)sci_cube_frame_size(x);
#pragma omp parallel for schedule(static) collapse(2) if (sci_cube_count(x) >= SCI_PARALLEL_MIN)
    for (int f = 0; f < x->n; f++)
        for (int r = 0; r < x->h; r++) {
            long base = (long)r * x->w;
            const float *m = mask->data + f * fs + base, *yr = y->data + base;
            float *xr = x->data + f * fs + base;
            for (int c = 0; c < x->w; c++)
                xr[c] = m[c] * yr[c];
        }
}

long sci_op_phi_sum(const sci_cube *mask, sci_cube *phi)
{
    assert(phi->w == mask->w && phi->h == mask->h && phi->n == 1);
    const long fs = (long)sci_cube_frame_size(mask);
    long guarded = 0;
#pragma omp parallel for schedule(static) reduction(+ : guarded) if (sci_cube_count(mask) >= SCI_PARALLEL_MIN)
    for (long i = 0; i < fs; i++) {
        double s = 0;
        for (int f = 0; f < mask->n; f++) {
            double m = mask->data[f * fs + i];
            s += m * m;
        }
        if (s == 0) {
            s = 1;
            guarded++;
        }
        phi->data[i] = (float)s;
    }
    return guarded;
}

/* Row r of A(x) into yhat (if not NULL), returning Σ (y − A x)² and Σ y² of the row through num/den. */
static void forward_row(const sci_cube *mask, const sci_cube *x, const sci_cube *y, float *yhat, int r,
                        double *num, double *den)
{
    const long fs = (long)sci_cube_frame_size(x);
    const int w = x->w;
    double acc[256], nsum = 0, dsum = 0;
    for (int c0 = 0; c0 < w; c0 += 256) {
        int len = w - c0 < 256 ? w - c0 : 256;
        long base = (long)r * w + c0;
        for (int c = 0; c < len; c++)
            acc[c] = 0;
        for (int f = 0; f < x->n; f++) {
            const float *m = mask->data + f * fs + base, *xf = x->data + f * fs + base;
            for (int c = 0; c < len; c++)
                acc[c] += (double)m[c] * xf[c];
        }
        for (int c = 0; c < len; c++) {
            float a = (float)acc[c];
            double yv = y->data[base + c], d = yv - a;
            if (yhat)
                yhat[base + c] = a;
            nsum += d * d;
            dsum += yv * yv;
        }
    }
    *num = nsum;
    *den = dsum;
}

double sci_op_forward_residual(const sci_cube *mask, const sci_cube *x, const sci_cube *y, sci_cube *yhat,
                               double *rowbuf)
{
    assert(sci_cube_same_shape(mask, x) && y->w == x->w && y->h == x->h && y->n == 1);
    const int h = x->h;
    /* Per-row partial sums added in row order afterwards: an OpenMP reduction would combine the threads' sums in
     * arrival order, and the result would change in the last bits from run to run. */
#pragma omp parallel for schedule(static) if (sci_cube_count(x) >= SCI_PARALLEL_MIN)
    for (int r = 0; r < h; r++)
        forward_row(mask, x, y, yhat ? yhat->data : NULL, r, &rowbuf[2 * r], &rowbuf[2 * r + 1]);
    double num = 0, den = 0;
    for (int r = 0; r < h; r++) {
        num += rowbuf[2 * r];
        den += rowbuf[2 * r + 1];
    }
    return den > 0 ? sqrt(num / den) : sqrt(num);
}

void sci_op_forward(const sci_cube *mask, const sci_cube *x, sci_cube *y)
{
    assert(sci_cube_same_shape(mask, x) && y->w == x->w && y->h == x->h && y->n == 1);
    /* Rows in parallel, frames summed in a fixed order in double: same answer for any thread count. The residual
     * sums forward_row also returns are ignored here (y serves as its own reference). */
#pragma omp parallel for schedule(static) if (sci_cube_count(x) >= SCI_PARALLEL_MIN)
    for (int r = 0; r < x->h; r++) {
        double num, den;
        forward_row(mask, x, y, y->data, r, &num, &den);
    }
}

double sci_op_residual(const sci_cube *mask, const sci_cube *x, const sci_cube *y)
{
    double *rows = malloc(2 * (size_t)x->h * sizeof *rows);
    if (!rows)
        return NAN;
    double res = sci_op_forward_residual(mask, x, y, NULL, rows);
    free(rows);
    return res;
}
