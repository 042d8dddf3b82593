/* One snapshot through the simulated camera, trigger and DMD in each sync mode: a good sync, a short exposure,
 * a missed camera trigger, a DMD that missed its start, stale frames and drops; plus format negotiation as the
 * V4L2 backend's pure choice functions. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>
#include <errno.h>
#include <linux/videodev2.h>

#include "base/clock.h"
#include "drivers/capture.h"
#include "drivers/v4l2_util.h"
#include "sim/camera_sim.h"
#include "sim/trigger_sim.h"

static uint64_t g_seed;

/* The bench wiring: which line starts what, per sync mode. */
typedef struct rig {
    enum sync_mode mode;
    camera *cam;
    trigger *trig;
    camera_sim *cs;
    trigger_sim *ts;
    sync_timeline tl;
    int64_t dmd_latency_ns;  /* DMD trigger-in to pattern 0 */
    int64_t dmd_jitter_ns;
    int dmd_misses;          /* the DMD ignores its next n starts */
    int arm_model;           /* camera master: the strobe starts the DMD only once armed (through r->dmd) */
    int armed;
    int64_t armed_ns;        /* only an exposure starting later starts it */
    int64_t arm_call_ns;     /* how long the arm call takes */
    int arm_late;            /* 1: armed at the end of the call (the simulator); 0: at its start (the hardware) */
    int arm_fails;           /* the arm call fails: the DMD is unplugged */
    dmd *dmd;
    capture_params p;
    capture_snapshot snap;
} rig;

static void dmd_start_at(rig *r, int64_t t)
{
    if (r->dmd_misses > 0) {
        r->dmd_misses--;
        return;
    }
    trigger_sim_play(r->ts, &r->tl, t + r->dmd_latency_ns, r->dmd_jitter_ns, 20);
}

static void on_output(void *arg, int64_t t, uint32_t width_us)
{
    rig *r = arg;
    (void)width_us;
    if (r->mode == SYNC_MODE_HOST_MASTER) {
        camera_sim_trigger(r->cs, t);
        dmd_start_at(r, t);
    } else if (r->mode == SYNC_MODE_DMD_MASTER) {
        /* the output is wired to the DMD; the DMD's first pattern trigger starts the camera */
        int before = r->dmd_misses;
        dmd_start_at(r, t);
        if (r->dmd_misses == before)
            camera_sim_trigger(r->cs, t + r->dmd_latency_ns);
    }
}

static void on_strobe(void *arg, const camera_sim_exposure *e)
{
    rig *r = arg;
    trigger_sim_inject(r->ts, TRIGGER_ROLE_STROBE, e->start_ns, 1);
    trigger_sim_inject(r->ts, TRIGGER_ROLE_STROBE, e->end_ns, 0);
    if (r->mode != SYNC_MODE_CAMERA_MASTER)
        return;
    if (!r->arm_model) {
        dmd_start_at(r, e->start_ns);
    } else if (r->armed && e->start_ns >= r->armed_ns) {
        r->armed = 0;
        dmd_start_at(r, e->start_ns);
    }
}

/* A DMD whose start call arms it, slowly: the camera keeps exposing meanwhile. */
static void arm_sleep(int64_t ns)
{
    struct timespec ts = {.tv_sec = ns / 1000000000LL, .tv_nsec = ns % 1000000000LL};
    while (nanosleep(&ts, &ts) < 0)
        ;
}
static int arm_open(void **state, const dmd_config *cfg, sci_error *err)
{
    (void)err;
    *state = (void *)cfg->backend_options;
    return 0;
}
static void arm_close(void *state) { (void)state; }
static int arm_start(void *state, sci_error *err)
{
    rig *r = state;
    if (r->arm_fails)
        return sci_error_set(err, -ENODEV, "DMD: not connected");
    if (r->arm_late)
        arm_sleep(r->arm_call_ns);
    r->armed = 1;
    r->armed_ns = sci_clock_mono_ns();
    if (!r->arm_late)
        arm_sleep(r->arm_call_ns);
    return 0;
}
static int arm_stop(void *state, sci_error *err)
{
    (void)err;
    ((rig *)state)->armed = 0;
    return 0;
}
static const dmd_ops arm_ops = {.name = "arm", .open = arm_open, .close = arm_close, .start = arm_start,
                                .stop = arm_stop};

static void rig_open(rig *r, enum sync_mode mode, uint32_t exposure_us, int strobe_wired)
{
    memset(r, 0, sizeof *r);
    r->mode = mode;
    r->dmd_latency_ns = 300000;
    r->dmd_jitter_ns = 2000;
    assert_int_equal(sync_timeline_uniform(&r->tl, 0, 8, 1000, 100, NULL), 0); /* 8.7 ms of patterns */
    sci_error err = {0};
    camera_sim_options copt = {.strobe = on_strobe, .strobe_arg = r, .readout_ns = 200000};
    camera_config cc = camera_config_default();
    cc.width = 64;
    cc.height = 32;
    cc.pixfmt = PIXFMT_Y10P;
    cc.exposure_us = exposure_us;
    cc.interval_num = 1;
    cc.interval_den = 40; /* free run (camera master): 25 ms period */
    if (mode != SYNC_MODE_CAMERA_MASTER) {
        cc.trigger_profile[0] = (camera_control){.name = "trigger_mode", .value = 1};
        cc.trigger_profile_count = 1;
    }
    cc.backend_options = &copt;
    if (camera_open(&r->cam, &camera_sim_ops, &cc, &err) < 0)
        fail_msg("%s", err.msg);
    r->cs = camera_sim_from(r->cam);
    trigger_sim_options topt = {.seed = g_seed, .latency_ns = 20000, .jitter_ns = 5000, .on_output = on_output,
                                .on_output_arg = r};
    trigger_config tc = trigger_config_default();
    tc.chip = "sim-gpiochip0";
    tc.output.offset = 17;
    tc.inputs[TRIGGER_ROLE_DMD].offset = 22;
    if (strobe_wired)
        tc.inputs[TRIGGER_ROLE_STROBE].offset = 27;
    tc.backend_options = &topt;
    if (trigger_open(&r->trig, &trigger_sim_ops, &tc, &err) < 0)
        fail_msg("%s", err.msg);
    r->ts = trigger_sim_from(r->trig);
    assert_int_equal(camera_start(r->cam, &err), 0);
    r->p = capture_params_default();
    r->p.mode = mode;
    r->p.timeline = &r->tl;
    r->p.dmd_latency_ns = r->dmd_latency_ns;
    r->p.readout_ns = 200000;
    r->p.frame_timeout_ns = 200000000;
}

static void rig_close(rig *r)
{
    dmd_close(r->dmd); /* NULL unless rig_open_armed */
    capture_snapshot_release(&r->snap);
    camera_close(r->cam);
    trigger_close(r->trig);
}

static void assert_not_broken(const capture_snapshot *sn)
{
    char flags[128];
    if (sn->report.broken)
        fail_msg("broken sync: %s (edges %d/%d, inside %d, offset %lld ns, jitter %lld ns)",
                 sync_flags_describe(sn->report.flags, flags, sizeof flags), sn->report.edges_matched,
                 sn->report.edges_seen, sn->report.inside, (long long)sn->report.offset_ns,
                 (long long)sn->report.jitter_ns);
}

static void expect_good(rig *r)
{
    sci_error err = {0};
    int rc = capture_snapshot_take(r->cam, r->trig, &r->p, &r->snap, &err);
    if (rc < 0)
        fail_msg("capture (%s): %s", sync_mode_name(r->mode), err.msg);
    char flags[128];
    sync_report *rep = &r->snap.report;
    if (rep->broken)
        fail_msg("%s: broken sync: %s, offset %lld ns, jitter %lld ns, inside %d", sync_mode_name(r->mode),
                 sync_flags_describe(rep->flags, flags, sizeof flags), (long long)rep->offset_ns,
                 (long long)rep->jitter_ns, rep->inside);
    assert_int_equal(rep->inside, 8);
    assert_int_equal(rep->edges_matched, 8);
    assert_true(rep->exposure_measured);
    assert_int_equal(r->snap.frame.width, 64);
    assert_int_equal(r->snap.frame.bits_per_sample, 10);
    printf("  %s: offset %lld ns, jitter %lld ns, lead %lld us, trail %lld us\n", sync_mode_name(r->mode),
           (long long)rep->offset_ns, (long long)rep->jitter_ns, (long long)rep->lead_ns / 1000,
           (long long)rep->trail_ns / 1000);
}

static void host_master_good_sync(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_HOST_MASTER, 10000, 1);
    expect_good(&r);
    /* the measured offset is the simulated trigger latency plus jitter: 20..25 µs */
    assert_true(r.snap.report.offset_ns >= 20000 && r.snap.report.offset_ns <= 25000 + 2000);
    assert_true(r.snap.report.jitter_ns <= 2000);
    expect_good(&r); /* and again: stale edges and frames from the first do not leak into the second */
    json_t *meta = capture_snapshot_meta_json(&r.snap);
    assert_non_null(meta);
    assert_string_equal(json_string_value(json_object_get(meta, "sync_mode")), "host-master");
    assert_int_equal(json_integer_value(json_object_get(json_object_get(meta, "frame"), "exposure_us")), 10000);
    assert_int_equal(json_integer_value(json_object_get(json_object_get(meta, "frame"), "bits_per_sample")), 10);
    assert_string_equal(json_string_value(json_object_get(json_object_get(meta, "camera"), "backend")), "sim");
    assert_int_equal(json_integer_value(json_object_get(json_object_get(meta, "trigger"), "output_line")), 17);
    assert_true(json_is_false(json_object_get(json_object_get(meta, "sync"), "broken")));
    json_decref(meta);
    rig_close(&r);
}

static void dmd_master_good_sync(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_DMD_MASTER, 9500, 1);
    expect_good(&r);
    rig_close(&r);
}

static void camera_master_good_sync(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_CAMERA_MASTER, 10000, 1);
    r.p.dmd_latency_ns = r.dmd_latency_ns;
    expect_good(&r);
    assert_true(r.snap.report.offset_ns >= 0 && r.snap.report.offset_ns <= 2000);
    rig_close(&r);
}

/* Camera master with the DMD armed by the capture: an arm call longer than the camera's period (25 ms) has
 * an exposure start inside it. Armed at the call's end, that exposure did not start the DMD and the next one did;
 * armed at its start, it did. Either way the snapshot holds the whole sequence. */
/* A camera-master rig whose capture arms the DMD through arm_ops (r->arm_* set after). */
static void rig_open_armed(rig *r)
{
    rig_open(r, SYNC_MODE_CAMERA_MASTER, 10000, 1);
    r->arm_model = 1;
    dmd_config cfg = dmd_config_default();
    cfg.backend_options = r;
    sci_error err = {0};
    assert_int_equal(dmd_open(&r->dmd, &arm_ops, &cfg, &err), 0);
    r->p.dmd = r->dmd;
}

static void camera_master_slow_arm(int late)
{
    rig r;
    rig_open_armed(&r);
    r.arm_late = late;
    r.arm_call_ns = 30000000;
    for (int k = 0; k < 2; k++) {
        expect_good(&r);
        /* the first exposure to start after the arm, one camera period at most */
        assert_true(r.snap.start_ns >= r.armed_ns && r.snap.start_ns - r.armed_ns <= 25000000);
    }
    assert_false(r.armed); /* one sequence a snapshot */
    rig_close(&r);
}
/* An arm that fails is the DMD's error, which the caller must not take for the camera's. */
static void camera_master_arm_failure_is_the_dmds(void **state)
{
    (void)state;
    rig r;
    rig_open_armed(&r);
    r.arm_fails = 1;
    sci_error err = {0};
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), -ENODEV);
    assert_true(r.snap.dmd_failed);
    r.arm_fails = 0;
    expect_good(&r);
    assert_false(r.snap.dmd_failed);
    rig_close(&r);
}

static void camera_master_armed_late_in_a_slow_call(void **state)
{
    (void)state;
    camera_master_slow_arm(1);
}
static void camera_master_armed_early_in_a_slow_call(void **state)
{
    (void)state;
    camera_master_slow_arm(0);
}

static void short_exposure_is_flagged(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_HOST_MASTER, 6000, 1); /* patterns need 8.7 ms after a 0.3 ms latency */
    sci_error err = {0};
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), 0);
    assert_true(r.snap.report.broken);
    assert_true(r.snap.report.flags & (SYNC_FLAG_PARTIAL_MASK | SYNC_FLAG_MASK_OUTSIDE));
    assert_int_equal(r.snap.report.inside, 5); /* patterns 0..4 end by 0.3 + 4*1.1 + 1 = 5.7 ms */
    assert_int_equal(r.snap.report.partial, 1);
    assert_int_equal(r.snap.report.outside, 2);
    rig_close(&r);
}

static void missed_trigger_times_out(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_HOST_MASTER, 10000, 1);
    r.p.frame_timeout_ns = 50000000;
    trigger_sim_miss_next(r.ts, 1);
    sci_error err = {0};
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), -ETIMEDOUT);
    assert_non_null(strstr(err.msg, "missed trigger?"));
    assert_non_null(strstr(err.msg, "sim-camera"));
    assert_true(r.snap.report.flags & SYNC_FLAG_NO_FRAME);
    assert_true(r.snap.report.broken);
    /* the camera alone missing it (stall) is the same to the caller */
    camera_sim_fault(r.cs, CAMERA_SIM_FAULT_STALL, 1);
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), -ETIMEDOUT);
    assert_non_null(strstr(err.msg, "DMD edges seen: 8")); /* the DMD did run: the diagnosis says so */
    /* the next snapshot works again */
    r.p.frame_timeout_ns = 200000000;
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), 0);
    assert_not_broken(&r.snap);
    rig_close(&r);
}

static void dmd_missed_start_is_flagged(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_HOST_MASTER, 10000, 1);
    r.dmd_misses = 1;
    sci_error err = {0};
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), 0);
    assert_true(r.snap.report.flags & SYNC_FLAG_NO_DMD_EDGES);
    assert_true(r.snap.report.broken);
    rig_close(&r);
}

static void without_strobe_the_window_is_estimated(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_HOST_MASTER, 10000, 0);
    sci_error err = {0};
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), 0);
    assert_false(r.snap.report.exposure_measured);
    assert_true(r.snap.report.flags & SYNC_FLAG_EXPOSURE_ESTIMATED);
    assert_not_broken(&r.snap);
    assert_int_equal(r.snap.strobe_edges, 0);
    rig_close(&r);
}

static void drops_and_stale_frames_are_reported(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_CAMERA_MASTER, 10000, 1);
    sci_error err = {0};
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), 0);
    camera_sim_fault(r.cs, CAMERA_SIM_FAULT_DROP, 2);
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), 0);
    assert_int_equal(r.snap.frame.lost_total, 2);
    assert_not_broken(&r.snap);
    rig_close(&r);
}

static void disconnect_during_capture(void **state)
{
    (void)state;
    rig r;
    rig_open(&r, SYNC_MODE_HOST_MASTER, 10000, 1);
    camera_sim_fault(r.cs, CAMERA_SIM_FAULT_DISCONNECT, 0);
    sci_error err = {0};
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), -ENODEV);
    camera_sim_replug(r.cs);
    assert_int_equal(camera_recover(r.cam, &err), 0);
    assert_int_equal(capture_snapshot_take(r.cam, r.trig, &r.p, &r.snap, &err), 0);
    assert_not_broken(&r.snap);
    rig_close(&r);
}

static void v4l2_format_choice(void **state)
{
    (void)state;
    sci_error err = {0};
    enum pixfmt f;
    const v4l2_util_fmtdesc webcam[] = {{V4L2_PIX_FMT_YUYV, 0}, {V4L2_PIX_FMT_MJPEG, V4L2_FMT_FLAG_COMPRESSED}};
    assert_int_equal(v4l2_util_choose_format(webcam, 2, PIXFMT_NONE, "/dev/video0", &f, &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, "/dev/video0: offers no raw monochrome format"));
    assert_non_null(strstr(err.msg, "YUYV (colour), MJPG (compressed)"));
    assert_int_equal(v4l2_util_choose_format(webcam, 2, PIXFMT_Y16, "/dev/video0", &f, &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, "does not offer format Y16"));
    const v4l2_util_fmtdesc mono[] = {{V4L2_PIX_FMT_GREY, 0}, {V4L2_PIX_FMT_Y10P, 0}, {V4L2_PIX_FMT_YUYV, 0}};
    assert_int_equal(v4l2_util_choose_format(mono, 3, PIXFMT_NONE, "cam", &f, &err), 0);
    assert_int_equal(f, PIXFMT_Y10P); /* more bits beat GREY */
    const v4l2_util_fmtdesc vivid[] = {{V4L2_PIX_FMT_Y10P, 0}, {V4L2_PIX_FMT_Y16, 0}, {V4L2_PIX_FMT_Y12, 0}};
    assert_int_equal(v4l2_util_choose_format(vivid, 3, PIXFMT_NONE, "cam", &f, &err), 0);
    assert_int_equal(f, PIXFMT_Y16);
    assert_int_equal(v4l2_util_choose_format(vivid, 3, PIXFMT_Y12, "cam", &f, &err), 0);
    assert_int_equal(f, PIXFMT_Y12);

    /* vivid's webcam input: discrete sizes */
    const v4l2_util_framesize disc[] = {{320, 320, 0, 180, 180, 0}, {1280, 1280, 0, 720, 720, 0},
                                        {1920, 1920, 0, 1080, 1080, 0}};
    uint32_t w, h;
    assert_int_equal(v4l2_util_choose_size(disc, 3, 1920, 1080, "cam", &w, &h, &err), 0);
    assert_int_equal(v4l2_util_choose_size(disc, 3, 0, 0, "cam", &w, &h, &err), 0);
    assert_int_equal(w, 1920);
    assert_int_equal(h, 1080);
    assert_int_equal(v4l2_util_choose_size(disc, 3, 1000, 1000, "cam", &w, &h, &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, "1000x1000 is not offered; sizes: 320x180, 1280x720, 1920x1080"));
    const v4l2_util_framesize step[] = {{16, 4096, 16, 16, 2160, 2}};
    assert_int_equal(v4l2_util_choose_size(step, 1, 1936, 1096, "cam", &w, &h, &err), 0);
    assert_int_equal(v4l2_util_choose_size(step, 1, 1930, 1096, "cam", &w, &h, &err), -ENOTSUP);
    assert_true(v4l2_util_ctrl_name_eq("Trigger Mode", "trigger_mode"));
    assert_false(v4l2_util_ctrl_name_eq("Trigger Mode", "trigger_source"));
}

int main(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    g_seed = s ? strtoull(s, NULL, 0) : 11u;
    printf("test_capture: seed %llu (set SCICAP_TEST_SEED to change)\n", (unsigned long long)g_seed);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(host_master_good_sync),
        cmocka_unit_test(dmd_master_good_sync),
        cmocka_unit_test(camera_master_good_sync),
        cmocka_unit_test(camera_master_armed_late_in_a_slow_call),
        cmocka_unit_test(camera_master_armed_early_in_a_slow_call),
        cmocka_unit_test(camera_master_arm_failure_is_the_dmds),
        cmocka_unit_test(short_exposure_is_flagged),
        cmocka_unit_test(missed_trigger_times_out),
        cmocka_unit_test(dmd_missed_start_is_flagged),
        cmocka_unit_test(without_strobe_the_window_is_estimated),
        cmocka_unit_test(drops_and_stale_frames_are_reported),
        cmocka_unit_test(disconnect_during_capture),
        cmocka_unit_test(v4l2_format_choice),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
