/* DeSCI on a colour (Bayer RGGB) snapshot, per CFA plane (recon/bayer.h), against GAP-TV per plane: RGB PSNR on
 * etc/scenes/cacti_color.json (256×256×8, four 128×128 planes). A cheap setting — GAP-TV warm start, then a few
 * iterations of WNNM at σ 12 with one block matching — must beat GAP-TV at its defaults (100 iterations) by a
 * margin (measured +0.49 dB; the demosaicing bounds both near 23 dB). About 17 s at -O3 on 2 loaded cores. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>
#include "recon/bayer.h"
#include "recon/desci.h"
#include "recon/gaptv.h"
#include "recon/metrics.h"
#include "sim/scene.h"
#include "sim/simulate.h"

#include "tests/helpers/sanitized.h"

static int tv_plane(const sci_problem *plane, sci_result *r, void *user)
{
    return sci_gaptv_solve(plane, user, r, NULL, NULL);
}

static int desci_plane(const sci_problem *plane, sci_result *r, void *user)
{
    return sci_desci_solve(plane, user, r, NULL, NULL, NULL);
}

static double seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static void test_colour_beats_gaptv(void **state)
{
    (void)state;
    sim_scene *sc = NULL;
    sci_problem **ps = NULL;
    int k = 0;
    sci_error err = {0};
    if (sim_scene_load_file(&sc, "etc/scenes/cacti_color.json", &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(sim_run(sc, &ps, &k, NULL, NULL, NULL, &err), 0);
    const sci_problem *p = ps[0];
    sci_cube *truth = NULL;
    assert_int_equal(sci_cube_new(&truth, p->mask->w, p->mask->h, 3 * p->mask->n, &err), 0);
    assert_int_equal(sim_render_truth_rgb(sc, 0, truth, &err), 0);

    /* GAP-TV per CFA plane at its defaults (100 iterations; AddressSanitizer: 5) */
    sci_gaptv_params g;
    sci_gaptv_params_default(&g);
    g.iters = SANITIZED ? 5 : 100;
    g.metrics_every = g.ssim_every = 0;
    sci_result planes[4] = {{0}};
    sci_cube *tv_rgb = NULL, *raw = NULL;
    double t0 = seconds();
    assert_int_equal(sci_bayer_solve(p, SCI_CFA_RGGB, SCI_DEMOSAIC_MHC, tv_plane, &g, &tv_rgb, &raw, planes, &err), 0);
    const double tv_s = seconds() - t0;
    const double tv = sci_psnr_rgb(tv_rgb, truth, SCI_PEAK_FRAME_MAX, 0, NULL);
    for (int i = 0; i < 4; i++)
        sci_result_free_contents(&planes[i]);
    sci_cube_free(raw);
    raw = NULL;

    /* DeSCI per plane: the same GAP-TV start, then 3 iterations at σ 12 (one block matching, window ±10, keys every 4 pixels, 40 patches a group) */
    sci_desci_params d;
    sci_desci_params_default(&d);
    d.iters = SANITIZED ? 1 : 3;
    d.sigma = (solver_values){1, {12}};
    d.tv_init = g.iters;
    d.window = SANITIZED ? 5 : 10;
    d.step = 4;   /* keys on a 4-pixel grid: a quarter of the default's groups */
    d.group = 40;
    d.metrics_every = d.ssim_every = 0;
    if (sci_desci_params_check(&d, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube *rgb = NULL;
    t0 = seconds();
    if (sci_bayer_solve(p, SCI_CFA_RGGB, SCI_DEMOSAIC_MHC, desci_plane, &d, &rgb, &raw, planes, &err) != 0)
        fail_msg("%s", err.msg);
    const double desci_s = seconds() - t0;
    const double desci = sci_psnr_rgb(rgb, truth, SCI_PEAK_FRAME_MAX, 0, NULL);
    printf("  colour scene, RGB PSNR (peak = frame max): desci %.2f dB (%.1f s), GAP-TV per plane %.2f dB (%.1f s)%s\n",
           desci, desci_s, tv, tv_s, SANITIZED ? " (AddressSanitizer build: 1 DeSCI iteration after 5 of GAP-TV)" : "");
    if (SANITIZED)
        assert_true(isfinite(desci) && desci > tv);
    else
        assert_true(desci > tv + 0.3); /* measured 23.42 against 22.93 dB (2 threads, -O3) */
    for (int i = 0; i < 4; i++)
        sci_result_free_contents(&planes[i]);
    sci_cube_free(raw);
    sci_cube_free(rgb);
    sci_cube_free(tv_rgb);
    sci_cube_free(truth);
    sci_problem_array_free(ps, k);
    sim_scene_free(sc);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_colour_beats_gaptv)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
