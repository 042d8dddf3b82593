/* RayFormer solver at tiny sizes: parameters are checked, the loss decreases, the reconstruction beats the
 * mean-frame baseline (every frame = y ⊘ Σ M) by a clear margin (1.5 dB; GAP-TV gains 4 dB here), the trace follows the contract, cancel works. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

/* Under AddressSanitizer (make check-asan: memory errors, not accuracy) the learning test trains 40 steps instead
 * of 150 and checks that the loss falls; the optimised build checks how far. */
#include "tests/helpers/sanitized.h"
#include <omp.h>

#include "recon/metrics.h"
#include "recon/nerf/rayformer_solve.h"
#include "recon/sci_ops.h"
#include "sim/simulate.h"
#include "tests/helpers/nerf_scene.h"

static void small_params(sci_rayformer_params *prm, unsigned long long seed)
{
    sci_rayformer_params_default(prm);
    prm->patch = 8;
    prm->patches_per_step = 2;
    prm->samples = 16;
    prm->log2_table = 12;
    prm->finest_res = 64;
    prm->metrics_every = 0;
    prm->seed = seed;
}

static void test_params_check(void **state)
{
    (void)state;
    sci_rayformer_params p;
    sci_error err = {0};
    sci_rayformer_params_default(&p);
    assert_int_equal(sci_rayformer_params_check(&p, &err), 0);
    p.patch = 6;
    assert_int_equal(sci_rayformer_params_check(&p, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "patch"));
    sci_rayformer_params_default(&p);
    p.lr = NAN;
    assert_int_equal(sci_rayformer_params_check(&p, &err), -EINVAL);
    /* Adam's ε: at 0 a parameter whose moments are still 0 steps by 0/0; NaN, ∞ and the range's outside refused */
    const double bad_eps[] = {0.0, -1e-8, NAN, INFINITY, 2.0};
    for (size_t i = 0; i < sizeof bad_eps / sizeof bad_eps[0]; i++) {
        sci_rayformer_params_default(&p);
        p.adam_eps = bad_eps[i];
        err.msg[0] = 0;
        assert_int_equal(sci_rayformer_params_check(&p, &err), -EINVAL);
        assert_non_null(strstr(err.msg, "adam-eps"));
    }
    p.adam_eps = 1e-8;
    assert_int_equal(sci_rayformer_params_check(&p, &err), 0);
}

static void test_needs_camera(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(32, 1);
    sci_camera *cam = p->camera;
    p->camera = NULL;
    sci_rayformer_params prm;
    small_params(&prm, 1);
    sci_result r = {0};
    assert_int_equal(sci_rayformer_solve(p, &prm, &r, NULL, NULL), -EINVAL);
    assert_non_null(strstr(r.error.msg, "camera"));
    assert_null(r.frames);
    sci_result_free_contents(&r);
    p->camera = cam;
    sci_problem_free(p);
}

static double mean_loss(const sci_trace *t, size_t from, size_t to)
{
    double s = 0;
    for (size_t i = from; i < to; i++)
        s += t->e[i].loss;
    return s / (double)(to - from);
}

/* Known poses: the loss of the last steps is well below that of the first, the reconstruction beats the mean
 * frame by more than 1.5 dB, and the trace has one row per step with PSNR at the end. */
static void test_learns_tiny_scene(void **state)
{
    (void)state;
    unsigned long long seed = test_seed_env(7);
    sci_problem *p = nerf_tiny_problem(32, seed);
    sci_rayformer_params prm;
    small_params(&prm, seed);
    prm.iters = SANITIZED ? 40 : 150;
    sci_result r = {0};
    int rc = sci_rayformer_solve(p, &prm, &r, NULL, NULL);
    if (rc != 0)
        fail_msg("%s", r.error.msg);
    assert_non_null(r.frames);
    assert_int_equal((int)r.trace.len, prm.iters);
    double first = mean_loss(&r.trace, 0, 10), last = mean_loss(&r.trace, r.trace.len - 10, r.trace.len);
    double base = nerf_mean_frame_psnr(p), psnr = r.trace.e[r.trace.len - 1].psnr_peak1;
    printf("loss %.4g -> %.4g; PSNR %.2f dB vs mean frame %.2f dB; %.1f s\n", first, last, psnr, base,
           r.trace.e[r.trace.len - 1].wall_s);
    if (SANITIZED) {
        printf("(AddressSanitizer build: 40 steps, the loss must fall)\n");
        assert_true(last < first);
    } else {
        assert_true(last < 0.5 * first);
        assert_true(psnr > base + 1.5);
    }
    /* the diagnostics of the final render: the residual over the whole snapshot agrees with the frames (recomputed
     * here), the largest ray weight is a weight; rows without a render carry NaN */
    const sci_trace_entry *e = &r.trace.e[r.trace.len - 1];
    double res = sci_op_residual(p->mask, r.frames, p->meas);
    printf("final render: measurement residual %.4g (recomputed %.4g), mean largest weight %.3f\n", e->meas_residual,
           res, e->max_weight);
    assert_true(fabs(e->meas_residual - res) <= 1e-9 * (1 + res));
    assert_true(e->meas_residual < 1);
    assert_true(e->max_weight > 0 && e->max_weight <= 1);
    assert_true(isnan(r.trace.e[0].meas_residual) && isnan(r.trace.e[0].max_weight));
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

static int cancel_at_3(const sci_trace_entry *e, void *user)
{
    (void)user;
    return e->iter >= 3;
}

static void test_cancel_keeps_frames(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(32, 2);
    sci_rayformer_params prm;
    small_params(&prm, 2);
    prm.iters = 50;
    sci_result r = {0};
    assert_int_equal(sci_rayformer_solve(p, &prm, &r, cancel_at_3, NULL), SCI_ECANCELED);
    assert_int_equal(r.iters_done, 3);
    assert_non_null(r.frames);
    assert_int_equal(sci_cube_check_finite(r.frames, "frames", NULL), 0);
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

/* `threads` bounds the whole run: the trainer's own loops and Adam follow the calling thread's OpenMP default, so
 * the run sets it (seen from the progress callback, which runs on that thread) and puts the caller's back. */
static int record_threads(const sci_trace_entry *e, void *user)
{
    (void)e;
    int *seen = user;
    *seen = *seen > omp_get_max_threads() ? *seen : omp_get_max_threads();
    return 0;
}

static void test_threads_bound_the_run(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(32, 2);
    sci_rayformer_params prm;
    small_params(&prm, 3);
    prm.iters = 4;
    prm.metrics_every = 1;
    prm.threads = 1;
    const int before = omp_get_max_threads();
    omp_set_num_threads(3);
    int seen = 0;
    sci_result r = {0};
    assert_int_equal(sci_rayformer_solve(p, &prm, &r, record_threads, &seen), 0);
    assert_int_equal(seen, 1);
    assert_int_equal(omp_get_max_threads(), 3);
    sci_result_free_contents(&r);
    prm.threads = 0; /* 0: the caller's */
    seen = 0;
    r = (sci_result){0};
    assert_int_equal(sci_rayformer_solve(p, &prm, &r, record_threads, &seen), 0);
    assert_int_equal(seen, 3);
    omp_set_num_threads(before); /* the later tests run as the suite was started */
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

/* The ablation ladder: each step switches on its own and trains: finite frames, and the frames after 30 steps are
 * more than 0.5 dB better than after the first (per-step losses over two random patches are too noisy to compare). */
static void test_ablation_ladder(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(32, 5);
    double base = nerf_mean_frame_psnr(p);
    for (int step = 0; step <= 4; step++) {
        sci_rayformer_params prm;
        small_params(&prm, 5);
        prm.patch = 4;
        prm.patches_per_step = 8; /* 128 rays: windows that cover the 32 × 32 frames within the 30 steps (with 2,
                                     the density head — no layer norm before it — moves only where windows fell) */
        prm.samples = 8;
        assert_int_equal(sci_rayformer_params_ablation(&prm, step, 0.01), 0);
        assert_int_equal(prm.patch_sampling, step >= 1);
        assert_int_equal(prm.inter_ray, step >= 2);
        assert_int_equal(prm.intra_ray, step >= 3);
        assert_true((prm.tv_weight > 0) == (step >= 4));
        double psnr[2];
        for (int k = 0; k < 2; k++) {
            prm.iters = k ? 30 : 1;
            sci_result r = {0};
            int rc = sci_rayformer_solve(p, &prm, &r, NULL, NULL);
            if (rc != 0)
                fail_msg("%s: %s", sci_rayformer_ablation_names[step], r.error.msg);
            assert_int_equal(sci_cube_check_finite(r.frames, "frames", NULL), 0);
            psnr[k] = r.trace.e[r.trace.len - 1].psnr_peak1;
            sci_result_free_contents(&r);
        }
        printf("%-9s PSNR after 1 step %.2f dB, after 30 %.2f dB (mean frame %.2f)\n",
               sci_rayformer_ablation_names[step], psnr[0], psnr[1], base);
        assert_true(psnr[1] > psnr[0] + 0.5);
    }
    sci_rayformer_params prm;
    sci_rayformer_params_default(&prm);
    assert_int_equal(sci_rayformer_params_ablation(&prm, 5, 0.01), -EINVAL);
    for (const char *const *n = (const char *const[]){"fast", "balanced", "best", NULL}; *n; n++) {
        assert_int_equal(sci_rayformer_params_preset(&prm, *n), 0);
        assert_int_equal(sci_rayformer_params_check(&prm, NULL), 0);
    }
    assert_int_equal(sci_rayformer_params_preset(&prm, "fastest"), -EINVAL);
    sci_problem_free(p);
}

/* Solves p with prm into r; fails the test on an error or non-finite frames. */
static void solve_finite(const sci_problem *p, const sci_rayformer_params *prm, sci_result *r)
{
    *r = (sci_result){0};
    if (sci_rayformer_solve(p, prm, r, NULL, NULL) != 0)
        fail_msg("%s", r->error.msg);
    assert_int_equal(sci_cube_check_finite(r->frames, "frames", NULL), 0);
}

/* The tiny runs' settings: small_params with 8 windows of 4×4, 8 samples, 20 steps. */
static void tiny_params(sci_rayformer_params *prm)
{
    small_params(prm, 3);
    prm->patch = 4;
    prm->patches_per_step = 8;
    prm->samples = 8;
    prm->iters = 20;
}

/* A 20-step run on the tiny scene with 4×4 windows, inter-ray attention on or off and one inference or training
 * option set (render_tilings, window_jitter); fails the test on an error or non-finite frames. */
static void tiny_run(const sci_problem *p, int inter, int render_tilings, int window_jitter, sci_result *r)
{
    sci_rayformer_params prm;
    tiny_params(&prm);
    prm.inter_ray = inter;
    prm.render_tilings = render_tilings;
    prm.window_jitter = window_jitter;
    solve_finite(p, &prm, r);
}

static int same_loss(const sci_result *a, const sci_result *b)
{
    int same = a->trace.len == b->trace.len;
    for (size_t i = 0; same && i < a->trace.len; i++)
        same = a->trace.e[i].loss == b->trace.e[i].loss;
    return same;
}

static int same_frames(const sci_result *a, const sci_result *b)
{
    size_t n = (size_t)a->frames->w * a->frames->h * a->frames->n;
    return memcmp(a->frames->data, b->frames->data, n * sizeof(float)) == 0;
}

/* Four tilings at inference: training is untouched (the same loss at every step), the render changes only where
 * inter-ray attention makes a pixel depend on its window (with it off the frames are bitwise those of one tiling),
 * the frames stay finite, and other counts are refused. */
static void test_render_tilings(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(32, 3);
    for (int inter = 0; inter <= 1; inter++) {
        sci_result r[2];
        tiny_run(p, inter, 1, 0, &r[0]);
        tiny_run(p, inter, 4, 0, &r[1]);
        assert_true(same_loss(&r[0], &r[1]));
        double p1 = r[0].trace.e[r[0].trace.len - 1].psnr_peak1, p4 = r[1].trace.e[r[1].trace.len - 1].psnr_peak1;
        printf("inter-ray %d: PSNR one tiling %.3f dB, four %.3f dB\n", inter, p1, p4);
        assert_int_equal(same_frames(&r[0], &r[1]), !inter);
        sci_result_free_contents(&r[0]);
        sci_result_free_contents(&r[1]);
    }
    sci_rayformer_params prm;
    small_params(&prm, 3);
    prm.render_tilings = 2;
    assert_int_equal(sci_rayformer_params_check(&prm, NULL), -EINVAL);
    sci_problem_free(p);
}

/* The window's shared depth jitter serves inter-ray attention only: with that path off the run is bitwise the one
 * without it (the option is ignored), with it on the training differs (other depths are drawn) and stays finite. */
static void test_window_jitter(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(32, 3);
    for (int inter = 0; inter <= 1; inter++) {
        sci_result r[2];
        tiny_run(p, inter, 1, 0, &r[0]);
        tiny_run(p, inter, 1, 1, &r[1]);
        if (inter) /* other depths from the first step on */
            assert_true(r[0].trace.e[0].loss != r[1].trace.e[0].loss);
        else
            assert_true(same_loss(&r[0], &r[1]) && same_frames(&r[0], &r[1]));
        sci_result_free_contents(&r[0]);
        sci_result_free_contents(&r[1]);
    }
    sci_problem_free(p);
}

/* Stratified window (or ray) positions change training from the first step, with windows and with scattered rays,
 * and the run stays finite. */
static void test_stratify(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(32, 3);
    for (int patches = 0; patches <= 1; patches++) {
        sci_result r[2];
        for (int k = 0; k < 2; k++) {
            sci_rayformer_params prm;
            small_params(&prm, 3);
            prm.iters = 20;
            prm.patch_sampling = patches;
            prm.stratify = k;
            solve_finite(p, &prm, &r[k]);
        }
        assert_true(r[0].trace.e[0].loss != r[1].trace.e[0].loss);
        sci_result_free_contents(&r[0]);
        sci_result_free_contents(&r[1]);
    }
    sci_problem_free(p);
}

/* Wider training windows, each window's stride drawn from 1 … 4 (patch_stride_max, coarse 0) or every window
 * narrowing from 3 to 1 over the run (patch_stride_start, coarse 1): other pixels than adjacent windows' from the
 * first step, a finite field, every pixel rendered by the one adjacent tiling; a value under the stride or over 8
 * is refused, as is one whose window outgrows the image, and the two settings together. */
static void wide_window_cases(const sci_problem *p, int coarse)
{
    sci_rayformer_params prm;
    int *wide = coarse ? &prm.patch_stride_start : &prm.patch_stride_max;
    sci_result rs[2];
    for (int k = 0; k < 2; k++) {
        tiny_params(&prm);
        *wide = k ? 4 - coarse : 0;
        solve_finite(p, &prm, &rs[k]);
    }
    assert_true(rs[0].trace.e[0].loss != rs[1].trace.e[0].loss);
    for (size_t i = 0; i < (size_t)rs[1].frames->w * rs[1].frames->h * rs[1].frames->n; i++)
        assert_true(rs[1].frames->data[i] != 0.0f);
    sci_result_free_contents(&rs[0]);
    sci_result_free_contents(&rs[1]);
    tiny_params(&prm);
    prm.patch_stride = 2, *wide = 1;
    assert_int_equal(sci_rayformer_params_check(&prm, NULL), -EINVAL);
    *wide = 9;
    assert_int_equal(sci_rayformer_params_check(&prm, NULL), -EINVAL);
    prm.patch_stride = 1, prm.patch_stride_start = 3, prm.patch_stride_max = 3;
    sci_error err = {0};
    assert_int_equal(sci_rayformer_params_check(&prm, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "exclude each other"));
    small_params(&prm, 3);
    prm.patch = 8;
    *wide = 5; /* a 36-pixel window on a 32-pixel image (at the first step, narrowing) */
    prm.iters = 2;
    sci_result rb = {0};
    assert_true(sci_rayformer_solve(p, &prm, &rb, NULL, NULL) < 0);
    assert_non_null(strstr(rb.error.msg, "window of stride 5"));
    sci_result_free_contents(&rb);
}

/* Strided windows: scattered rays ignore the stride (bitwise the run without it); windows of stride 3 train on
 * other pixels from the first step and their one tiling renders every pixel (the frames start at 0, a rendered pixel
 * has the field's colour); four tilings stay finite; a stride whose tiling block outgrows the image is refused with
 * a message naming it, as are strides outside 1 … 8; the same for wider training windows (wide_window_cases). */
static void test_patch_stride(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(32, 3);
    for (int patches = 0; patches <= 1; patches++) {
        sci_result r[2];
        for (int k = 0; k < 2; k++) {
            sci_rayformer_params prm;
            tiny_params(&prm);
            prm.patch_sampling = patches;
            prm.patch_stride = k ? 3 : 1;
            solve_finite(p, &prm, &r[k]);
        }
        if (patches)
            assert_true(r[0].trace.e[0].loss != r[1].trace.e[0].loss);
        else
            assert_true(same_loss(&r[0], &r[1]) && same_frames(&r[0], &r[1]));
        const size_t n = (size_t)r[1].frames->w * r[1].frames->h * r[1].frames->n;
        size_t zeros = 0;
        for (size_t i = 0; i < n; i++)
            zeros += r[1].frames->data[i] == 0.0f;
        assert_int_equal(zeros, 0);
        sci_result_free_contents(&r[0]);
        sci_result_free_contents(&r[1]);
    }
    sci_rayformer_params prm;
    tiny_params(&prm);
    prm.patch_stride = 3;
    prm.render_tilings = 4;
    sci_result r4;
    solve_finite(p, &prm, &r4);
    sci_result_free_contents(&r4);
    small_params(&prm, 3);
    prm.patch = 8;
    prm.patch_stride = 5; /* blocks of 40 pixels on a 32-pixel image */
    prm.iters = 2;
    sci_result r = {0};
    assert_true(sci_rayformer_solve(p, &prm, &r, NULL, NULL) < 0);
    assert_non_null(strstr(r.error.msg, "stride 5"));
    sci_result_free_contents(&r);
    prm.patch_stride = 9;
    assert_int_equal(sci_rayformer_params_check(&prm, NULL), -EINVAL);
    prm.patch_stride = 0;
    assert_int_equal(sci_rayformer_params_check(&prm, NULL), -EINVAL);
    wide_window_cases(p, 0);
    wide_window_cases(p, 1);
    sci_problem_free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_params_check),
        cmocka_unit_test(test_needs_camera),
        cmocka_unit_test(test_cancel_keeps_frames),
        cmocka_unit_test(test_threads_bound_the_run),
        cmocka_unit_test(test_learns_tiny_scene),
        cmocka_unit_test(test_ablation_ladder),
        cmocka_unit_test(test_render_tilings),
        cmocka_unit_test(test_window_jitter),
        cmocka_unit_test(test_stratify),
        cmocka_unit_test(test_patch_stride),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
