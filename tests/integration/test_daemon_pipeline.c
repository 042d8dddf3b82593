/* scicapd end to end on the simulated bench, over the real socket: capture -> store -> reconstruct with a PSNR
 * floor; the capture folder is a valid problem folder with the raw 16-bit TIFF, the masks shown, meta.json and
 * the reconstruction; calibration (dark frame, measured masks) is used by the next capture. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "io/image.h"
#include "io/problem_dir.h"
#include "tests/integration/daemon_harness.h"

#define PSNR_FLOOR_DB 20.0 /* default scene, GAP-TV default preset: ~23 dB (offline `scicap recon`: 23.1 dB) */

static void capture_then_reconstruct(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, NULL, NULL);
    hconn c;
    hconn_open(&c, &h);
    json_t *r = hconn_request(&c, "capture", json_pack("{s:b, s:s}", "reconstruct", 1, "preset", "default"));
    json_int_t job = json_integer_value(json_object_get(r, "job"));
    assert_true(job > 0);
    json_decref(r);
    json_t *snap = hconn_wait_event(&c, "capture.snapshot", 20000);
    assert_true(json_is_false(json_object_get(json_object_get(snap, "data"), "broken")));
    assert_int_equal(json_integer_value(json_object_get(json_object_get(snap, "data"), "inside")), 8);
    json_decref(snap);
    json_t *st = hconn_wait_event(&c, "capture.stored", 20000);
    const char *cap = json_string_value(json_object_get(json_object_get(st, "data"), "capture"));
    assert_non_null(cap);
    char id[64];
    snprintf(id, sizeof id, "%s", cap);
    printf("  stored %s, %.0f ms after the request\n", id,
           json_number_value(json_object_get(json_object_get(st, "data"), "latency_ms")));
    json_decref(st);
    json_t *done = hconn_wait_event(&c, "recon.done", 60000);
    json_t *d = json_object_get(done, "data");
    double psnr = json_number_value(json_object_get(d, "psnr"));
    printf("  %s: PSNR %.2f dB, SSIM %.3f, solve %.2f s\n", json_string_value(json_object_get(d, "method")), psnr,
           json_number_value(json_object_get(d, "ssim")), json_number_value(json_object_get(d, "solve_s")));
    assert_true(psnr >= PSNR_FLOOR_DB);
    json_decref(done);

    /* the folder: a problem folder plus raw.tif, masks shown, meta.json, recon/gap-tv/ */
    char dir[512];
    snprintf(dir, sizeof dir, "%s/captures/%s", h.store, id);
    sci_problem **p;
    int k;
    sci_error err = {0};
    if (sci_problem_dir_read(dir, &p, &k, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(k, 1);
    assert_int_equal(p[0]->mask->n, 8);
    assert_non_null(p[0]->truth);
    sci_problem_array_free(p, k);
    char path[700];
    snprintf(path, sizeof path, "%s/raw.tif", dir);
    sci_cube *raw;
    int bits;
    if (sci_image_read(path, &raw, &bits, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(bits, 16);
    assert_int_equal(raw->w, 256);
    sci_cube_free(raw);
    assert_true(h_exists("%s/%s", dir, "dmd_mask_007.png"));
    assert_true(h_exists("%s/%s", dir, "recon/gap-tv/trace.csv"));
    assert_true(h_exists("%s/%s", dir, "recon/gap-tv/preview.gif"));
    assert_true(h_exists("%s/%s", dir, "recon/gap-tv/frame_000.exr"));
    snprintf(path, sizeof path, "%s/meta.json", dir);
    json_error_t je;
    json_t *meta = json_load_file(path, 0, &je);
    assert_non_null(meta);
    assert_string_equal(json_string_value(json_object_get(meta, "capture_id")), id);
    assert_non_null(json_object_get(meta, "sync"));
    assert_non_null(json_object_get(json_object_get(meta, "software"), "version"));
    assert_string_equal(json_string_value(json_object_get(json_object_get(json_object_get(meta, "devices"), "dmd"),
                                                          "serial")), "SIM0001");
    assert_int_equal(json_integer_value(json_object_get(json_object_get(meta, "settings"), "pattern_us")), 1000);
    json_decref(meta);

    /* reconstruct again through the command, another method */
    r = hconn_request(&c, "reconstruct", json_pack("{s:s, s:s, s:{s:i}}", "capture", id, "method", "admm-tv",
                                                   "params", "iters", 40));
    json_decref(r);
    done = hconn_wait_event(&c, "recon.done", 60000);
    assert_string_equal(json_string_value(json_object_get(json_object_get(done, "data"), "method")), "admm-tv");
    json_decref(done);
    assert_true(h_exists("%s/%s", dir, "recon/admm-tv/result.json"));
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

static void calibration_is_used(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, NULL, NULL);
    hconn c;
    hconn_open(&c, &h);
    json_decref(hconn_request(&c, "calibrate", json_pack("{s:s}", "kind", "dark")));
    json_t *e = hconn_wait_event(&c, "calibrate.done", 20000);
    double dark = json_number_value(json_object_get(json_object_get(e, "data"), "mean_counts"));
    printf("  dark frame: mean %.1f counts\n", dark);
    assert_true(dark > 150 && dark < 250); /* the simulator's 200 counts */
    json_decref(e);
    json_decref(hconn_request(&c, "calibrate", json_pack("{s:s, s:i}", "kind", "masks", "average", 2)));
    e = hconn_wait_event(&c, "calibrate.done", 30000);
    double white = json_number_value(json_object_get(json_object_get(e, "data"), "counts_per_unit"));
    printf("  measured masks: white level %.1f counts\n", white);
    assert_true(fabs(white - 6000) < 60);
    json_decref(e);
    json_decref(hconn_request(&c, "capture", json_pack("{s:b, s:s}", "reconstruct", 1, "preset", "fast")));
    json_t *st = hconn_wait_event(&c, "capture.stored", 20000);
    char path[700];
    snprintf(path, sizeof path, "%s/calibration.json",
             json_string_value(json_object_get(json_object_get(st, "data"), "dir")));
    json_decref(st);
    json_error_t je;
    json_t *cal = json_load_file(path, 0, &je);
    assert_non_null(cal);
    assert_string_equal(json_string_value(json_object_get(cal, "kind")), "measured-masks");
    json_decref(cal);
    e = hconn_wait_event(&c, "recon.done", 60000);
    double psnr = json_number_value(json_object_get(json_object_get(e, "data"), "psnr"));
    printf("  with measured masks (fast preset): PSNR %.2f dB\n", psnr);
    assert_true(psnr >= 19.0);
    json_decref(e);
    /* calibrations survive a restart */
    hconn_close(&c);
    harness_stop(&h);
    assert_true(h_exists("%s/%s", h.store, "calibrations/masks-random8.json"));
    assert_true(h_exists("%s/%s", h.store, "calibrations/dark.json"));
    harness_cleanup(&h);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(capture_then_reconstruct),
        cmocka_unit_test(calibration_is_used),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
