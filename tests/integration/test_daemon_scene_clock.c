/* The simulated bench shows the scene moving on from capture to capture: capture number c sees the scene's clock
 * frames (c − 1)·n … (c − 1)·n + n − 1 (sim/bench.h), so consecutive captures differ, each with its truth, and
 * the same number gives the same frames after a restart (meta.json "simulated"."scene_frames" says which). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "io/problem_dir.h"
#include "tests/helpers/daemon_child.h"

static harness H;
static char scicap[1024];

/* meta.json's simulated.scene_frames of capture `cap` must be first, first + 1, ... (n of them). */
static void assert_scene_frames(const char *cap, int first, int n)
{
    char p[700];
    snprintf(p, sizeof p, "%s/captures/%s/meta.json", H.store, cap);
    json_t *m = json_load_file(p, 0, NULL);
    assert_non_null(m);
    json_t *t = json_object_get(json_object_get(m, "simulated"), "scene_frames");
    assert_int_equal(json_array_size(t), n);
    for (int k = 0; k < n; k++)
        if (json_number_value(json_array_get(t, (size_t)k)) != first + k)
            fail_msg("%s: scene_frames[%d] = %g, expected %d", cap, k, json_number_value(json_array_get(t, (size_t)k)),
                     first + k);
    json_decref(m);
}

static double gap_tv_psnr(hconn *c, const char *cap)
{
    json_decref(hconn_request(c, "reconstruct", json_pack("{s:s, s:s}", "capture", cap, "preset", "fast")));
    json_t *e = hconn_wait_event(c, "recon.done", 60000);
    double v = json_number_value(json_object_get(json_object_get(e, "data"), "psnr"));
    json_decref(e);
    return v;
}

static void consecutive_captures_differ(void **state)
{
    hconn c;
    hconn_open(&c, &H);
    char cap[2][32];
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 2)));
    for (int i = 0; i < 2; i++) {
        json_t *e = hconn_wait_event(&c, "capture.stored", 30000);
        json_t *d = json_object_get(e, "data");
        snprintf(cap[json_integer_value(json_object_get(d, "index"))], 32, "%s",
                 json_string_value(json_object_get(d, "capture")));
        json_decref(e);
    }
    assert_string_equal(cap[0], "c000001");
    assert_string_equal(cap[1], "c000002");
    assert_scene_frames(cap[0], 0, 8);
    assert_scene_frames(cap[1], 8, 8);
    sci_problem *a = daemon_child_read_capture(&H, cap[0]), *b = daemon_child_read_capture(&H, cap[1]);
    assert_non_null(a->truth);
    assert_non_null(b->truth);
    double truth_moved = 0, meas_moved = 0;
    for (size_t i = 0; i < sci_cube_count(a->truth); i++)
        truth_moved = fmax(truth_moved, fabs(a->truth->data[i] - b->truth->data[i]));
    for (size_t i = 0; i < sci_cube_count(a->meas); i++)
        meas_moved = fmax(meas_moved, fabs(a->meas->data[i] - b->meas->data[i]));
    double pa = gap_tv_psnr(&c, cap[0]), pb = gap_tv_psnr(&c, cap[1]);
    print_message("  %s and %s: truth differs by up to %.3f, measurement by %.3f; gap-tv fast %.2f and %.2f dB\n",
                  cap[0], cap[1], truth_moved, meas_moved, pa, pb);
    assert_true(truth_moved > 0.1);
    assert_true(meas_moved > 0.1);
    assert_true(fabs(pa - pb) > 0.01);
    sci_problem_free(a);
    sci_problem_free(b);
    hconn_close(&c);
}

/* The frames follow the capture number, not the daemon's run: after a restart c000003 sees 16 … 23. */
static void same_number_same_frames_after_restart(void **state)
{
    harness_stop(&H);
    harness_spawn(&H, NULL);
    hconn c;
    hconn_open(&c, &H);
    char cap[32];
    daemon_child_capture(&c, cap, sizeof cap, 30000);
    assert_string_equal(cap, "c000003");
    assert_scene_frames(cap, 16, 8);
    hconn_close(&c);
}

static int setup(void **state) { return daemon_child_setup(&H, scicap, sizeof scicap, NULL); }
static int teardown(void **state) { return daemon_child_teardown(&H); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(consecutive_captures_differ),
        cmocka_unit_test(same_number_same_frames_after_restart),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
