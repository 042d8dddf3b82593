/* The tracer keeps its last iteration's per-frame metrics in the result (recon/problem.h, final_metrics), and
 * result.json's summary (io/recon_store.h) takes them instead of computing PSNR and SSIM again: the values equal
 * a fresh computation on the result's frames; a result whose frames are not those the metrics were computed on
 * is computed afresh. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "io/recon_store.h"
#include "recon/gaptv.h"
#include "recon/metrics.h"

static sci_problem *small_problem(void)
{
    sci_problem *p = calloc(1, sizeof *p);
    assert_non_null(p);
    const int w = 48, h = 40, n = 4;
    assert_int_equal(sci_cube_new(&p->mask, w, h, n, NULL), 0);
    assert_int_equal(sci_cube_new(&p->truth, w, h, n, NULL), 0);
    assert_int_equal(sci_cube_new(&p->meas, w, h, 1, NULL), 0);
    unsigned s = 7;
    for (size_t i = 0; i < sci_cube_count(p->mask); i++) {
        s = s * 1103515245u + 12345u;
        p->mask->data[i] = (float)((s >> 16) & 1);
        const size_t x = i % w, y = (i / w) % h, k = i / ((size_t)w * h);
        p->truth->data[i] = (float)(0.5 + 0.4 * sin(0.2 * (double)x + 0.1 * (double)k) * cos(0.15 * (double)y));
    }
    for (int k = 0; k < n; k++)
        for (size_t i = 0; i < (size_t)w * h; i++)
            p->meas->data[i] += sci_cube_frame(p->mask, k)[i] * sci_cube_frame(p->truth, k)[i];
    p->peak = 1;
    snprintf(p->name, sizeof p->name, "final-metrics");
    return p;
}

static void check_summary(const sci_problem *p, const sci_result *r)
{
    const int n = r->frames->n;
    double want[3 * 8];
    sci_psnr(r->frames, p->truth, SCI_PEAK_FRAME_MAX, 0, want);
    sci_psnr(r->frames, p->truth, SCI_PEAK_FIXED, p->peak, want + n);
    sci_ssim(r->frames, p->truth, p->peak, want + 2 * n);
    json_t *s = sci_recon_summary(p, r, NULL);
    const char *keys[3] = {"psnr_frame_max_db", "psnr_peak1_db", "ssim"};
    for (int m = 0; m < 3; m++) {
        json_t *a = json_object_get(json_object_get(s, keys[m]), "frames");
        assert_int_equal(json_array_size(a), n);
        for (int k = 0; k < n; k++) {
            const double got = json_number_value(json_array_get(a, (size_t)k));
            if (fabs(got - want[m * n + k]) > 1e-9 * fmax(1, fabs(got)))
                fail_msg("%s frame %d: %.12g, computed afresh %.12g", keys[m], k, got, want[m * n + k]);
        }
    }
    json_decref(s);
}

static void test_final_metrics_reused(void **state)
{
    sci_problem *p = small_problem();
    sci_gaptv_params gp;
    sci_gaptv_params_default(&gp);
    gp.iters = 12;
    gp.ssim_every = 0;
    sci_result r = {0};
    assert_int_equal(sci_gaptv_solve(p, &gp, &r, NULL, NULL), 0);
    assert_non_null(r.final_metrics);
    assert_int_equal(r.final_n, 4);
    assert_ptr_equal(r.final_of, r.frames->data);
    assert_true(isfinite(r.trace.e[r.trace.len - 1].ssim));
    check_summary(p, &r);
    /* frames that are not the traced ones: the summary computes afresh (here: after a change of one pixel) */
    r.frames->data[5] += 0.25f;
    sci_cube *other = NULL;
    assert_int_equal(sci_cube_clone(&other, r.frames, NULL), 0);
    sci_cube_free(r.frames);
    r.frames = other;
    check_summary(p, &r);
    sci_result_free_contents(&r);
    assert_null(r.final_metrics);
    sci_problem_free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_final_metrics_reused)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
