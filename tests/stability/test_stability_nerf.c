/* Hard cases for the NeRF-based reconstruction (rayformer) through its public solver: each must end with finite
 * frames, or with a clear error and no frames — never with garbage. Tiny scenes and few steps: seconds. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "recon/nerf/rayformer_solve.h"
#include "sim/simulate.h"

/* A static3d scene of w×h×n; the camera's end rotation (about y) and translation are the knobs. */
static sci_problem *scene(int w, int h, int n, double end_yaw, double end_x, double texture_lo, double texture_hi)
{
    char text[2048];
    snprintf(text, sizeof text,
             "{\"kind\": \"static3d\", \"width\": %d, \"height\": %d, \"frames\": %d, \"seed\": 5,"
             " \"objects\": [{\"type\": \"plane\", \"center\": [0, 0, -4], \"size\": [40, 40],"
             "   \"texture\": {\"type\": \"noise\", \"cell\": 4, \"values\": [%g, %g]}}],"
             " \"camera\": {\"fx\": %d, \"cx\": %g, \"cy\": %g, \"near\": 1, \"far\": 8,"
             "   \"start\": {\"position\": [0, 0, 0], \"rotation_rad\": [0, 0, 0]},"
             "   \"end\": {\"position\": [%g, 0, 0], \"rotation_rad\": [0, %.17g, 0]}}}",
             w, h, n, texture_lo, texture_hi, w > 1 ? w : 1, w / 2.0, h / 2.0, end_x, end_yaw);
    sim_scene *sc = NULL;
    sci_error err = {0};
    if (sim_scene_load_string(&sc, "hard.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_problem **p;
    int k;
    if (sim_run(sc, &p, &k, NULL, NULL, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_problem *one = p[0];
    for (int i = 1; i < k; i++)
        sci_problem_free(p[i]);
    free(p);
    sim_scene_free(sc);
    return one;
}

static void small(sci_rayformer_params *q)
{
    sci_rayformer_params_default(q);
    q->iters = 6;
    q->patch = 4;
    q->patches_per_step = 2;
    q->samples = 8;
    q->log2_table = 12;
    q->metrics_every = 0;
    q->ssim_every = 0;
    q->seed = 3;
}

static void expect_finite_or_clear_error(const sci_problem *p, const sci_rayformer_params *q, const char *what)
{
    sci_result r = {0};
    int rc = sci_rayformer_solve(p, q, &r, NULL, NULL);
    if (rc == 0) {
        assert_non_null(r.frames);
        for (size_t i = 0; i < sci_cube_count(r.frames); i++)
            if (!isfinite(r.frames->data[i]))
                fail_msg("%s: non-finite output at %zu", what, i);
        printf("%s: ok, final loss %g\n", what, r.trace.e[r.trace.len - 1].loss);
    } else {
        printf("%s: refused: %s\n", what, r.error.msg);
        assert_true(rc == SCI_EDIVERGED || rc == -EINVAL || rc == SCI_ESHAPE);
        assert_true(r.error.msg[0] != 0);
        if (rc == SCI_EDIVERGED)
            assert_null(r.frames);
    }
    sci_result_free_contents(&r);
}

/* Sizes that are not a multiple of the patch, the patch's own size (one place for a window: the stratified grid
 * is a single cell that every window of a step shares) and smaller than it: windows must be clipped or shifted
 * inside the image, never read past it, with uniform or stratified window positions, windows narrowing from stride
 * 3 (refused where the widest does not fit), and stratified scattered rays on an image with fewer pixels than rays
 * a step. */
static void test_sizes_not_multiple_of_patch(void **state)
{
    const int sz[][2] = {{13, 11}, {4, 4}, {5, 3}, {1, 1}};
    for (int i = 0; i < 4; i++) {
        sci_problem *p = scene(sz[i][0], sz[i][1], 3, 0.02, 0.05, 0.2, 0.8);
        for (int stratify = 0; stratify <= 1; stratify++) {
            sci_rayformer_params q;
            small(&q);
            q.stratify = stratify;
            char what[64];
            snprintf(what, sizeof what, "%dx%d, patch 4%s", sz[i][0], sz[i][1], stratify ? ", stratified" : "");
            expect_finite_or_clear_error(p, &q, what);
            /* windows narrowing from stride 3 (10 pixels a side at the start): they fit 13x11 only */
            q.patch_stride_start = 3;
            snprintf(what, sizeof what, "%dx%d, patch 4, strides 3 to 1%s", sz[i][0], sz[i][1],
                     stratify ? ", stratified" : "");
            expect_finite_or_clear_error(p, &q, what);
            q.patch_stride_start = 0;
            q.patch_sampling = 0;
            snprintf(what, sizeof what, "%dx%d, 32 rays%s", sz[i][0], sz[i][1], stratify ? ", stratified" : "");
            expect_finite_or_clear_error(p, &q, what);
        }
        sci_problem_free(p);
    }
}

/* NaN or Inf anywhere in the input is refused before training. */
static void test_nonfinite_refused(void **state)
{
    sci_problem *p = scene(16, 16, 3, 0.02, 0.05, 0.2, 0.8);
    sci_rayformer_params q;
    small(&q);
    p->meas->data[7] = NAN;
    sci_result r = {0};
    assert_int_equal(sci_rayformer_solve(p, &q, &r, NULL, NULL), SCI_ENONFINITE);
    assert_null(r.frames);
    p->meas->data[7] = 0;
    p->camera->pose[1][3] = INFINITY;
    r = (sci_result){0};
    assert_int_equal(sci_rayformer_solve(p, &q, &r, NULL, NULL), SCI_ENONFINITE);
    sci_problem_free(p);
}

/* Identical start and end poses (the camera does not move: log(T₁⁻¹T_N) = 0, where careless SE(3) code divides
 * 0 by 0), and a rotation of π − 1e-6 between them (where acos-based logs lose the axis), with the poses optimised
 * from there. */
static void test_degenerate_pose_paths(void **state)
{
    const double yaws[] = {0.0, M_PI - 1e-6};
    for (int i = 0; i < 2; i++) {
        sci_problem *p = scene(16, 16, 3, yaws[i], 0.0, 0.2, 0.8);
        sci_rayformer_params q;
        small(&q);
        q.pose_mode = NERF_POSES_LINEAR;
        char what[64];
        snprintf(what, sizeof what, "start/end yaw %.9g, poses optimised", yaws[i]);
        expect_finite_or_clear_error(p, &q, what);
        sci_problem_free(p);
    }
}

/* Extreme densities: an all-black scene drives densities towards zero everywhere (transmittance 1, nothing to
 * render), an all-white one towards opaque at the first sample. */
static void test_extreme_densities(void **state)
{
    sci_problem *black = scene(16, 16, 3, 0.02, 0.05, 0.0, 0.0);
    sci_problem *white = scene(16, 16, 3, 0.02, 0.05, 1.0, 1.0);
    sci_rayformer_params q;
    small(&q);
    q.iters = 20;
    q.lr = 5e-2;
    expect_finite_or_clear_error(black, &q, "all-black scene");
    expect_finite_or_clear_error(white, &q, "all-white scene");
    sci_problem_free(black);
    sci_problem_free(white);
}

/* A learning rate almost a thousand times too large: the solver must either stay finite or stop with "diverged" and no frames. */
static void test_huge_learning_rate(void **state)
{
    sci_problem *p = scene(16, 16, 3, 0.02, 0.05, 0.2, 0.8);
    sci_rayformer_params q;
    small(&q);
    q.iters = 30;
    q.lr = 9; /* the largest the parameter check allows; the paper's scale is 1e-2 */
    q.lr_final = 9;
    expect_finite_or_clear_error(p, &q, "learning rate 9");
    sci_problem_free(p);
}

/* The recipe with every knob on (disparity and log spacing, distortion loss, depth TV, GAP-TV warm start,
 * coarse-to-fine levels, zero-initialised gates, a window's rays sharing their depth jitter, the inter-ray gate on
 * two spacings of three and off on the third, a moving average of the weights over the whole run) on the hard
 * scenes: all-black (weights → 0, the distortion and depth terms see empty rays), all-white (opaque at the first
 * sample), and a learning rate of 9. */
static void test_recipe_hard_cases(void **state)
{
    sci_problem *black = scene(16, 16, 3, 0.02, 0.05, 0.0, 0.0);
    sci_problem *white = scene(16, 16, 3, 0.02, 0.05, 1.0, 1.0);
    sci_problem *tex = scene(16, 16, 3, 0.02, 0.05, 0.2, 0.8);
    for (int sp = NERF_SPACING_LINEAR; sp <= NERF_SPACING_LOG; sp++) {
        sci_rayformer_params q;
        small(&q);
        q.iters = 20;
        q.zero_gates = 1;
        q.heads_full_lr = 1;
        q.window_jitter = 1;
        q.inter_gate = sp != NERF_SPACING_DISPARITY; /* the gated inter-ray path (the default), and the bare one */
        q.recipe = (nerf_recipe){.spacing = (nerf_spacing)sp, .distortion_weight = 0.5, .depth_tv_weight = 5,
                                 .prior_steps = 10, .prior_weight = 10, .density_bias = -3, .c2f_steps = 15,
                                 .ema_steps = 5};
        char what[64];
        snprintf(what, sizeof what, "recipe, spacing %d, all-black", sp);
        expect_finite_or_clear_error(black, &q, what);
        snprintf(what, sizeof what, "recipe, spacing %d, all-white", sp);
        expect_finite_or_clear_error(white, &q, what);
        q.lr = q.lr_final = 9;
        q.recipe.density_bias = 8; /* e^8 ≈ 3000: opaque everywhere at the start */
        snprintf(what, sizeof what, "recipe, spacing %d, lr 9, density bias 8", sp);
        expect_finite_or_clear_error(tex, &q, what);
        /* Adam's ε at its ends: 1 turns a step into momentum SGD at lr (gradients are far below ε), 1e-30 makes a
         * grazing touch of a hash entry a full lr-sized step */
        q.adam_eps = sp == NERF_SPACING_LOG ? 1.0 : 1e-30;
        snprintf(what, sizeof what, "recipe, spacing %d, lr 9, adam_eps %g", sp, q.adam_eps);
        expect_finite_or_clear_error(tex, &q, what);
    }
    sci_problem_free(black);
    sci_problem_free(white);
    sci_problem_free(tex);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sizes_not_multiple_of_patch), cmocka_unit_test(test_nonfinite_refused),
        cmocka_unit_test(test_degenerate_pose_paths), cmocka_unit_test(test_extreme_densities),
        cmocka_unit_test(test_huge_learning_rate), cmocka_unit_test(test_recipe_hard_cases),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
