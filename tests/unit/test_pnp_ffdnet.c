/* recon/pnp_ffdnet: PnP-FFDNet through the solver table. drop40 snapshot 1 passes the PyTorch reference's 39.57 dB
 * (≥ 39.5, peak = frame max); ADMM runs; the colour route beats GAP-TV per plane on the colour scene; missing or
 * wrong weights and bad settings are refused with messages. Under AddressSanitizer (≈ 10× slower) the quality cases
 * run on fewer iterations (one σ stage) and assert less: drop40 above GAP-TV at the same iterations, the colour
 * route finite and above 10 dB; each says so when it runs. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "io/matfile.h"
#include "recon/bayer.h"
#include "recon/gaptv.h"
#include "recon/metrics.h"
#include "recon/pnp_ffdnet.h"
#include "recon/solver.h"
#include "sim/scene.h"
#include "sim/simulate.h"
#include "tests/helpers/testdata.h"

#include "tests/helpers/sanitized.h"

static sci_problem **load_drop(int *k)
{
    char path[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", path);
    sci_problem **p = NULL;
    sci_error err = {0};
    if (sci_mat_read(path, 255, &p, k, &err) < 0)
        fail_msg("%s", err.msg);
    return p;
}

static void weights_or_skip(void)
{
    char path[4096];
    TESTDATA_REQUIRE("ffdnet/net_gray.pth", path);
    TESTDATA_REQUIRE("ffdnet/net_rgb.pth", path);
}

static double run(const sci_problem *p, const char *json, double *residual)
{
    const solver_ops *m = solver_find("pnp-ffdnet");
    assert_non_null(m);
    void *s = solver_settings_new(m);
    sci_error err = {0};
    json_t *j = json_loads(json, 0, NULL);
    assert_int_equal(solver_settings_from_json(m, s, j, NULL, "params", &err), 0);
    json_decref(j);
    sci_result r = {0};
    int rc = solver_run(m, p, s, NULL, &r);
    if (rc != 0)
        fail_msg("pnp-ffdnet: %s", r.error.msg);
    const sci_trace_entry *last = &r.trace.e[r.trace.len - 1];
    const double psnr = last->psnr;
    if (residual)
        *residual = last->residual;
    printf("  %s %s: %d iterations, PSNR %.2f dB (peak = frame max), residual %.4f, %.1f s\n", p->name, json,
           r.iters_done, psnr, last->residual, last->wall_s);
    sci_result_free_contents(&r);
    solver_settings_free(s);
    return psnr;
}

static void test_drop40_reaches_reference(void **state)
{
    (void)state;
    weights_or_skip();
    int k = 0;
    sci_problem **p = load_drop(&k);
    if (!SANITIZED) {
        /* PnP-SCI's recipe (σ 50, 25, 12, 6 × 10, accelerated GAP) gives 39.57 dB with PyTorch-CPU; the same
         * recipe here must land within 0.1 dB of it (measured 39.57). The balanced preset (40.27 dB) costs 4.5×
         * more and is measured by the bench, not here. */
        const double ref = run(p[0], "{\"iters\":40,\"sigma\":[50,25,12,6]}", NULL);
        assert_true(fabs(ref - 39.57) < 0.1);
        /* ADMM dips at each σ change before it recovers: measured 39.96 dB at 40 iterations */
        assert_true(run(p[0], "{\"projection\":\"admm\",\"iters\":40}", NULL) > 39.0);
    } else {
        printf("  (AddressSanitizer build: 4 iterations, checked against GAP-TV at 4 iterations)\n");
        sci_gaptv_params g;
        sci_gaptv_params_default(&g);
        g.iters = 4;
        sci_result r = {0};
        assert_int_equal(sci_gaptv_solve(p[0], &g, &r, NULL, NULL), 0);
        const double tv = r.trace.e[r.trace.len - 1].psnr;
        sci_result_free_contents(&r);
        /* one σ stage of 4 iterations: 7.8 dB at -O3, GAP-TV's 4 iterations ≈ 6 dB */
        assert_true(run(p[0], "{\"iters\":4,\"sigma\":[50]}", NULL) > tv);
    }
    sci_problem_array_free(p, k);
}

static int tv_plane(const sci_problem *plane, sci_result *r, void *user)
{
    return sci_gaptv_solve(plane, user, r, NULL, NULL);
}

/* The colour route (demosaic, colour FFDNet, mosaic) against GAP-TV per CFA plane, RGB PSNR on the colour scene. */
static void test_colour_beats_gaptv(void **state)
{
    (void)state;
    weights_or_skip();
    sim_scene *sc = NULL;
    sci_problem **ps = NULL;
    int k = 0;
    sci_error err = {0};
    assert_int_equal(sim_scene_load_file(&sc, "etc/scenes/cacti_color.json", &err), 0);
    assert_int_equal(sim_run(sc, &ps, &k, NULL, NULL, NULL, &err), 0);
    const sci_problem *p = ps[0];
    sci_cube *truth = NULL, *rgb = NULL, *tv_rgb = NULL;
    assert_int_equal(sci_cube_new(&truth, p->mask->w, p->mask->h, 3 * p->mask->n, &err), 0);
    assert_int_equal(sim_render_truth_rgb(sc, 0, truth, &err), 0);

    sci_pnp_params q;
    sci_pnp_params_default(&q);
    q.iters = SANITIZED ? 2 : 40;
    if (SANITIZED)
        q.sigma = q.sigma_rgb = (solver_values){1, {50}};
    q.tv_init = SANITIZED ? 5 : -1;
    q.metrics_every = q.ssim_every = 0;
    sci_result r = {0};
    if (sci_pnp_solve_bayer(p, &q, SCI_CFA_RGGB, SCI_DEMOSAIC_MHC, &rgb, &r, NULL, NULL) != 0)
        fail_msg("%s", r.error.msg);
    assert_non_null(rgb);
    const double pnp = sci_psnr_rgb(rgb, truth, SCI_PEAK_FRAME_MAX, 0, NULL);

    /* GAP-TV per CFA plane at its defaults (100 iterations), demosaiced the same way */
    sci_gaptv_params g;
    sci_gaptv_params_default(&g);
    g.iters = SANITIZED ? 5 : 100;
    g.metrics_every = g.ssim_every = 0;
    sci_result planes[4] = {{0}};
    sci_cube *raw = NULL;
    assert_int_equal(sci_bayer_solve(p, SCI_CFA_RGGB, SCI_DEMOSAIC_MHC, tv_plane, &g, &tv_rgb, &raw, planes, &err), 0);
    const double tv = sci_psnr_rgb(tv_rgb, truth, SCI_PEAK_FRAME_MAX, 0, NULL);
    printf("  colour scene, RGB PSNR (peak = frame max): pnp-ffdnet %.2f dB, GAP-TV per plane %.2f dB%s\n", pnp, tv,
           SANITIZED ? " (AddressSanitizer build: 2 iterations against 5)" : "");
    if (SANITIZED)
        assert_true(isfinite(pnp) && pnp > 10);
    else
        assert_true(pnp > tv + 1.0);
    for (int i = 0; i < 4; i++)
        sci_result_free_contents(&planes[i]);
    sci_cube_free(raw);
    sci_cube_free(tv_rgb);
    sci_result_free_contents(&r);
    sci_cube_free(rgb);
    sci_cube_free(truth);
    sci_problem_array_free(ps, k);
    sim_scene_free(sc);
}

static void test_bad_weights_and_settings(void **state)
{
    (void)state;
    weights_or_skip();
    int k = 0;
    sci_problem **p = load_drop(&k);
    const solver_ops *m = solver_find("pnp-ffdnet");
    void *s = solver_settings_new(m);
    sci_error err = {0};
    json_t *j = json_pack("{s:s,s:i}", "weights", "/nonexistent/net_gray.pth", "iters", 4);
    assert_int_equal(solver_settings_from_json(m, s, j, NULL, "params", &err), 0);
    json_decref(j);
    sci_result r = {0};
    assert_true(solver_run(m, p[0], s, NULL, &r) < 0);
    printf("  %s\n", r.error.msg);
    assert_non_null(strstr(r.error.msg, "pnp-ffdnet: weights: /nonexistent/net_gray.pth"));
    sci_result_free_contents(&r);

    /* the colour network on a grey problem */
    char rgbw[4096];
    TESTDATA_REQUIRE("ffdnet/net_rgb.pth", rgbw);
    j = json_pack("{s:s}", "weights", rgbw);
    assert_int_equal(solver_settings_from_json(m, s, j, NULL, "params", &err), 0);
    json_decref(j);
    r = (sci_result){0};
    assert_true(solver_run(m, p[0], s, NULL, &r) < 0);
    printf("  %s\n", r.error.msg);
    assert_non_null(strstr(r.error.msg, "colour FFDNet"));
    sci_result_free_contents(&r);

    /* fewer iterations than σ stages: refused when the run starts */
    j = json_pack("{s:s,s:i,s:[iii]}", "weights", "", "iters", 2, "sigma", 50, 25, 12);
    assert_int_equal(solver_settings_from_json(m, s, j, NULL, "params", &err), 0);
    json_decref(j);
    r = (sci_result){0};
    assert_true(solver_run(m, p[0], s, NULL, &r) < 0);
    printf("  %s\n", r.error.msg);
    assert_non_null(strstr(r.error.msg, "at least one per sigma stage"));
    sci_result_free_contents(&r);

    /* σ lists: a string or an array, values in (0, 255], no more stages than iterations */
    const char *bad[] = {"{\"sigma\":[]}", "{\"sigma\":[50,300]}", "{\"sigma\":\"50,x\"}", "{\"sigma\":[1,2,3,4,5,6,7,8,9]}",
                         "{\"iters\":0}", "{\"weights\":5}", "{\"projection\":\"pgd\"}"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        j = json_loads(bad[i], 0, NULL);
        err = (sci_error){0};
        assert_true(solver_settings_from_json(m, s, j, NULL, "params", &err) < 0);
        printf("  %s -> %s\n", bad[i], err.msg);
        json_decref(j);
    }
    j = json_loads("{\"sigma\":\"40, 20,10\",\"iters\":6}", 0, NULL);
    assert_int_equal(solver_settings_from_json(m, s, j, NULL, "params", &err), 0);
    json_decref(j);
    const sci_pnp_params *q = s;
    assert_int_equal(q->sigma.n, 3);
    assert_true(q->sigma.v[1] == 20);
    json_t *out = solver_settings_to_json(m, s);
    assert_int_equal(json_array_size(json_object_get(out, "sigma")), 3);
    json_decref(out);
    solver_settings_free(s);
    sci_problem_array_free(p, k);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_drop40_reaches_reference),
        cmocka_unit_test(test_colour_beats_gaptv),
        cmocka_unit_test(test_bad_weights_and_settings),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
