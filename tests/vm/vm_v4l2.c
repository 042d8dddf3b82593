/* Kernel-level test of the V4L2 camera backend against vivid (runs inside the check-vm guest, tests/vm/run).
 *
 * vivid is loaded capture-only with one webcam input (tests/vm/init). Covered: every mono format the backend
 * measures with (GREY, Y10, Y12, Y16) captured through mmap streaming, checked pixel by pixel across formats
 * (vivid's pattern generator writes the same 8-bit luma y as y, y<<2, y<<4 and y<<8 — so a wrong byte order or
 * shift shows); sequence numbers and CLOCK_MONOTONIC end-of-frame timestamps; the frame interval set with S_PARM;
 * gain set and read back; exposure, which vivid lacks, refused with -ENOTSUP naming the device; named controls of
 * a trigger profile (v4l2-ctl spelling) applied through VIDIOC_S_EXT_CTRLS; a second user refused while the
 * first streams; vivid's error injection: dropped buffers counted as lost frames, an error-flagged buffer as a
 * corrupt frame, a fatal streaming error (-EIO) and a disconnect (-ENODEV) both recovered by camera_recover.
 *
 * Needs root and vivid; exits 77 (skip) when no vivid node exists, so it can also run on a host that has one. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <cmocka.h>

#include "base/clock.h"
#include "drivers/camera_v4l2.h"
#include "drivers/v4l2_util.h"

enum { W = 320, H = 180, NFMT = 4 };
#define VIVID_CARD "vivid"
#define FRAME_TIMEOUT_NS (3 * 1000000000LL) /* generous: the guest runs under TCG */

static char g_node[64];                     /* the vivid capture node, found once */
static uint16_t *g_frames[NFMT];            /* last frame of each format, for the cross-format check */
static const enum pixfmt g_fmts[NFMT] = {PIXFMT_GREY, PIXFMT_Y10, PIXFMT_Y12, PIXFMT_Y16};

/* ---- a side channel to vivid's own controls (error injection), on a second fd ---- */

static int ctl_find(int fd, const char *name, uint32_t *id)
{
    struct v4l2_query_ext_ctrl q = {.id = V4L2_CTRL_FLAG_NEXT_CTRL};
    while (ioctl(fd, VIDIOC_QUERY_EXT_CTRL, &q) == 0) {
        if (v4l2_util_ctrl_name_eq(q.name, name)) {
            *id = q.id;
            return 0;
        }
        q = (struct v4l2_query_ext_ctrl){.id = q.id | V4L2_CTRL_FLAG_NEXT_CTRL};
    }
    return -ENOENT;
}

static void ctl_set(const char *name, int32_t value)
{
    int fd = open(g_node, O_RDWR | O_CLOEXEC);
    assert_true(fd >= 0);
    uint32_t id = 0;
    if (ctl_find(fd, name, &id) < 0)
        fail_msg("%s: vivid has no control \"%s\" (loaded with no_error_inj?)", g_node, name);
    struct v4l2_ext_control c = {.id = id, .value = value};
    struct v4l2_ext_controls cs = {.which = V4L2_CTRL_WHICH_CUR_VAL, .count = 1, .controls = &c};
    if (ioctl(fd, VIDIOC_S_EXT_CTRLS, &cs) < 0)
        fail_msg("%s: setting \"%s\" = %d: %s", g_node, name, value, strerror(errno));
    close(fd);
}

/* ---- helpers ---- */

/* Cameras a test holds: closed by the teardown too, so a failed test does not leave the node streaming. */
static camera *g_open[4];

static camera *open_cam(camera_config *cfg)
{
    camera *cam = NULL;
    sci_error err = {0};
    if (camera_open(&cam, &camera_v4l2_ops, cfg, &err) < 0)
        fail_msg("camera_open: %s", err.msg);
    for (int i = 0; i < 4; i++)
        if (!g_open[i]) {
            g_open[i] = cam;
            break;
        }
    return cam;
}

static void close_cam(camera *cam)
{
    for (int i = 0; i < 4; i++)
        if (g_open[i] == cam)
            g_open[i] = NULL;
    camera_close(cam);
}

static int teardown(void **state)
{
    (void)state;
    for (int i = 0; i < 4; i++) {
        camera_close(g_open[i]);
        g_open[i] = NULL;
    }
    return 0;
}

static camera_config base_cfg(enum pixfmt f)
{
    camera_config cfg = camera_config_default();
    cfg.device = g_node;
    cfg.width = W;
    cfg.height = H;
    cfg.pixfmt = f;
    /* a static picture: no OSD text (it carries a frame counter); set by name through the backend */
    cfg.trigger_profile_name = "vivid-static";
    cfg.trigger_profile[0] = (camera_control){"osd_text_mode", 2};
    cfg.trigger_profile[1] = (camera_control){"Percentage of Dropped Buffers", 0};
    cfg.trigger_profile[2] = (camera_control){"timestamp_source", 0}; /* 0 end of frame, 1 start of exposure */
    cfg.trigger_profile_count = 3;
    return cfg;
}

static void take(camera *cam, camera_frame *fr)
{
    sci_error err = {0};
    if (camera_wait_frame(cam, FRAME_TIMEOUT_NS, fr, &err) < 0)
        fail_msg("camera_wait_frame: %s", err.msg);
}

/* ---- tests ---- */

/* Found by card name over /dev/video*, identity from VIDIOC_QUERYCAP. */
static void find_by_card(void **state)
{
    (void)state;
    camera_config cfg = camera_config_default();
    cfg.card = VIVID_CARD;
    camera *cam = open_cam(&cfg);
    camera_identity id;
    camera_identity_get(cam, &id);
    assert_string_equal(id.backend, "v4l2");
    assert_string_equal(id.driver, "vivid");
    assert_string_equal(id.card, VIVID_CARD);
    assert_non_null(strstr(id.bus_info, "vivid"));
    assert_string_equal(id.path, g_node);
    assert_true(id.version > 0);
    close_cam(cam);
}

/* Each format: frames of the asked size and depth, sequence rising, timestamps CLOCK_MONOTONIC one frame period
 * apart (times the sequence step). vivid stamps a frame when it fills it: with "Start of Exposure" that is the
 * stamp, with "End of Frame" it adds 0.9 of a period — a moment that may still lie ahead when the buffer is
 * dequeued. Even formats run with end-of-frame stamps, odd ones with start-of-exposure, and the frame must say
 * which (buffer flags V4L2_BUF_FLAG_TSTAMP_SRC_*). */
static void capture_each_format(void **state)
{
    (void)state;
    const int64_t period = 1000000000LL / 30;
    for (int k = 0; k < NFMT; k++) {
        int soe = k & 1;
        camera_config cfg = base_cfg(g_fmts[k]);
        cfg.trigger_profile[2].value = soe;
        cfg.interval_num = 1;
        cfg.interval_den = 30;
        camera *cam = open_cam(&cfg);
        camera_format f;
        camera_format_get(cam, &f);
        assert_int_equal(f.width, W);
        assert_int_equal(f.height, H);
        assert_int_equal(f.pixfmt, g_fmts[k]);
        assert_true(f.bytesperline >= pixfmt_min_stride(g_fmts[k], W));
        assert_int_equal(f.interval_num, 1);
        assert_int_equal(f.interval_den, 30);
        sci_error err = {0};
        int64_t t0 = sci_clock_mono_ns();
        if (camera_start(cam, &err) < 0)
            fail_msg("%s: start: %s", pixfmt_name(g_fmts[k]), err.msg);
        camera_frame fr = {0};
        uint32_t prev_seq = 0;
        int64_t prev_ts = t0;
        for (int i = 0; i < 4; i++) {
            take(cam, &fr);
            int64_t now = sci_clock_mono_ns();
            assert_int_equal(fr.width, W);
            assert_int_equal(fr.height, H);
            assert_int_equal(fr.pixfmt, g_fmts[k]);
            assert_int_equal(fr.bits_per_sample, pixfmt_info_get(g_fmts[k])->bits_per_sample);
            assert_int_equal(fr.ts_source, soe ? CAMERA_TS_SOE : CAMERA_TS_EOF);
            int64_t ahead = soe ? 0 : period; /* vivid's EOF stamp may be up to 0.9 period in the future */
            if (fr.timestamp_ns <= (i ? prev_ts : t0) || fr.timestamp_ns > now + ahead)
                fail_msg("%s frame %d: timestamp %lld ns outside (%lld, %lld] (not CLOCK_MONOTONIC?)",
                         pixfmt_name(g_fmts[k]), i, (long long)fr.timestamp_ns, (long long)(i ? prev_ts : t0),
                         (long long)(now + ahead));
            if (i > 0) {
                assert_true(fr.sequence > prev_seq);
                int64_t per = (fr.timestamp_ns - prev_ts) / (int64_t)(fr.sequence - prev_seq);
                if (per < period / 2 || per > period * 2)
                    fail_msg("%s frame %d: %lld ns per frame, want about %lld", pixfmt_name(g_fmts[k]), i,
                             (long long)per, (long long)period);
            }
            prev_seq = fr.sequence;
            prev_ts = fr.timestamp_ns;
        }
        uint16_t lim = (uint16_t)((1u << fr.bits_per_sample) - 1), mx = 0;
        for (size_t i = 0; i < (size_t)W * H; i++)
            if (fr.data[i] > mx)
                mx = fr.data[i];
        if (mx > lim || mx <= lim / 2)
            fail_msg("%s: brightest sample %u, want (%u, %u] (vivid's white bar)", pixfmt_name(g_fmts[k]), mx,
                     lim / 2, lim);
        g_frames[k] = malloc((size_t)W * H * sizeof(uint16_t));
        memcpy(g_frames[k], fr.data, (size_t)W * H * sizeof(uint16_t));
        camera_stats st;
        camera_stats_get(cam, &st);
        assert_int_equal(st.frames, 4);
        assert_int_equal(st.errors, 0);
        assert_int_equal(camera_stop(cam, &err), 0);
        camera_frame_release(&fr);
        close_cam(cam);
        printf("# %s: %ux%u, bytesperline %u, 4 frames, last sequence %u, max sample %u, %s timestamps\n",
               pixfmt_name(g_fmts[k]), W, H, f.bytesperline, prev_seq, mx, soe ? "start-of-exposure" : "end-of-frame");
    }
}

/* vivid writes the same luma y as GREY y, Y10 y<<2, Y12 y<<4, Y16 y<<8 (low byte 0, or 0xff for white). */
static void formats_agree_pixel_by_pixel(void **state)
{
    (void)state;
    for (int k = 0; k < NFMT; k++)
        if (!g_frames[k])
            skip();
    int levels[256] = {0}, distinct = 0;
    for (size_t i = 0; i < (size_t)W * H; i++) {
        uint16_t y = g_frames[0][i], y10 = g_frames[1][i], y12 = g_frames[2][i], y16 = g_frames[3][i];
        uint16_t lo16 = y == 0xff ? 0xff : 0;
        if (y10 != (uint16_t)(y << 2) || y12 != (uint16_t)(y << 4) || y16 != (uint16_t)((y << 8) | lo16))
            fail_msg("pixel (%zu, %zu): GREY %u, Y10 %u, Y12 %u, Y16 %u do not agree", i % W, i / W, y, y10, y12,
                     y16);
        if (!levels[y]++)
            distinct++;
    }
    printf("# formats agree on all %d pixels, %d grey levels\n", W * H, distinct);
    assert_true(distinct >= 4); /* colour bars, not a flat frame */
}

/* Gain through V4L2_CID_GAIN, read back. Exposure: vivid has no exposure control -> -ENOTSUP naming it. */
static void gain_and_exposure(void **state)
{
    (void)state;
    camera_config cfg = base_cfg(PIXFMT_GREY);
    cfg.gain = 150;
    camera *cam = open_cam(&cfg);
    assert_int_equal(camera_gain(cam), 150);
    sci_error err = {0};
    int32_t g = 37;
    if (camera_set_gain(cam, &g, &err) < 0)
        fail_msg("set_gain: %s", err.msg);
    assert_int_equal(g, 37);
    assert_int_equal(camera_gain(cam), 37);
    /* what the driver holds now, through a second fd */
    int fd = open(g_node, O_RDWR | O_CLOEXEC);
    struct v4l2_control c = {.id = V4L2_CID_GAIN};
    assert_int_equal(ioctl(fd, VIDIOC_G_CTRL, &c), 0);
    close(fd);
    assert_int_equal(c.value, 37);
    uint32_t e = 5000;
    assert_int_equal(camera_set_exposure_us(cam, &e, &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, g_node));
    assert_non_null(strstr(err.msg, "EXPOSURE_ABSOLUTE"));
    printf("# exposure refused as expected: %s\n", err.msg);
    close_cam(cam);
}

/* A control the device lacks fails the open with the control and profile named; nothing stays open. */
static void unknown_profile_control(void **state)
{
    (void)state;
    camera_config cfg = base_cfg(PIXFMT_GREY);
    cfg.trigger_profile_name = "imx296-ext";
    cfg.trigger_profile[0] = (camera_control){"trigger_mode", 1};
    cfg.trigger_profile_count = 1;
    camera *cam = NULL;
    sci_error err = {0};
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -ENOTSUP);
    assert_null(cam);
    assert_non_null(strstr(err.msg, "\"trigger_mode\""));
    assert_non_null(strstr(err.msg, "imx296-ext"));
    /* the node is free again: a new open and stream works */
    cfg = base_cfg(PIXFMT_GREY);
    cam = open_cam(&cfg);
    assert_int_equal(camera_start(cam, &err), 0);
    close_cam(cam); /* close while streaming */
}

/* A second process-level user cannot take the buffers of a streaming camera: -EBUSY. */
static void busy_when_streaming(void **state)
{
    (void)state;
    camera_config cfg = base_cfg(PIXFMT_GREY);
    camera *a = open_cam(&cfg), *b = NULL;
    sci_error err = {0};
    assert_int_equal(camera_start(a, &err), 0);
    camera_frame fr = {0};
    take(a, &fr);
    int rc = camera_open(&b, &camera_v4l2_ops, &cfg, &err);
    if (rc == 0) {
        camera_close(b);
        fail_msg("second open of a streaming node succeeded");
    }
    assert_int_equal(rc, -EBUSY);
    printf("# second user: %s\n", err.msg);
    take(a, &fr); /* the first stream is unharmed */
    camera_frame_release(&fr);
    close_cam(a);
}

/* vivid drops a percentage of buffers; the sequence keeps counting, so the gaps are the drops. */
static void dropped_buffers_counted(void **state)
{
    (void)state;
    camera_config cfg = base_cfg(PIXFMT_GREY);
    cfg.trigger_profile[1].value = 40; /* "Percentage of Dropped Buffers" */
    cfg.interval_num = 1;
    cfg.interval_den = 60;
    camera *cam = open_cam(&cfg);
    sci_error err = {0};
    assert_int_equal(camera_start(cam, &err), 0);
    camera_frame fr = {0};
    uint32_t first = 0, gaps = 0;
    enum { N = 30 };
    for (int i = 0; i < N; i++) {
        take(cam, &fr);
        if (i == 0)
            first = fr.sequence;
        gaps += fr.lost_before;
    }
    camera_stats st;
    camera_stats_get(cam, &st);
    printf("# %d frames delivered, sequence %u..%u, %u lost\n", N, first, fr.sequence, gaps);
    assert_int_equal(st.frames, N);
    assert_int_equal(st.lost, gaps);
    assert_int_equal(fr.lost_total, gaps);
    assert_int_equal(fr.sequence - first + 1, N + gaps); /* every sequence number is a frame or a drop */
    assert_true(gaps >= 3); /* 40 % of ~50 buffers; P(< 3) is negligible */
    close_cam(cam);
    /* back to no drops for the next test */
    cfg = base_cfg(PIXFMT_GREY);
    close_cam(open_cam(&cfg));
}

/* vivid hands one buffer back in the error state: the frame comes with `corrupt` set and is counted. */
static void error_flag_counted(void **state)
{
    (void)state;
    camera_config cfg = base_cfg(PIXFMT_Y10);
    camera *cam = open_cam(&cfg);
    sci_error err = {0};
    assert_int_equal(camera_start(cam, &err), 0);
    camera_frame fr = {0};
    take(cam, &fr);
    assert_false(fr.corrupt);
    ctl_set("Inject V4L2_BUF_FLAG_ERROR", 1);
    int corrupt = 0;
    for (int i = 0; i < 10 && !corrupt; i++) {
        take(cam, &fr);
        corrupt = fr.corrupt;
    }
    assert_true(corrupt);
    take(cam, &fr);
    assert_false(fr.corrupt);
    camera_stats st;
    camera_stats_get(cam, &st);
    assert_int_equal(st.corrupt, 1);
    camera_frame_release(&fr);
    close_cam(cam);
}

/* A fatal streaming error (vb2_queue_error): DQBUF fails with EIO; camera_recover restarts the stream. */
static void fatal_error_and_recover(void **state)
{
    (void)state;
    camera_config cfg = base_cfg(PIXFMT_GREY);
    camera *cam = open_cam(&cfg);
    sci_error err = {0};
    assert_int_equal(camera_start(cam, &err), 0);
    camera_frame fr = {0};
    take(cam, &fr);
    ctl_set("Inject Fatal Streaming Error", 1);
    int rc = 0;
    for (int i = 0; i < 10 && rc == 0; i++)
        rc = camera_wait_frame(cam, FRAME_TIMEOUT_NS, &fr, &err);
    printf("# after a fatal streaming error: %d %s\n", rc, err.msg);
    assert_int_equal(rc, -EIO);
    if (camera_recover(cam, &err) < 0)
        fail_msg("recover: %s", err.msg);
    take(cam, &fr);
    take(cam, &fr);
    camera_stats st;
    camera_stats_get(cam, &st);
    assert_int_equal(st.recoveries, 1);
    camera_frame_release(&fr);
    close_cam(cam);
}

/* vivid's "Disconnect" unregisters the node: the stream fails with -ENODEV; once every fd is closed vivid
 * registers it again, and camera_recover reopens, reapplies and restarts. */
static void disconnect_and_recover(void **state)
{
    (void)state;
    camera_config cfg = base_cfg(PIXFMT_Y12);
    cfg.gain = 90;
    camera *cam = open_cam(&cfg);
    sci_error err = {0};
    assert_int_equal(camera_start(cam, &err), 0);
    camera_frame fr = {0};
    take(cam, &fr);
    ctl_set("Disconnect", 0); /* a button: any value presses it */
    int rc = 0;
    for (int i = 0; i < 10 && rc == 0; i++) /* buffers already filled may still come out */
        rc = camera_wait_frame(cam, FRAME_TIMEOUT_NS, &fr, &err);
    assert_int_equal(rc, -ENODEV);
    assert_non_null(strstr(err.msg, "disconnected"));
    printf("# after disconnect: %s\n", err.msg);
    if ((rc = camera_recover(cam, &err)) < 0)
        fail_msg("recover: %s", err.msg);
    assert_true(camera_is_streaming(cam));
    take(cam, &fr);
    assert_int_equal(fr.pixfmt, PIXFMT_Y12);
    assert_int_equal(fr.width, W);
    assert_int_equal(fr.lost_before, 0); /* the restarted count is not a loss */
    take(cam, &fr);
    camera_stats st;
    camera_stats_get(cam, &st);
    assert_int_equal(st.recoveries, 1);
    assert_true(st.errors >= 1);
    /* gain reapplied on the new fd */
    int fd = open(g_node, O_RDWR | O_CLOEXEC);
    struct v4l2_control c = {.id = V4L2_CID_GAIN};
    assert_int_equal(ioctl(fd, VIDIOC_G_CTRL, &c), 0);
    close(fd);
    assert_int_equal(c.value, 90);
    camera_frame_release(&fr);
    close_cam(cam);
}

/* Find vivid's capture node by card name, without the backend (to compare its answer with). */
static int find_vivid(void)
{
    for (int i = 0; i < 64; i++) {
        char p[32];
        snprintf(p, sizeof p, "/dev/video%d", i);
        int fd = open(p, O_RDWR | O_NONBLOCK | O_CLOEXEC);
        if (fd < 0)
            continue;
        struct v4l2_capability cap = {0};
        int ok = ioctl(fd, VIDIOC_QUERYCAP, &cap) == 0 && strcmp((const char *)cap.driver, "vivid") == 0 &&
                 (cap.device_caps & V4L2_CAP_VIDEO_CAPTURE);
        close(fd);
        if (ok) {
            snprintf(g_node, sizeof g_node, "%s", p);
            return 0;
        }
    }
    return -ENOENT;
}

int main(void)
{
    if (find_vivid() < 0) {
        printf("vm_v4l2: no vivid capture node (modprobe vivid node_types=0x1); skipped\n");
        return 77;
    }
    printf("# vivid capture node: %s\n", g_node);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(find_by_card, teardown),
        cmocka_unit_test_teardown(capture_each_format, teardown),
        cmocka_unit_test_teardown(formats_agree_pixel_by_pixel, teardown),
        cmocka_unit_test_teardown(gain_and_exposure, teardown),
        cmocka_unit_test_teardown(unknown_profile_control, teardown),
        cmocka_unit_test_teardown(busy_when_streaming, teardown),
        cmocka_unit_test_teardown(dropped_buffers_counted, teardown),
        cmocka_unit_test_teardown(error_flag_counted, teardown),
        cmocka_unit_test_teardown(fatal_error_and_recover, teardown),
        cmocka_unit_test_teardown(disconnect_and_recover, teardown),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    for (int k = 0; k < NFMT; k++)
        free(g_frames[k]);
    return rc;
}
