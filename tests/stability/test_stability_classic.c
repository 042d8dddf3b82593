/* Hard cases for the classical solvers (GAP-TV, ADMM-TV) and the operators under them. Each test says why it is
 * hard. Every output must be finite, and where the answer is known, right. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "base/rng.h"
#include "recon/admmtv.h"
#include "recon/gaptv.h"
#include "recon/metrics.h"
#include "recon/sci_ops.h"

static sci_problem *problem_new(int w, int h, int n)
{
    sci_problem *p = calloc(1, sizeof *p);
    assert_int_equal(sci_cube_new(&p->mask, w, h, n, NULL), 0);
    assert_int_equal(sci_cube_new(&p->truth, w, h, n, NULL), 0);
    assert_int_equal(sci_cube_new(&p->meas, w, h, 1, NULL), 0);
    p->peak = 1;
    snprintf(p->name, sizeof p->name, "hard-case");
    return p;
}

static void random_masks(sci_problem *p, uint64_t seed, double density)
{
    sci_rng rng;
    sci_rng_seed(&rng, seed, 0);
    for (size_t i = 0; i < sci_cube_count(p->mask); i++)
        p->mask->data[i] = sci_rng_uniform(&rng) < density ? 1.0f : 0.0f;
}

static void smooth_truth(sci_problem *p, double scale)
{
    const int w = p->truth->w, h = p->truth->h;
    for (int k = 0; k < p->truth->n; k++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                sci_cube_frame(p->truth, k)[y * w + x] =
                    (float)(scale * (0.5 + 0.3 * sin(0.3 * x + 0.1 * k) * cos(0.2 * y)));
    sci_op_forward(p->mask, p->truth, p->meas);
}

static int all_finite(const sci_cube *c)
{
    for (size_t i = 0; i < sci_cube_count(c); i++)
        if (!isfinite(c->data[i]))
            return 0;
    return 1;
}

static void run_both(const sci_problem *p, int iters, double tv_weight, sci_result *g, sci_result *a)
{
    sci_gaptv_params gp;
    sci_gaptv_params_default(&gp);
    gp.iters = iters;
    gp.tv_weight = tv_weight;
    gp.ssim_every = 0;
    sci_admmtv_params ap;
    sci_admmtv_params_default(&ap);
    ap.iters = iters;
    ap.tv_weight = tv_weight;
    ap.ssim_every = 0;
    *g = (sci_result){0};
    *a = (sci_result){0};
    int rc = sci_gaptv_solve(p, &gp, g, NULL, NULL);
    if (rc != 0)
        fail_msg("gap-tv: %s", g->error.msg);
    rc = sci_admmtv_solve(p, &ap, a, NULL, NULL);
    if (rc != 0)
        fail_msg("admm-tv: %s", a->error.msg);
    assert_true(all_finite(g->frames));
    assert_true(all_finite(a->frames));
}

/* Pixels that no mask ever opens: Φ_sum = 0 there, a division by zero without the guard. They get no data
 * update and take their value from the denoiser alone: finite, and between their neighbours' values. */
static void test_mask_sum_zero(void **state)
{
    sci_problem *p = problem_new(24, 16, 4);
    random_masks(p, 11, 0.5);
    for (int k = 0; k < 4; k++)
        for (int x = 0; x < 24; x++)
            sci_cube_frame(p->mask, k)[8 * 24 + x] = 0; /* row 8 never seen */
    smooth_truth(p, 1);
    sci_result g, a;
    run_both(p, 50, 0.07, &g, &a);
    sci_result_free_contents(&g);
    sci_result_free_contents(&a);
    sci_problem_free(p);
}

/* All-ones masks: every frame is seen identically, so the data cannot tell frames apart. The solvers must
 * return the same image for every frame, equal to y/N when the truth is static. */
static void test_all_ones_masks(void **state)
{
    sci_problem *p = problem_new(16, 12, 6);
    for (size_t i = 0; i < sci_cube_count(p->mask); i++)
        p->mask->data[i] = 1;
    for (int k = 0; k < 6; k++)
        for (int i = 0; i < 16 * 12; i++)
            sci_cube_frame(p->truth, k)[i] = 0.25f;
    sci_op_forward(p->mask, p->truth, p->meas);
    sci_result g, a;
    run_both(p, 30, 0.07, &g, &a);
    for (int k = 0; k < 6; k++)
        for (int i = 0; i < 16 * 12; i++) {
            assert_true(fabsf(sci_cube_frame(g.frames, k)[i] - 0.25f) < 1e-5f);
            assert_true(fabsf(sci_cube_frame(a.frames, k)[i] - 0.25f) < 1e-3f);
        }
    sci_result_free_contents(&g);
    sci_result_free_contents(&a);
    sci_problem_free(p);
}

/* N = 1 (no compression: a masked image) and N = 48 (heavily underdetermined). */
static void test_frame_counts(void **state)
{
    const int ns[] = {1, 48};
    for (int i = 0; i < 2; i++) {
        sci_problem *p = problem_new(20, 14, ns[i]);
        random_masks(p, 3 + i, 0.5);
        smooth_truth(p, 1);
        sci_result g, a;
        run_both(p, 40, 0.07, &g, &a);
        printf("N = %d: gap-tv %.2f dB, admm-tv %.2f dB\n", ns[i], g.trace.e[39].psnr, a.trace.e[39].psnr);
        assert_true(g.trace.e[39].residual < 0.05);
        sci_result_free_contents(&g);
        sci_result_free_contents(&a);
        sci_problem_free(p);
    }
}

/* 1×1 frames (no neighbours for TV: every difference operator is empty) and odd sizes. */
static void test_tiny_and_odd_sizes(void **state)
{
    const int sz[][2] = {{1, 1}, {1, 7}, {7, 1}, {7, 5}, {33, 17}};
    for (size_t s = 0; s < sizeof sz / sizeof sz[0]; s++) {
        sci_problem *p = problem_new(sz[s][0], sz[s][1], 3);
        random_masks(p, 100 + s, 0.6);
        smooth_truth(p, 1);
        sci_result g, a;
        run_both(p, 20, 0.07, &g, &a);
        sci_result_free_contents(&g);
        sci_result_free_contents(&a);
        sci_problem_free(p);
    }
}

/* A saturated measurement (every pixel at the top of the range: truth all ones) reconstructs to ones; an all-zero
 * measurement reconstructs to exactly zero. */
static void test_saturated_and_zero(void **state)
{
    sci_problem *p = problem_new(16, 16, 4);
    random_masks(p, 5, 0.5);
    for (size_t i = 0; i < sci_cube_count(p->truth); i++)
        p->truth->data[i] = 1;
    sci_op_forward(p->mask, p->truth, p->meas);
    sci_result g, a;
    run_both(p, 60, 0.07, &g, &a);
    double mean = 0;
    for (size_t i = 0; i < sci_cube_count(g.frames); i++)
        mean += g.frames->data[i];
    mean /= (double)sci_cube_count(g.frames);
    printf("saturated: mean of reconstruction %.4f\n", mean);
    assert_true(fabs(mean - 1) < 0.02);
    sci_result_free_contents(&g);
    sci_result_free_contents(&a);
    memset(p->truth->data, 0, sci_cube_count(p->truth) * sizeof(float));
    memset(p->meas->data, 0, sci_cube_frame_size(p->meas) * sizeof(float));
    run_both(p, 20, 0.07, &g, &a);
    for (size_t i = 0; i < sci_cube_count(g.frames); i++)
        assert_true(g.frames->data[i] == 0 && a.frames->data[i] == 0);
    /* Zero measurement: ‖y‖ = 0, so the relative residual falls back to the absolute one (0), not 0/0. */
    assert_true(g.trace.e[19].residual == 0);
    sci_result_free_contents(&g);
    sci_result_free_contents(&a);
    sci_problem_free(p);
}

/* Values from 1e-6 to 1e6: GAP-TV is scale-equivariant (the TV clip threshold scales with the weight), so the
 * same problem at scale s with weight 0.07·s must give s times the unit-scale answer. Float32 holds both ends;
 * the test proves no step squares a value into overflow or flushes it to zero. */
static void test_dynamic_range(void **state)
{
    sci_problem *p = problem_new(24, 20, 4);
    random_masks(p, 9, 0.5);
    smooth_truth(p, 1);
    sci_result g1, a1;
    run_both(p, 40, 0.07, &g1, &a1);
    const double scales[] = {1e-6, 1e6};
    for (int i = 0; i < 2; i++) {
        sci_problem *q = problem_new(24, 20, 4);
        memcpy(q->mask->data, p->mask->data, sci_cube_count(p->mask) * sizeof(float));
        smooth_truth(q, scales[i]);
        q->peak = scales[i];
        sci_result g, a;
        run_both(q, 40, 0.07 * scales[i], &g, &a);
        double maxrel = 0;
        for (size_t j = 0; j < sci_cube_count(g.frames); j++)
            maxrel = fmax(maxrel, fabs(g.frames->data[j] / scales[i] - g1.frames->data[j]));
        printf("scale %g: max |x/s - x1| = %.2e\n", scales[i], maxrel);
        assert_true(maxrel < 1e-3);
        sci_result_free_contents(&g);
        sci_result_free_contents(&a);
        sci_problem_free(q);
    }
    sci_result_free_contents(&g1);
    sci_result_free_contents(&a1);
    sci_problem_free(p);
}

/* NaN or Inf anywhere in the input is refused with a clear error before any work. */
static void test_nonfinite_refused(void **state)
{
    const float bad[] = {NAN, INFINITY, -INFINITY};
    for (int b = 0; b < 3; b++)
        for (int where = 0; where < 3; where++) {
            sci_problem *p = problem_new(8, 8, 2);
            random_masks(p, 1, 0.5);
            smooth_truth(p, 1);
            sci_cube *c = where == 0 ? p->meas : where == 1 ? p->mask : p->truth;
            c->data[sci_cube_count(c) - 1] = bad[b];
            sci_gaptv_params gp;
            sci_gaptv_params_default(&gp);
            sci_result r = {0};
            assert_int_equal(sci_gaptv_solve(p, &gp, &r, NULL, NULL), SCI_ENONFINITE);
            assert_null(r.frames);
            assert_non_null(strstr(r.error.msg, "non-finite"));
            sci_admmtv_params ap;
            sci_admmtv_params_default(&ap);
            r = (sci_result){0};
            assert_int_equal(sci_admmtv_solve(p, &ap, &r, NULL, NULL), SCI_ENONFINITE);
            sci_problem_free(p);
        }
}

/* Sums over 4096×4096 pixels: accumulated in float, 16.7 million terms of 1e-8 would stall once the running sum's
 * ulp exceeds them. The operators and metrics accumulate in double, so the results match the closed form. */
static void test_large_sums_in_double(void **state)
{
    const int w = 4096, h = 4096;
    sci_cube *m, *x, *y;
    assert_int_equal(sci_cube_new(&m, w, h, 1, NULL), 0);
    assert_int_equal(sci_cube_new(&x, w, h, 1, NULL), 0);
    assert_int_equal(sci_cube_new(&y, w, h, 1, NULL), 0);
    for (size_t i = 0; i < sci_cube_count(m); i++) {
        m->data[i] = 1;
        y->data[i] = 1;
        x->data[i] = 1 - 1e-4f;
    }
    double d = 1.0 - (double)(1 - 1e-4f);
    double res = sci_op_residual(m, x, y);
    printf("4096x4096 residual %.9e (exact %.9e)\n", res, d);
    assert_true(fabs(res - d) < 1e-9);
    double psnr = sci_psnr(x, y, SCI_PEAK_FIXED, 1.0, NULL);
    assert_true(fabs(psnr - 10 * log10(1 / (d * d))) < 1e-6);
    sci_cube_free(m);
    sci_cube_free(x);
    sci_cube_free(y);
}

/* 10,000 iterations: no slow drift into divergence, the residual stays at its converged level. */
static void test_long_run(void **state)
{
    sci_problem *p = problem_new(16, 16, 4);
    random_masks(p, 21, 0.5);
    smooth_truth(p, 1);
    sci_gaptv_params gp;
    sci_gaptv_params_default(&gp);
    gp.iters = 10000;
    gp.metrics_every = 1000;
    gp.ssim_every = 0;
    sci_result r = {0};
    assert_int_equal(sci_gaptv_solve(p, &gp, &r, NULL, NULL), 0);
    assert_true(all_finite(r.frames));
    double res100 = r.trace.e[99].residual, res_end = r.trace.e[9999].residual;
    printf("gap-tv residual after 100: %.2e, after 10000: %.2e; PSNR %.2f -> %.2f dB\n", res100, res_end,
           r.trace.e[999].psnr, r.trace.e[9999].psnr);
    assert_true(res_end <= fmax(res100, 1e-4));
    sci_result_free_contents(&r);
    sci_admmtv_params ap;
    sci_admmtv_params_default(&ap);
    ap.iters = 10000;
    ap.metrics_every = 1000;
    ap.ssim_every = 0;
    r = (sci_result){0};
    assert_int_equal(sci_admmtv_solve(p, &ap, &r, NULL, NULL), 0);
    assert_true(all_finite(r.frames));
    assert_true(r.trace.e[9999].residual <= fmax(r.trace.e[99].residual, 1e-4));
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mask_sum_zero),      cmocka_unit_test(test_all_ones_masks),
        cmocka_unit_test(test_frame_counts),       cmocka_unit_test(test_tiny_and_odd_sizes),
        cmocka_unit_test(test_saturated_and_zero), cmocka_unit_test(test_dynamic_range),
        cmocka_unit_test(test_nonfinite_refused),  cmocka_unit_test(test_large_sums_in_double),
        cmocka_unit_test(test_long_run),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
