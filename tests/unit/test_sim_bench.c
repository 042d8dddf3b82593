/* The simulated bench end to end: scene → simulated DMD (dmd_sim) → simulated camera (camera_sim) through the
 * scene frame source (sim/bench_source.h). Under ideal timing the snapshot is the plain forward model; a wrong
 * mask order, a late trigger or a missed trigger shows exactly as it would on hardware. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "recon/sci_ops.h"
#include "sim/bench_source.h"
#include "sim/dmd_sim.h"
#include "sim/simulate.h"

#define W 64
#define H 48
#define N 8
#define SLOT_US 1000

typedef struct bench {
    sim_scene *scene;
    sci_cube *mask, *truth;
    dmd *dev;
    camera *cam;
    camera_sim *cs;
    sim_bench_source *src;
    camera_sim_options co; /* must outlive camera_open */
    camera_frame fr;
} bench;

static void bench_open(bench *b, int reversed)
{
    memset(b, 0, sizeof *b);
    const char *s = getenv("SCICAP_TEST_SEED");
    unsigned long long seed = s ? strtoull(s, NULL, 0) : 5;
    printf("seed %llu (set SCICAP_TEST_SEED to change)\n", seed);
    char text[1024];
    snprintf(text, sizeof text,
             "{\"kind\": \"video2d\", \"width\": %d, \"height\": %d, \"frames\": %d, \"seed\": %llu,"
             " \"layers\": [{\"texture\": {\"type\": \"noise\", \"cell\": 10}},"
             " {\"shape\": \"disc\", \"size\": [16, 16], \"position\": [12, 20], \"velocity\": [5, 0],"
             "  \"texture\": {\"type\": \"constant\", \"value\": 1}}]}",
             W, H, N, seed);
    sci_error err = {0};
    if (sim_scene_load_string(&b->scene, "bench.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(sim_masks_make(&b->scene->masks, W, H, N, b->scene->seed, &b->mask, &err), 0);
    assert_int_equal(sci_cube_new(&b->truth, W, H, N, &err), 0);
    assert_int_equal(sim_render_truth(b->scene, 0, b->truth, &err), 0);

    dmd_config dc = dmd_config_default();
    dc.width = W;
    dc.height = H;
    if (dmd_open(&b->dev, &dmd_sim_ops, &dc, &err) < 0)
        fail_msg("dmd_open: %s", err.msg);
    sci_cube *up = b->mask;
    if (reversed) { /* the operator's slip: masks uploaded in the wrong order */
        assert_int_equal(sci_cube_clone(&up, b->mask, &err), 0);
        for (int k = 0; k < N; k++)
            memcpy(sci_cube_frame(up, k), sci_cube_frame(b->mask, N - 1 - k), sizeof(float) * W * H);
    }
    if (dmd_upload(b->dev, up, &err) < 0)
        fail_msg("dmd_upload: %s", err.msg);
    if (up != b->mask)
        sci_cube_free(up);
    dmd_timing t = {.exposure_us = SLOT_US, .dark_us = 0, .trigger = DMD_TRIGGER_INTERNAL, .passes = 1};
    if (dmd_set_timing(b->dev, &t, &err) < 0)
        fail_msg("dmd_set_timing: %s", err.msg);

    sim_bench_source_options so = {.slot_ns = SLOT_US * 1000LL, .steps_per_slot = 8, .counts_white = 4000};
    assert_int_equal(sim_bench_source_new(&b->src, b->scene, b->dev, &so, &err), 0);
    b->co = (camera_sim_options){.trigger_latency_ns = 0, .source = sim_bench_source_fill, .source_arg = b->src};
    camera_config cc = camera_config_default();
    cc.width = W;
    cc.height = H;
    cc.pixfmt = PIXFMT_Y16;
    cc.exposure_us = N * SLOT_US;
    cc.gain = 100;
    cc.trigger_profile[0] = (camera_control){.name = "trigger_mode", .value = 1};
    cc.trigger_profile_count = 1;
    cc.backend_options = &b->co;
    if (camera_open(&b->cam, &camera_sim_ops, &cc, &err) < 0)
        fail_msg("camera_open: %s", err.msg);
    b->cs = camera_sim_from(b->cam);
    assert_non_null(b->cs);
    assert_int_equal(camera_start(b->cam, &err), 0);
}

static void bench_close(bench *b)
{
    camera_frame_release(&b->fr);
    camera_close(b->cam);
    dmd_close(b->dev);
    sim_bench_source_free(b->src);
    sci_cube_free(b->mask);
    sci_cube_free(b->truth);
    sim_scene_free(b->scene);
}

/* Start the DMD sequence and trigger the camera `delay_slots` pattern slots after it. */
static int shoot(bench *b, int delay_slots, int64_t timeout_ns, sci_error *err)
{
    if (dmd_start(b->dev, err) < 0)
        fail_msg("dmd_start: %s", err->msg);
    int64_t t0 = dmd_sim_started_ns(b->dev);
    assert_true(t0 > 0);
    camera_sim_trigger(b->cs, t0 + (int64_t)delay_slots * SLOT_US * 1000);
    return camera_wait_frame(b->cam, timeout_ns, &b->fr, err);
}

static double compare(const bench *b, const sci_cube *y, double *worst_counts)
{
    const float *last = sim_bench_source_last(b->src);
    assert_non_null(last);
    double worst = 0, wc = 0;
    for (int i = 0; i < W * H; i++) {
        worst = fmax(worst, fabs((double)last[i] - y->data[i]));
        wc = fmax(wc, fabs(b->fr.data[i] - 4000.0 * y->data[i]));
    }
    *worst_counts = wc;
    return worst;
}

static void test_ideal_timing_is_the_forward_model(void **state)
{
    bench b;
    bench_open(&b, 0);
    sci_error err = {0};
    if (shoot(&b, 0, 2000000000LL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube *y;
    assert_int_equal(sci_cube_new(&y, W, H, 1, NULL), 0);
    sci_op_forward(b.mask, b.truth, y);
    double wc, d = compare(&b, y, &wc);
    printf("ideal timing: max |snapshot − A(mask, truth)| = %g; counts within %.3f of 4000·y\n", d, wc);
    assert_true(d == 0);
    assert_true(wc <= 0.5);
    sci_cube_free(y);
    bench_close(&b);
}

static void test_wrong_mask_order_shows(void **state)
{
    bench b;
    bench_open(&b, 1);
    sci_error err = {0};
    if (shoot(&b, 0, 2000000000LL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube *y, *rev;
    assert_int_equal(sci_cube_new(&y, W, H, 1, NULL), 0);
    assert_int_equal(sci_cube_clone(&rev, b.mask, NULL), 0);
    for (int k = 0; k < N; k++)
        memcpy(sci_cube_frame(rev, k), sci_cube_frame(b.mask, N - 1 - k), sizeof(float) * W * H);
    sci_op_forward(b.mask, b.truth, y);
    double wc, d = compare(&b, y, &wc);
    printf("reversed upload: differs from the intended model by up to %g\n", d);
    assert_true(d > 0.5);
    sci_op_forward(rev, b.truth, y); /* ... and is the model of the masks actually shown */
    d = compare(&b, y, &wc);
    assert_true(d == 0);
    sci_cube_free(rev);
    sci_cube_free(y);
    bench_close(&b);
}

static void test_late_and_missed_trigger_show(void **state)
{
    bench b;
    bench_open(&b, 0);
    sci_error err = {0};
    /* One slot late: the exposure misses mask 0 and, after the sequence ends, sees a dark DMD. */
    if (shoot(&b, 1, 2000000000LL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube *y, *m;
    assert_int_equal(sci_cube_new(&y, W, H, 1, NULL), 0);
    assert_int_equal(sci_cube_clone(&m, b.mask, NULL), 0);
    memset(sci_cube_frame(m, 0), 0, sizeof(float) * W * H);
    sci_op_forward(m, b.truth, y);
    double wc, d = compare(&b, y, &wc);
    printf("late by one slot: equals the model without mask 0 (max diff %g)\n", d);
    assert_true(d == 0);
    /* Missed trigger: the camera never exposes and the wait times out. */
    camera_sim_fault(b.cs, CAMERA_SIM_FAULT_STALL, 1);
    dmd_stop(b.dev, &err);
    int rc = shoot(&b, 0, 300000000LL, &err);
    printf("missed trigger: %s\n", err.msg);
    assert_int_equal(rc, -ETIMEDOUT);
    sci_cube_free(m);
    sci_cube_free(y);
    bench_close(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ideal_timing_is_the_forward_model),
        cmocka_unit_test(test_wrong_mask_order_shows),
        cmocka_unit_test(test_late_and_missed_trigger_show),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
