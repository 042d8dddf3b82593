/* tests/unit/test_solver_contract.c — the solver contract (recon/gaptv.h) on gap-tv and admm-tv: cancel through
 * the progress callback, divergence noticed and reported, bad input refused, results independent of thread count,
 * the trace filled every iteration. Small synthetic problems: fast. (The method table itself: test_solver.c.) */
#include <errno.h>
#include <math.h>
#include <omp.h>
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

/* A smooth moving blob under random binary masks, measured exactly. */
static sci_problem *blob_problem(int w, int h, int n, uint64_t seed)
{
    sci_problem *p = calloc(1, sizeof *p);
    assert_int_equal(sci_cube_new(&p->mask, w, h, n, NULL), 0);
    assert_int_equal(sci_cube_new(&p->truth, w, h, n, NULL), 0);
    assert_int_equal(sci_cube_new(&p->meas, w, h, 1, NULL), 0);
    sci_rng rng;
    sci_rng_seed(&rng, seed, 0);
    for (size_t i = 0; i < sci_cube_count(p->mask); i++)
        p->mask->data[i] = (float)(sci_rng_u64(&rng) & 1);
    for (int k = 0; k < n; k++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                double cx = w * (0.3 + 0.4 * k / (double)n), cy = h * 0.5;
                double d2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (0.04 * w * w);
                sci_cube_frame(p->truth, k)[y * w + x] = (float)(0.2 + 0.7 * exp(-d2));
            }
    sci_op_forward(p->mask, p->truth, p->meas);
    p->peak = 1;
    snprintf(p->name, sizeof p->name, "blob");
    return p;
}

static int cancel_at_5(const sci_trace_entry *e, void *user)
{
    (*(int *)user)++;
    return e->iter >= 5;
}

static void test_cancel(void **state)
{
    sci_problem *p = blob_problem(32, 24, 4, 1);
    sci_gaptv_params gp;
    sci_gaptv_params_default(&gp);
    int calls = 0;
    sci_result r = {0};
    assert_int_equal(sci_gaptv_solve(p, &gp, &r, cancel_at_5, &calls), SCI_ECANCELED);
    assert_int_equal(calls, 5);
    assert_int_equal(r.iters_done, 5);
    assert_int_equal((int)r.trace.len, 5);
    assert_non_null(r.frames); /* the estimate so far is kept */
    assert_non_null(strstr(r.error.msg, "canceled"));
    sci_result_free_contents(&r);
    sci_admmtv_params ap;
    sci_admmtv_params_default(&ap);
    calls = 0;
    sci_result ra = {0};
    assert_int_equal(sci_admmtv_solve(p, &ap, &ra, cancel_at_5, &calls), SCI_ECANCELED);
    assert_int_equal(ra.iters_done, 5);
    sci_result_free_contents(&ra);
    sci_problem_free(p);
}

/* Plain GAP with λ far above 2 overshoots every step: the residual grows geometrically. The solver must stop,
 * say so, and hand out no frames. */
static void test_divergence_reported(void **state)
{
    sci_problem *p = blob_problem(32, 24, 4, 2);
    sci_gaptv_params gp;
    sci_gaptv_params_default(&gp);
    gp.accelerate = 0;
    gp.lambda = 40;
    gp.tv_weight = 0;
    gp.iters = 10000;
    sci_result r = {0};
    int rc = sci_gaptv_solve(p, &gp, &r, NULL, NULL);
    printf("%s\n", r.error.msg);
    assert_int_equal(rc, SCI_EDIVERGED);
    assert_null(r.frames);
    assert_true(r.iters_done < 100);
    assert_non_null(strstr(r.error.msg, "diverged"));
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

static void test_bad_input_refused(void **state)
{
    sci_problem *p = blob_problem(16, 16, 3, 3);
    sci_gaptv_params gp;
    sci_gaptv_params_default(&gp);
    sci_result r = {0};
    p->meas->data[17] = NAN;
    assert_int_equal(sci_gaptv_solve(p, &gp, &r, NULL, NULL), SCI_ENONFINITE);
    assert_non_null(strstr(r.error.msg, "measurement"));
    assert_non_null(strstr(r.error.msg, "x=1 y=1"));
    p->meas->data[17] = 0;
    p->mask->data[5] = INFINITY;
    r = (sci_result){0};
    assert_int_equal(sci_gaptv_solve(p, &gp, &r, NULL, NULL), SCI_ENONFINITE);
    assert_non_null(strstr(r.error.msg, "masks"));
    p->mask->data[5] = 1;
    gp.lambda = -1;
    r = (sci_result){0};
    assert_int_equal(sci_gaptv_solve(p, &gp, &r, NULL, NULL), -EINVAL);
    assert_non_null(strstr(r.error.msg, "lambda"));
    sci_problem_free(p);
}

/* Frames are denoised independently and frame sums are done in double in a fixed order: 1 and 2 threads give
 * the same bits. The problem is above SCI_PARALLEL_MIN so the loops really do run on two threads. */
static void test_thread_count_independent(void **state)
{
    sci_problem *p = blob_problem(128, 96, 8, 4);
    assert_true(sci_cube_count(p->mask) >= SCI_PARALLEL_MIN);
    sci_gaptv_params gp;
    sci_gaptv_params_default(&gp);
    gp.iters = 30;
    sci_result r1 = {0}, r2 = {0};
    int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    assert_int_equal(sci_gaptv_solve(p, &gp, &r1, NULL, NULL), 0);
    omp_set_num_threads(2);
    assert_int_equal(sci_gaptv_solve(p, &gp, &r2, NULL, NULL), 0);
    omp_set_num_threads(saved);
    assert_memory_equal(r1.frames->data, r2.frames->data, sci_cube_count(r1.frames) * sizeof(float));
    assert_true(r1.trace.e[29].residual == r2.trace.e[29].residual);
    assert_true(r1.trace.e[29].psnr == r2.trace.e[29].psnr);
    sci_result_free_contents(&r1);
    sci_result_free_contents(&r2);
    sci_problem_free(p);
}

/* The trace: one row per iteration, increasing time, PSNR where asked, and reconstruction far better than
 * the back-projection on this easy problem. */
static void test_trace_and_quality(void **state)
{
    sci_problem *p = blob_problem(64, 48, 8, 5);
    sci_admmtv_params ap;
    sci_admmtv_params_default(&ap);
    ap.iters = 60;
    ap.metrics_every = 10;
    ap.ssim_every = 30;
    ap.tv_weight = 0.1;
    sci_result r = {0};
    assert_int_equal(sci_admmtv_solve(p, &ap, &r, NULL, NULL), 0);
    assert_int_equal((int)r.trace.len, 60);
    for (size_t i = 1; i < r.trace.len; i++)
        assert_true(r.trace.e[i].wall_s >= r.trace.e[i - 1].wall_s);
    assert_true(isnan(r.trace.e[0].psnr) && !isnan(r.trace.e[9].psnr) && !isnan(r.trace.e[29].ssim));
    assert_true(isnan(r.trace.e[9].ssim));
    double psnr = r.trace.e[59].psnr;
    /* Baseline: every frame = y ⊘ Φ_sum, the best one can do without a prior on motion. */
    sci_cube *phi, *base;
    assert_int_equal(sci_cube_new(&phi, 64, 48, 1, NULL), 0);
    assert_int_equal(sci_cube_new(&base, 64, 48, 8, NULL), 0);
    sci_op_phi_sum(p->mask, phi);
    for (int k = 0; k < 8; k++)
        for (int i = 0; i < 64 * 48; i++)
            sci_cube_frame(base, k)[i] = p->meas->data[i] / phi->data[i];
    double bpsnr = sci_psnr(base, p->truth, SCI_PEAK_FRAME_MAX, 0, NULL);
    printf("admm-tv blob: %.2f dB after 60 iterations (baseline y/phi %.2f dB), residual %.2e\n", psnr, bpsnr,
           r.trace.e[59].residual);
    assert_true(psnr > bpsnr + 15);
    sci_cube_free(phi);
    sci_cube_free(base);
    assert_true(r.trace.e[59].residual < 0.02);
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cancel),
        cmocka_unit_test(test_divergence_reported),
        cmocka_unit_test(test_bad_input_refused),
        cmocka_unit_test(test_thread_count_independent),
        cmocka_unit_test(test_trace_and_quality),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
