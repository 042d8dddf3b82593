/* The Aravis backend against a GigE Vision camera on loopback: arv-fake-gv-camera-0.8 serving 127.0.0.1 (started
 * and stopped by tests/aravis-gv/run, `make check-gv`). Over the real GVCP control / GVSP stream protocols:
 * identity, the fake's ramp pixel for pixel, timestamps, frames lost while the caller falls behind counted
 * exactly (the camera's 16-bit block ids skip, and the loss equals the skip), and the trigger paths: in software
 * trigger mode nothing comes until a trigger, then one frame per trigger — the path an external (line) trigger
 * takes, with the software command standing in for the pulse — and in line mode with no pulse the wait times
 * out, as a stalled external trigger does.
 *
 * SCICAP_GV_DEVICE: the device id or address (default 127.0.0.1). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include <arv.h>
#include <errno.h>
#include <math.h>
#include <time.h>
#include <unistd.h>

#include "base/clock.h"
#include "drivers/camera_aravis.h"
#include "tests/helpers/camtest.h"

#define SEC 1000000000LL
#define MS 1000000LL

static const char *g_device;
static camera *g_cam; /* the open camera, closed by teardown even when a test fails half-way (a leaked
                        * connection would keep the fake's control channel and fail every later test) */

static int teardown(void **state)
{
    (void)state;
    camera_close(g_cam);
    g_cam = NULL;
    return 0;
}

/* The fake may still be binding its socket when the first test runs: retry -ENOENT for up to 5 s. */
static camera *open_gv(camera_config *cfg)
{
    cfg->device = g_device;
    sci_error err = {0};
    camera *cam = NULL;
    int64_t until = sci_clock_mono_ns() + 5 * SEC;
    int rc;
    while ((rc = camera_open(&cam, &camera_aravis_ops, cfg, &err)) == -ENOENT && sci_clock_mono_ns() < until)
        usleep(200 * 1000);
    if (rc < 0)
        fail_msg("camera_open(%s): %d %s", g_device, rc, err.msg);
    g_cam = cam;
    return cam;
}

static uint16_t ramp_mono8(uint32_t x, uint32_t y, uint64_t id)
{
    return (uint16_t)((x + id + y) % 255); /* gain 0, exposure 10 ms: scale 1 */
}

static camera_config small_mono8(void)
{
    camera_config cfg = camera_config_default();
    cfg.width = 128;
    cfg.height = 64;
    cfg.pixfmt = PIXFMT_GREY;
    cfg.exposure_us = 10000;
    cfg.gain = 0;
    cfg.interval_num = 1;
    cfg.interval_den = 50;
    return cfg;
}

static void identity_over_gvcp(void **state)
{
    (void)state;
    camera_config cfg = small_mono8();
    camera *cam = open_gv(&cfg);
    camera_identity id;
    camera_identity_get(cam, &id);
    assert_string_equal(id.backend, "aravis");
    assert_string_equal(id.driver, "GigEVision");
    assert_string_equal(id.card, "Aravis Fake");
    assert_string_equal(id.bus_info, "GV01");
    assert_string_equal(id.path, g_device);
    teardown(NULL);
}

/* Free run: the fake's ramp arrives intact through GVSP packets (several per frame), frame after frame, with
 * increasing monotonic timestamps one period apart. */
static void free_run_frames_are_the_ramp(void **state)
{
    (void)state;
    camera_config cfg = small_mono8();
    camera *cam = open_gv(&cfg);
    sci_error err = {0};
    assert_int_equal(camera_start(cam, &err), 0);
    camera_frame fr = {0};
    int64_t prev = 0, first = 0;
    const int n = 10; /* the first frame leaves at acquisition start, off the period grid: timed from the second */
    for (int k = 0; k < n; k++) {
        camtest_wait_frame(cam, 2 * SEC, &fr);
        uint64_t id = camtest_aravis_frame_id(cam);
        for (uint32_t y = 0; y < fr.height; y++)
            for (uint32_t x = 0; x < fr.width; x++)
                if (fr.data[y * fr.width + x] != ramp_mono8(x, y, id))
                    fail_msg("frame %llu (%u,%u) = %u, the fake's ramp says %u", (unsigned long long)id, x, y,
                             fr.data[y * fr.width + x], ramp_mono8(x, y, id));
        int64_t now = sci_clock_mono_ns();
        assert_true(fr.timestamp_ns <= now + MS && now - fr.timestamp_ns < SEC);
        if (k > 0)
            assert_true(fr.timestamp_ns > prev);
        if (k == 1)
            first = fr.timestamp_ns;
        prev = fr.timestamp_ns;
    }
    camera_stats st;
    camera_stats_get(cam, &st);
    double periods = (double)(prev - first) / 20e6;
    if (fabs(periods - (n - 2 + (double)st.lost)) > 1.0)
        fail_msg("%d frames (%llu lost) span %.2f periods of 20 ms", n, (unsigned long long)st.lost, periods);
    camera_frame_release(&fr);
    teardown(NULL);
}

/* With 2 buffers and ~25 periods without waiting, the camera keeps sending and the frames that find no buffer are
 * lost: the block ids skip, and the backend's count of lost frames before the next delivered one equals the skip. */
static void losses_equal_block_id_skips(void **state)
{
    (void)state;
    camera_config cfg = small_mono8();
    cfg.buffer_count = 2;
    camera *cam = open_gv(&cfg);
    sci_error err = {0};
    assert_int_equal(camera_start(cam, &err), 0);
    camera_frame fr = {0};
    camtest_wait_frame(cam, 2 * SEC, &fr);
    usleep(500 * 1000);
    uint64_t prev_id = camtest_aravis_frame_id(cam);
    uint32_t prev_seq = fr.sequence;
    uint64_t lost = 0;
    for (int k = 0; k < 6; k++) {
        camtest_wait_frame(cam, 2 * SEC, &fr);
        uint64_t id = camtest_aravis_frame_id(cam);
        uint64_t skip = id > prev_id ? id - prev_id - 1 : id + 0xffff - prev_id - 1; /* 16-bit ids, no 0 */
        if (fr.lost_before != skip)
            fail_msg("frame id %llu after %llu: %llu skipped, backend says %u lost", (unsigned long long)id,
                     (unsigned long long)prev_id, (unsigned long long)skip, fr.lost_before);
        assert_int_equal(fr.sequence, prev_seq + 1 + fr.lost_before);
        lost += fr.lost_before;
        prev_id = id;
        prev_seq = fr.sequence;
    }
    if (lost < 15)
        fail_msg("25 periods behind with 2 buffers lost only %llu frames", (unsigned long long)lost);
    camera_stats st;
    camera_stats_get(cam, &st);
    assert_int_equal(st.lost, lost);
    camera_frame_release(&fr);
    teardown(NULL);
}

/* Software trigger: no frame without a trigger; one frame per trigger, in order, nothing extra. */
static void software_trigger_gates_frames(void **state)
{
    (void)state;
    camera_aravis_options opt = {.trigger = CAMERA_ARAVIS_TRIGGER_SOFTWARE};
    camera_config cfg = small_mono8();
    cfg.backend_options = &opt;
    camera *cam = open_gv(&cfg);
    sci_error err = {0};
    assert_int_equal(camera_start(cam, &err), 0);
    camera_frame fr = {0};
    assert_int_equal(camera_wait_frame(cam, 300 * MS, &fr, &err), -ETIMEDOUT);
    assert_non_null(strstr(err.msg, g_device));
    uint64_t prev_id = 0;
    for (int k = 0; k < 5; k++) {
        int64_t t0 = sci_clock_mono_ns();
        assert_int_equal(camera_aravis_trigger_software(cam, &err), 0);
        camtest_wait_frame(cam, 2 * SEC, &fr);
        assert_true(fr.timestamp_ns >= t0 - MS); /* taken after the trigger, not an old frame */
        uint64_t id = camtest_aravis_frame_id(cam);
        if (k > 0)
            assert_true(id == prev_id + 1 || (prev_id == 65535 && id == 1));
        prev_id = id;
        for (uint32_t x = 0; x < fr.width; x++)
            assert_int_equal(fr.data[x], ramp_mono8(x, 0, id));
        assert_int_equal(fr.lost_before, 0);
        /* exactly one frame per trigger */
        assert_int_equal(camera_wait_frame(cam, 150 * MS, &fr, &err), -ETIMEDOUT);
    }
    camera_stats st;
    camera_stats_get(cam, &st);
    assert_int_equal(st.frames, 5);
    assert_int_equal(st.lost, 0);
    camera_frame_release(&fr);
    teardown(NULL);
}

/* Line trigger with no pulse on the line: the camera is armed, nothing comes, the wait times out naming the
 * device (a stalled or missed external trigger), and the stream is still usable afterwards. */
static void line_trigger_without_pulse_times_out(void **state)
{
    (void)state;
    camera_aravis_options opt = {.trigger = CAMERA_ARAVIS_TRIGGER_LINE, .trigger_line = "Line0"};
    camera_config cfg = small_mono8();
    cfg.backend_options = &opt;
    camera *cam = open_gv(&cfg);
    sci_error err = {0};
    assert_int_equal(camera_start(cam, &err), 0);
    assert_string_equal(arv_camera_get_string(camera_aravis_arv_camera(cam), "TriggerSource", NULL), "Line0");
    camera_frame fr = {0};
    assert_int_equal(camera_wait_frame(cam, 400 * MS, &fr, &err), -ETIMEDOUT);
    camera_stats st;
    camera_stats_get(cam, &st);
    assert_int_equal(st.timeouts, 1);
    assert_int_equal(st.frames, 0);
    assert_int_equal(camera_stop(cam, &err), 0);
    teardown(NULL);
}

int main(void)
{
    g_device = getenv("SCICAP_GV_DEVICE") ? getenv("SCICAP_GV_DEVICE") : "127.0.0.1";
    printf("test_gv_loopback: GigE Vision camera at %s\n", g_device);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(identity_over_gvcp, teardown),
        cmocka_unit_test_teardown(free_run_frames_are_the_ramp, teardown),
        cmocka_unit_test_teardown(losses_equal_block_id_skips, teardown),
        cmocka_unit_test_teardown(software_trigger_gates_frames, teardown),
        cmocka_unit_test_teardown(line_trigger_without_pulse_times_out, teardown),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    arv_shutdown();
    return rc;
}
