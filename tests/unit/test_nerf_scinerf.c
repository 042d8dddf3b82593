/* SCINeRF-style solver (scinerf_solve.h) at tiny sizes: parameters are checked, the loss decreases and the
 * reconstruction beats the mean-frame baseline by a clear margin, the coarse + fine variant runs and learns, the
 * frequency-encoded SCINeRF network runs. */
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

#include "recon/metrics.h"
#include "recon/nerf/scinerf_solve.h"
#include "recon/sci_ops.h"
#include "sim/simulate.h"

static unsigned long long test_seed(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    unsigned long long seed = s ? strtoull(s, NULL, 0) : 7;
    printf("seed %llu (set SCICAP_TEST_SEED to change)\n", seed);
    return seed;
}

static sci_problem *tiny_problem(unsigned long long seed)
{
    char text[2048];
    snprintf(text, sizeof text,
             "{\"kind\": \"static3d\", \"width\": 32, \"height\": 32, \"frames\": 4, \"seed\": %llu,"
             " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, -3], \"radius\": 0.8,"
             "   \"texture\": {\"type\": \"checkerboard\", \"cell\": 16}},"
             "  {\"type\": \"plane\", \"center\": [0, 0, -5], \"size\": [8, 8], \"texture\": {\"type\": \"noise\", \"cell\": 32}}],"
             " \"camera\": {\"fx\": 32, \"cx\": 16, \"cy\": 16, \"near\": 1.5, \"far\": 6,"
             "   \"start\": {\"position\": [-0.15, 0, 0], \"look_at\": [0, 0, -3]},"
             "   \"end\": {\"position\": [0.15, 0.05, 0], \"look_at\": [0, 0, -3]}}}",
             seed);
    sim_scene *sc = NULL;
    sci_error err = {0};
    if (sim_scene_load_string(&sc, "tiny.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_problem **p;
    int k;
    if (sim_run(sc, &p, &k, NULL, NULL, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_problem *one = p[0];
    free(p);
    sim_scene_free(sc);
    return one;
}

static double mean_frame_psnr(const sci_problem *p)
{
    sci_cube *x, *phi;
    assert_int_equal(sci_cube_new(&x, p->mask->w, p->mask->h, p->mask->n, NULL), 0);
    assert_int_equal(sci_cube_new(&phi, p->mask->w, p->mask->h, 1, NULL), 0);
    sci_op_phi_sum(p->mask, phi);
    size_t fs = sci_cube_frame_size(x);
    for (int i = 0; i < x->n; i++)
        for (size_t k = 0; k < fs; k++)
            x->data[i * fs + k] = phi->data[k] > 0 ? p->meas->data[k] / phi->data[k] : 0;
    double psnr = sci_psnr(x, p->truth, SCI_PEAK_FIXED, p->peak, NULL);
    sci_cube_free(x);
    sci_cube_free(phi);
    return psnr;
}

static void small_params(sci_scinerf_params *prm, unsigned long long seed)
{
    sci_scinerf_params_default(prm);
    prm->rays_per_step = 128;
    prm->samples = 16;
    prm->log2_table = 12;
    prm->finest_res = 64;
    prm->metrics_every = 0;
    prm->seed = seed;
}

static double mean_loss(const sci_trace *t, size_t from, size_t to)
{
    double s = 0;
    for (size_t i = from; i < to; i++)
        s += t->e[i].loss;
    return s / (double)(to - from);
}

static void test_params_check(void **state)
{
    (void)state;
    sci_scinerf_params p;
    sci_error err = {0};
    sci_scinerf_params_default(&p);
    assert_int_equal(sci_scinerf_params_check(&p, &err), 0);
    p.rays_per_step = 100;
    assert_int_equal(sci_scinerf_params_check(&p, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "rays-per-step"));
    sci_scinerf_params_default(&p);
    p.depth = 0;
    assert_int_equal(sci_scinerf_params_check(&p, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "depth"));
    sci_scinerf_params_default(&p);
    assert_int_equal(sci_scinerf_params_preset(&p, "best"), 0);
    assert_int_equal(p.fine_samples, 32);
    assert_int_equal(sci_scinerf_params_check(&p, &err), 0);
    sci_scinerf_params_paper(&p);
    assert_int_equal(p.pos_enc, NERF_MLP_POS_FREQ);
    assert_int_equal(sci_scinerf_params_check(&p, &err), 0);
    assert_int_equal(sci_scinerf_params_preset(&p, "quick"), -EINVAL);
}

/* Hash-encoded field, random rays, known poses: the loss of the last steps is well below that of the first and the
 * frames beat the mean frame by more than 3 dB (measured 21.8 vs 16.9 dB at seed 7). */
static void test_learns_tiny_scene(void **state)
{
    (void)state;
    unsigned long long seed = test_seed();
    sci_problem *p = tiny_problem(seed);
    sci_scinerf_params prm;
    small_params(&prm, seed);
    prm.iters = 150;
    sci_result r = {0};
    int rc = sci_scinerf_solve(p, &prm, &r, NULL, NULL);
    if (rc != 0)
        fail_msg("%s", r.error.msg);
    assert_int_equal((int)r.trace.len, prm.iters);
    double first = mean_loss(&r.trace, 0, 10), last = mean_loss(&r.trace, r.trace.len - 10, r.trace.len);
    double base = mean_frame_psnr(p), psnr = r.trace.e[r.trace.len - 1].psnr_peak1;
    printf("loss %.4g -> %.4g; PSNR %.2f dB vs mean frame %.2f dB; %.1f s\n", first, last, psnr, base,
           r.trace.e[r.trace.len - 1].wall_s);
    assert_true(last < 0.2 * first);
    assert_true(psnr > base + 3);
    assert_string_equal(r.method, "scinerf");
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

/* Coarse + fine networks with importance sampling: learns as well (> 3 dB over the mean frame). */
static void test_coarse_fine(void **state)
{
    (void)state;
    unsigned long long seed = test_seed();
    sci_problem *p = tiny_problem(seed);
    sci_scinerf_params prm;
    small_params(&prm, seed);
    prm.iters = 100;
    prm.samples = 8;
    prm.fine_samples = 8;
    sci_result r = {0};
    int rc = sci_scinerf_solve(p, &prm, &r, NULL, NULL);
    if (rc != 0)
        fail_msg("%s", r.error.msg);
    double base = mean_frame_psnr(p), psnr = r.trace.e[r.trace.len - 1].psnr_peak1;
    printf("coarse 8 + fine 8 samples: PSNR %.2f dB vs mean frame %.2f dB\n", psnr, base);
    assert_true(psnr > base + 3);
    assert_int_equal(sci_cube_check_finite(r.frames, "frames", NULL), 0);
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

/* SCINeRF's own network (frequency encoding, ReLU density), narrowed so that it runs in a test: finite frames. */
static void test_frequency_network(void **state)
{
    (void)state;
    sci_problem *p = tiny_problem(3);
    sci_scinerf_params prm;
    small_params(&prm, 3);
    sci_scinerf_params_paper(&prm);
    prm.iters = 5, prm.rays_per_step = 64, prm.samples = 8, prm.fine_samples = 8, prm.depth = 3, prm.width = 32;
    prm.skip = 2, prm.feature_dim = 16, prm.color_hidden = 16, prm.metrics_every = 0;
    sci_result r = {0};
    int rc = sci_scinerf_solve(p, &prm, &r, NULL, NULL);
    if (rc != 0)
        fail_msg("%s", r.error.msg);
    assert_int_equal(sci_cube_check_finite(r.frames, "frames", NULL), 0);
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

static void test_needs_camera(void **state)
{
    (void)state;
    sci_problem *p = tiny_problem(1);
    sci_camera *cam = p->camera;
    p->camera = NULL;
    sci_scinerf_params prm;
    small_params(&prm, 1);
    sci_result r = {0};
    assert_int_equal(sci_scinerf_solve(p, &prm, &r, NULL, NULL), -EINVAL);
    assert_non_null(strstr(r.error.msg, "camera"));
    assert_null(r.frames);
    sci_result_free_contents(&r);
    p->camera = cam;
    sci_problem_free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_params_check),     cmocka_unit_test(test_needs_camera),
        cmocka_unit_test(test_frequency_network), cmocka_unit_test(test_coarse_fine),
        cmocka_unit_test(test_learns_tiny_scene),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
