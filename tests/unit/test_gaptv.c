/* GAP-TV and ADMM-TV against the MATLAB reference on the drop40 benchmark (docs/conventions.md §6), the
 * orientation identity that catches a transposed mask, and the presets as points of the measured curve: fast within
 * 1 dB of best, balanced within 0.3 dB (no preset is a trap for live preview). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <cmocka.h>

#include "io/matfile.h"
#include "recon/admmtv.h"
#include "recon/gaptv.h"
#include "recon/metrics.h"
#include "recon/sci_ops.h"
#include "recon/solver.h"
#include "tests/helpers/testdata.h"

static sci_problem **load_drop_scaled(int *k, double scale)
{
    char path[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", path);
    sci_problem **p = NULL;
    sci_error err = {0};
    int rc = sci_mat_read(path, scale, &p, k, &err);
    if (rc < 0)
        fail_msg("%s", err.msg);
    return p;
}

static sci_problem **load_drop(int *k) { return load_drop_scaled(k, 255); }

/* Σ mask ⊙ orig equals meas exactly for every snapshot. Read on the integer scale (scale 1) the sums are exact
 * in float; a transposed mask (the classic column-major slip) must break the identity by a wide margin. */
static void test_orientation(void **state)
{
    int k;
    sci_problem **p = load_drop_scaled(&k, 1);
    assert_int_equal(k, 5);
    for (int j = 0; j < k; j++) {
        assert_non_null(p[j]->truth);
        assert_int_equal(p[j]->mask->w, 256);
        assert_int_equal(p[j]->mask->n, 8);
        sci_cube *y;
        assert_int_equal(sci_cube_new(&y, 256, 256, 1, NULL), 0);
        sci_op_forward(p[j]->mask, p[j]->truth, y);
        double maxdiff = 0;
        for (size_t i = 0; i < sci_cube_count(y); i++)
            maxdiff = fmax(maxdiff, fabs((double)y->data[i] - (double)p[j]->meas->data[i]));
        printf("snapshot %d: max |A(orig) - meas| = %g counts\n", j + 1, maxdiff);
        assert_true(maxdiff == 0);
        if (j == 0) {
            /* The same identity with every mask frame transposed. */
            sci_cube *mt;
            assert_int_equal(sci_cube_clone(&mt, p[0]->mask, NULL), 0);
            for (int f = 0; f < mt->n; f++)
                for (int r = 0; r < 256; r++)
                    for (int c = 0; c < 256; c++)
                        sci_cube_frame(mt, f)[r * 256 + c] = sci_cube_frame(p[0]->mask, f)[c * 256 + r];
            double res = sci_op_residual(mt, p[0]->truth, p[0]->meas);
            printf("transposed masks: relative residual %.3f\n", res);
            assert_true(res > 0.1);
            sci_cube_free(mt);
        }
        sci_cube_free(y);
    }
    sci_problem_array_free(p, k);
}

static void test_gaptv_golden(void **state)
{
    int k;
    sci_problem **p = load_drop(&k);
    sci_gaptv_params par;
    sci_gaptv_params_default(&par);
    par.ssim_every = 0;
    sci_result r = {0};
    int rc = sci_gaptv_solve(p[0], &par, &r, NULL, NULL);
    assert_int_equal(rc, 0);
    double psnr = sci_psnr(r.frames, p[0]->truth, SCI_PEAK_FRAME_MAX, 0, NULL);
    double psnr1 = sci_psnr(r.frames, p[0]->truth, SCI_PEAK_FIXED, 1.0, NULL);
    double ssim = sci_ssim(r.frames, p[0]->truth, 1.0, NULL);
    printf("gap-tv drop40#1: PSNR %.3f dB (peak = frame max), %.3f dB (peak = 1), SSIM %.4f, %zu trace rows\n",
           psnr, psnr1, ssim, r.trace.len);
    assert_true(fabs(psnr - 34.63) <= 0.05);
    assert_true(fabs(psnr1 - 34.74) <= 0.05);
    assert_true(fabs(ssim - 0.969) <= 0.002);
    assert_int_equal(r.trace.len, 100);
    assert_true(fabs(r.trace.e[99].psnr - psnr) < 1e-9);
    sci_result_free_contents(&r);

    sci_admmtv_params ap;
    sci_admmtv_params_default(&ap);
    ap.ssim_every = 0;
    sci_result ra = {0};
    assert_int_equal(sci_admmtv_solve(p[0], &ap, &ra, NULL, NULL), 0);
    double apsnr = sci_psnr(ra.frames, p[0]->truth, SCI_PEAK_FRAME_MAX, 0, NULL);
    printf("admm-tv drop40#1: PSNR %.3f dB (peak = frame max)\n", apsnr);
    assert_true(fabs(apsnr - psnr) <= 0.1);
    sci_result_free_contents(&ra);
    sci_problem_array_free(p, k);
}

static double preset_psnr(const sci_problem *p, const solver_ops *op, solver_preset pr)
{
    void *s = solver_settings_new(op);
    assert_non_null(s);
    solver_settings_preset(op, s, pr);
    sci_result r = {0};
    const solver_io io = {0};
    assert_int_equal(solver_run(op, p, s, &io, &r), 0);
    double v = sci_psnr(r.frames, p->truth, SCI_PEAK_FRAME_MAX, 0, NULL);
    sci_result_free_contents(&r);
    solver_settings_free(s);
    return v;
}

static void test_presets_on_the_curve(void **state)
{
    int k;
    sci_problem **p = load_drop(&k);
    const solver_ops *ops[2] = {&sci_gaptv_solver, &sci_admmtv_solver};
    for (int m = 0; m < 2; m++) {
        double f = preset_psnr(p[0], ops[m], SOLVER_PRESET_FAST), b = preset_psnr(p[0], ops[m], SOLVER_PRESET_BALANCED),
               x = preset_psnr(p[0], ops[m], SOLVER_PRESET_BEST);
        printf("%s drop40#1 presets: fast %.2f, balanced %.2f, best %.2f dB\n", ops[m]->name, f, b, x);
        assert_true(f >= x - 1.0);
        assert_true(b >= x - 0.3);
        assert_true(x >= 34.6);
    }
    sci_problem_array_free(p, k);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_orientation),
        cmocka_unit_test(test_gaptv_golden),
        cmocka_unit_test(test_presets_on_the_curve),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
