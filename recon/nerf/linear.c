/* recon/nerf/linear.c — dense layer through cblas_sgemm (see linear.h). */
#include "recon/nerf/linear.h"

#include <cblas.h>
#include <math.h>
#include <string.h>

#include "base/rng.h"
#include "recon/nerf/smallgemm.h"

void nerf_linear_forward(int n, int in, int out, const float *W, const float *b, const float *x, int ldx,
                         float *y, int ldy)
{
    if (n <= 0) return;
    if (nerf_smallgemm_fits(in, out)) {
        nerf_smallgemm_rows(n, in, out, x, ldx, W, in, 1, b, 0, y, ldy);
        return;
    }
    float beta = 0.0f;
    if (b) {
        for (int i = 0; i < n; i++) memcpy(y + (size_t)i * ldy, b, (size_t)out * sizeof *y);
        beta = 1.0f;
    }
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, n, out, in, 1.0f, x, ldx, W, in, beta, y, ldy);
}

void nerf_linear_forward_add(int n, int in, int out, const float *W, const float *b, const float *x, int ldx,
                             float *y, int ldy)
{
    if (n <= 0) return;
    if (nerf_smallgemm_fits(in, out)) {
        nerf_smallgemm_rows(n, in, out, x, ldx, W, in, 1, b, 1, y, ldy);
        return;
    }
    if (b)
        for (int i = 0; i < n; i++)
            for (int o = 0; o < out; o++) y[(size_t)i * ldy + o] += b[o];
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, n, out, in, 1.0f, x, ldx, W, in, 1.0f, y, ldy);
}

void nerf_linear_backward(int n, int in, int out, const float *W, const float *x, int ldx, const float *dy,
                          int ldy, float *dx, int lddx, int accumulate_dx, float *dW, float *db)
{
    if (n <= 0) return;
    const int small = nerf_smallgemm_fits(in, out);
    if (dx && small)
        nerf_smallgemm_rows(n, out, in, dy, ldy, W, in, 0, NULL, accumulate_dx, dx, lddx);
    else if (dx)
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, n, in, out, 1.0f, dy, ldy, W, in,
                    accumulate_dx ? 1.0f : 0.0f, dx, lddx);
    if (dW && small)
        nerf_smallgemm_atb(n, out, in, dy, ldy, x, ldx, dW, in);
    else if (dW)
        cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, out, in, n, 1.0f, dy, ldy, x, ldx, 1.0f, dW, in);
    if (db) {
        /* row-wise so the inner loop runs over contiguous outputs and vectorises; the sum per output is still
         * over rows in order, in double */
        double acc[256], *a = out <= 256 ? acc : NULL;
        if (!a) {
            for (int o = 0; o < out; o++) {
                double s = 0.0;
                for (int i = 0; i < n; i++) s += dy[(size_t)i * ldy + o];
                db[o] += (float)s;
            }
            return;
        }
        for (int o = 0; o < out; o++) a[o] = 0.0;
        for (int i = 0; i < n; i++) {
            const float *r = dy + (size_t)i * ldy;
#pragma omp simd
            for (int o = 0; o < out; o++) a[o] += r[o];
        }
        for (int o = 0; o < out; o++) db[o] += (float)a[o];
    }
}

void nerf_linear_init(int in, int out, float *W, float *b, double gain, struct sci_rng *rng)
{
    double a = gain * sqrt(3.0 / in);
    for (size_t i = 0; i < (size_t)in * out; i++) W[i] = (float)((2.0 * sci_rng_uniform(rng) - 1.0) * a);
    if (b) memset(b, 0, (size_t)out * sizeof *b);
}

void nerf_blas_single_thread(void) { openblas_set_num_threads(1); }
void nerf_blas_set_threads(int n) { openblas_set_num_threads(n); }
