/* The simulated camera through the camera interface: format negotiation, free-run timing, drops (including across
 * the 32-bit sequence wrap), ring overflow, timeouts, stalls, corrupt frames, disconnect and recovery, and
 * bit-exact delivery of a frame source through every wire format. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include <errno.h>
#include <time.h>

#include "base/clock.h"
#include "base/rng.h"
#include "sim/camera_sim.h"

static uint64_t g_seed;

static camera *open_sim(camera_config *cfg, camera_sim_options *opt)
{
    cfg->backend_options = opt;
    camera *cam = NULL;
    sci_error err = {0};
    int rc = camera_open(&cam, &camera_sim_ops, cfg, &err);
    if (rc < 0)
        fail_msg("camera_open: %s", err.msg);
    return cam;
}

/* open_sim, streaming. */
static camera *start_sim(camera_config *cfg, camera_sim_options *opt)
{
    camera *cam = open_sim(cfg, opt);
    sci_error err = {0};
    if (camera_start(cam, &err) < 0)
        fail_msg("camera_start: %s", err.msg);
    return cam;
}

static camera_stats stats_of(camera *cam)
{
    camera_stats st;
    camera_stats_get(cam, &st);
    return st;
}

/* The last frame handed back, then the camera closed. */
static void finish(camera *cam, camera_frame *fr)
{
    camera_frame_release(fr);
    camera_close(cam);
}

/* The defaults at w×h pixels: most tests want a small frame. */
static camera_config sized_config(int w, int h)
{
    camera_config cfg = camera_config_default();
    cfg.width = w;
    cfg.height = h;
    return cfg;
}

static void negotiation(void **state)
{
    (void)state;
    camera_sim_options opt = {0};
    camera_config cfg = camera_config_default();
    camera *cam = open_sim(&cfg, &opt);
    camera_format f;
    camera_format_get(cam, &f);
    assert_int_equal(f.pixfmt, PIXFMT_Y16); /* nothing asked: the most bits */
    assert_int_equal(f.bits_per_sample, 16);
    sci_error err = {0};
    camera_config want = camera_config_default();
    want.pixfmt = PIXFMT_Y10P;
    want.width = 1001;
    want.height = 17;
    assert_int_equal(camera_set_format(cam, &want, &err), 0);
    camera_format_get(cam, &f);
    assert_int_equal(f.width, 1001);
    assert_int_equal(f.bits_per_sample, 10);
    assert_true(f.bytesperline >= pixfmt_min_stride(PIXFMT_Y10P, 1001));
    assert_int_equal(f.bytesperline % 32, 0);
    want.width = 5000;
    assert_int_equal(camera_set_format(cam, &want, &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, "5000x17 is not offered"));
    camera_close(cam);

    /* a device that offers only GREY refuses Y16, naming both */
    enum pixfmt only_grey[] = {PIXFMT_GREY};
    opt.formats = only_grey;
    opt.format_count = 1;
    cfg.pixfmt = PIXFMT_Y16;
    cfg.backend_options = &opt;
    camera *c2 = NULL;
    assert_int_equal(camera_open(&c2, &camera_sim_ops, &cfg, &err), -ENOTSUP);
    assert_null(c2);
    assert_non_null(strstr(err.msg, "does not offer format Y16; it offers GREY"));

    /* a trigger profile naming a control the device lacks */
    cfg = camera_config_default();
    cfg.trigger_profile_name = "imx296-ext";
    cfg.trigger_profile[0] = (camera_control){.name = "Trigger Source", .value = 3};
    cfg.trigger_profile_count = 1;
    cfg.backend_options = &(camera_sim_options){0};
    assert_int_equal(camera_open(&c2, &camera_sim_ops, &cfg, &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, "\"Trigger Source\""));
    assert_non_null(strstr(err.msg, "imx296-ext"));
}

static void free_run_timing_and_drops(void **state)
{
    (void)state;
    camera_sim_options opt = {.readout_ns = 100000};
    camera_config cfg = sized_config(64, 48);
    cfg.interval_num = 1;
    cfg.interval_den = 500; /* 2 ms period */
    cfg.exposure_us = 1000;
    cfg.buffer_count = CAMERA_MAX_BUFFERS; /* 64 ms of slack: a loaded test machine must not overflow the ring */
    camera *cam = start_sim(&cfg, &opt);
    camera_sim *cs = camera_sim_from(cam);
    assert_non_null(cs);
    sci_error err = {0};
    camera_frame fr = {0};
    int64_t prev_ts = 0;
    uint32_t prev_seq = 0;
    /* The drop applies to the frames the camera makes after the fault; on a loaded machine the reader may be
     * several frames behind (they wait in the ring), so it sees the gap some frames later: read until it has,
     * and at least 10 frames. Every other step is one frame. */
    int frames = 0, gap_at = -1;
    for (int i = 0; i < 10 || (gap_at < 0 && i < 2 * CAMERA_MAX_BUFFERS); i++) {
        if (i == 4)
            camera_sim_fault(cs, CAMERA_SIM_FAULT_DROP, 2);
        assert_int_equal(camera_wait_frame(cam, 100000000, &fr, &err), 0);
        frames++;
        assert_int_equal(fr.exposure_us, 1000);
        assert_int_equal(fr.ts_source, CAMERA_TS_EOF);
        if (i > 0) {
            uint32_t step = fr.sequence - prev_seq;
            assert_int_equal(fr.lost_before, step - 1);
            assert_int_equal(fr.timestamp_ns - prev_ts, (int64_t)step * 2000000); /* exact: the schedule is arithmetic */
            if (step != 1) {
                assert_int_equal(step, 3);
                assert_int_equal(gap_at, -1); /* one gap only */
                assert_true(i >= 4);          /* not before the fault */
                gap_at = i;
            }
        }
        prev_ts = fr.timestamp_ns;
        prev_seq = fr.sequence;
    }
    assert_true(gap_at >= 4);
    camera_stats st = stats_of(cam);
    assert_int_equal(st.frames, frames);
    assert_int_equal(st.lost, 2);
    assert_int_equal(fr.lost_total, 2);
    finish(cam, &fr);
}

static void drops_across_sequence_wrap(void **state)
{
    (void)state;
    camera_sim_options opt = {.first_sequence = 0xFFFFFFFDu, .unpaced = 1};
    camera_config cfg = sized_config(32, 8);
    camera *cam = start_sim(&cfg, &opt);
    camera_sim *cs = camera_sim_from(cam);
    sci_error err = {0};
    camera_frame fr = {0};
    assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), 0);
    assert_int_equal(fr.sequence, 0xFFFFFFFDu);
    camera_sim_fault(cs, CAMERA_SIM_FAULT_DROP, 3); /* FE, FF and 0 are lost */
    assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), 0);
    assert_int_equal(fr.sequence, 1u);
    assert_int_equal(fr.lost_before, 3);
    assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), 0);
    assert_int_equal(fr.sequence, 2u);
    assert_int_equal(fr.lost_before, 0);
    assert_int_equal(fr.lost_total, 3);
    finish(cam, &fr);
}

static void ring_overflow_counts_losses(void **state)
{
    (void)state;
    camera_sim_options opt = {0};
    camera_config cfg = sized_config(32, 8);
    cfg.interval_num = 1;
    cfg.interval_den = 1000;
    cfg.exposure_us = 100;
    cfg.buffer_count = 2;
    camera *cam = start_sim(&cfg, &opt);
    sci_error err = {0};
    camera_frame fr = {0};
    struct timespec ts = {0, 30 * 1000000}; /* 30 frames' time with only 2 buffers */
    nanosleep(&ts, NULL);
    assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), 0);
    assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), 0);
    assert_int_equal(camera_wait_frame(cam, 100000000, &fr, &err), 0);
    camera_sim_counters c;
    camera_sim_counters_get(camera_sim_from(cam), &c);
    assert_true(c.dropped >= 20);
    /* the third frame comes after the gap (later frames may have overflowed again since, on a loaded machine) */
    assert_true(fr.lost_before >= 20 && fr.lost_before <= c.dropped);
    finish(cam, &fr);
}

static void timeouts_stalls_and_corrupt_frames(void **state)
{
    (void)state;
    camera_sim_options opt = {.trigger_latency_ns = 5000};
    camera_config cfg = sized_config(32, 8);
    cfg.exposure_us = 500;
    cfg.trigger_profile[0] = (camera_control){.name = "trigger_mode", .value = 1};
    cfg.trigger_profile_count = 1;
    camera *cam = start_sim(&cfg, &opt);
    camera_sim *cs = camera_sim_from(cam);
    sci_error err = {0};
    camera_frame fr = {0};
    /* no trigger, no frame */
    int64_t t0 = sci_clock_mono_ns();
    assert_int_equal(camera_wait_frame(cam, 20000000, &fr, &err), -ETIMEDOUT);
    assert_true(sci_clock_mono_ns() - t0 >= 20000000);
    assert_non_null(strstr(err.msg, "no frame within 20.000 ms"));
    /* a trigger gives one frame, exposed from trigger + latency */
    int64_t t = sci_clock_mono_ns();
    assert_int_equal(camera_sim_trigger(cs, t), 1);
    assert_int_equal(camera_sim_trigger(cs, t + 1000), 0); /* busy exposing: ignored */
    assert_int_equal(camera_wait_frame(cam, 100000000, &fr, &err), 0);
    assert_int_equal(fr.timestamp_ns, t + 5000 + 500000);
    /* a stalled exposure (the camera missed the trigger) times out */
    camera_sim_fault(cs, CAMERA_SIM_FAULT_STALL, 1);
    assert_int_equal(camera_sim_trigger(cs, sci_clock_mono_ns()), 0);
    assert_int_equal(camera_wait_frame(cam, 10000000, &fr, &err), -ETIMEDOUT);
    /* corrupt flag */
    camera_sim_fault(cs, CAMERA_SIM_FAULT_CORRUPT, 1);
    assert_int_equal(camera_sim_trigger(cs, sci_clock_mono_ns()), 1);
    assert_int_equal(camera_wait_frame(cam, 100000000, &fr, &err), 0);
    assert_true(fr.corrupt);
    camera_stats st = stats_of(cam);
    assert_int_equal(st.timeouts, 2);
    assert_int_equal(st.corrupt, 1);
    assert_int_equal(st.frames, 2);
    finish(cam, &fr);
}

static void disconnect_and_recover(void **state)
{
    (void)state;
    camera_sim_options opt = {.unpaced = 1};
    camera_config cfg = sized_config(32, 8);
    cfg.device = "/dev/sim-cam7";
    camera *cam = start_sim(&cfg, &opt);
    camera_sim *cs = camera_sim_from(cam);
    sci_error err = {0};
    camera_frame fr = {0};
    assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), 0);
    camera_sim_fault(cs, CAMERA_SIM_FAULT_DISCONNECT, 0);
    assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), -ENODEV);
    assert_non_null(strstr(err.msg, "/dev/sim-cam7"));
    assert_int_equal(camera_recover(cam, &err), -ENODEV);
    assert_non_null(strstr(err.msg, "still disconnected"));
    camera_sim_replug(cs);
    assert_int_equal(camera_recover(cam, &err), 0);
    assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), 0);
    assert_int_equal(fr.lost_before, 0); /* the count restarted with the stream; no false gap */
    camera_stats st = stats_of(cam);
    assert_int_equal(st.recoveries, 1);
    assert_int_equal(st.errors, 1);
    finish(cam, &fr);
}

/* A source whose samples depend on the sequence and position: checks that what the source made is what the
 * caller gets, bit for bit, through the packing and unpacking of every wire format. */
static int seeded_source(void *arg, const camera_sim_exposure *e, uint16_t *px, uint32_t w, uint32_t h, int bits,
                         sci_error *err)
{
    (void)err;
    sci_rng rng;
    sci_rng_seed(&rng, *(uint64_t *)arg, e->sequence);
    for (size_t i = 0; i < (size_t)w * h; i++)
        px[i] = (uint16_t)sci_rng_below(&rng, 1u << bits);
    return 0;
}

static void frame_source_is_delivered_bit_exact(void **state)
{
    (void)state;
    for (int f = PIXFMT_GREY; f < PIXFMT_COUNT; f++) {
        uint64_t seed = g_seed;
        camera_sim_options opt = {.unpaced = 1, .source = seeded_source, .source_arg = &seed};
        camera_config cfg = sized_config(37, 5); /* not a multiple of 4: the last Y10P group is partial */
        cfg.pixfmt = (enum pixfmt)f;
        camera *cam = start_sim(&cfg, &opt);
        sci_error err = {0};
        camera_frame fr = {0};
        for (int k = 0; k < 3; k++) {
            assert_int_equal(camera_wait_frame(cam, 0, &fr, &err), 0);
            assert_int_equal(fr.bits_per_sample, pixfmt_info_get((enum pixfmt)f)->bits_per_sample);
            uint16_t want[37 * 5];
            camera_sim_exposure e = {.sequence = fr.sequence};
            seeded_source(&seed, &e, want, 37, 5, fr.bits_per_sample, NULL);
            assert_memory_equal(fr.data, want, sizeof want);
        }
        camera_frame_release(&fr);
        camera_close(cam);
    }
}

static void config_from_json(void **state)
{
    (void)state;
    json_error_t je;
    json_t *j = json_loads("{\"device\": \"/dev/video3\", \"width\": 1920, \"height\": 1080, \"format\": \"Y10P\","
                           " \"fps\": 60, \"exposure_us\": 5000, \"gain\": 4, \"buffers\": 6,"
                           " \"trigger_profile\": {\"name\": \"imx477\", \"controls\": {\"trigger_mode\": 1}}}", 0, &je);
    assert_non_null(j);
    camera_config c;
    sci_error err = {0};
    assert_int_equal(camera_config_from_json(j, "camera", &c, &err), 0);
    assert_string_equal(c.device, "/dev/video3");
    assert_int_equal(c.pixfmt, PIXFMT_Y10P);
    assert_int_equal(c.interval_den, 60);
    assert_int_equal(c.trigger_profile_count, 1);
    assert_string_equal(c.trigger_profile[0].name, "trigger_mode");
    json_decref(j);
    j = json_loads("{\"device\": \"/dev/video3\", \"format\": \"MJPG\"}", 0, &je);
    assert_int_equal(camera_config_from_json(j, "camera", &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "camera.format: \"MJPG\""));
    json_decref(j);
    j = json_loads("{\"device\": \"/dev/video3\", \"exposure\": 5}", 0, &je);
    assert_int_equal(camera_config_from_json(j, "camera", &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "camera.exposure: unknown key"));
    json_decref(j);
}

int main(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    g_seed = s ? strtoull(s, NULL, 0) : 5u;
    printf("test_camera_sim: seed %llu (set SCICAP_TEST_SEED to change)\n", (unsigned long long)g_seed);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(negotiation),
        cmocka_unit_test(free_run_timing_and_drops),
        cmocka_unit_test(drops_across_sequence_wrap),
        cmocka_unit_test(ring_overflow_counts_losses),
        cmocka_unit_test(timeouts_stalls_and_corrupt_frames),
        cmocka_unit_test(disconnect_and_recover),
        cmocka_unit_test(frame_source_is_delivered_bit_exact),
        cmocka_unit_test(config_from_json),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
