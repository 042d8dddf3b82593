/* The simulated bench end to end (sim/bench.h): scene → DMD (the "sim" DMD behind the bench's wrapper) → the
 * bench's camera, started by the bench's trigger as in host-master sync. Under ideal timing the snapshot is the
 * plain forward model; a wrong mask order, a late DMD and a missed trigger pulse show exactly as they would on
 * hardware; the white target, the dark level and a DMD larger than the camera do what the header says. */
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
#include "sim/bench.h"
#include "sim/dmd_sim.h"
#include "sim/masks.h"
#include "sim/simulate.h"

#define W 64
#define H 48
#define N 8
#define SLOT_US 1000
#define CPU 4000.0   /* counts per unit */
#define DARK 200.0   /* dark level, counts */

typedef struct bench {
    sim_bench *b;
    dmd *inner;        /* the "sim" DMD, attached to the bench */
    sci_cube *mask;    /* the masks meant (camera size) */
    const sci_cube *truth;
    camera_frame fr;
} bench;

/* dmd_w, dmd_h: the DMD's size (≥ the scene's); latency_slots: DMD start after its trigger edge. */
static void bench_open(bench *t, int dmd_w, int dmd_h, int latency_slots)
{
    memset(t, 0, sizeof *t);
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
    sim_bench_options o = sim_bench_options_default();
    if (sim_scene_load_string(&o.scene, "bench.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(sim_masks_make(&o.scene->masks, W, H, N, o.scene->seed, &t->mask, &err), 0);
    o.seed = seed;
    o.dmd_latency_ns = (int64_t)latency_slots * SLOT_US * 1000;
    o.trigger_latency_ns = 0; /* exact edges: the exposure starts with the sequence */
    o.trigger_jitter_ns = 0;
    o.counts_per_unit = CPU;
    o.dark_counts = DARK;
    o.read_noise = 0;
    if (sim_bench_open(&t->b, &o, &err) < 0)
        fail_msg("sim_bench_open: %s", err.msg);
    int w, h;
    sim_bench_size(t->b, &w, &h);
    assert_int_equal(w, W);
    assert_int_equal(h, H);
    assert_non_null(t->truth = sim_bench_truth(t->b, N, &err));

    dmd_config dc = dmd_config_default();
    dc.width = dmd_w;
    dc.height = dmd_h;
    if (dmd_open(&t->inner, &dmd_sim_ops, &dc, &err) < 0)
        fail_msg("dmd_open: %s", err.msg);
    sim_bench_attach_dmd(t->b, t->inner);
    camera *cam = sim_bench_camera(t->b);
    uint32_t e = N * SLOT_US; /* the whole sequence, nothing more */
    assert_int_equal(camera_set_exposure_us(cam, &e, &err), 0);
    assert_int_equal(e, N * SLOT_US);
}

static void bench_close(bench *t)
{
    camera_frame_release(&t->fr);
    sim_bench_attach_dmd(t->b, NULL);
    dmd_close(t->inner);
    sim_bench_close(t->b);
    sci_cube_free(t->mask);
}

/* masks (DMD size) onto the DMD, armed for its trigger input, one pulse, one frame. */
static int shoot(bench *t, const sci_cube *masks, int64_t timeout_ns, sci_error *err)
{
    dmd *d = sim_bench_dmd(t->b);
    dmd_timing tm = {.exposure_us = SLOT_US, .dark_us = 0, .trigger = DMD_TRIGGER_EXTERNAL, .passes = 1};
    if (dmd_upload(d, masks, err) < 0 || dmd_set_timing(d, &tm, err) < 0 || dmd_start(d, err) < 0)
        fail_msg("dmd: %s", err->msg);
    int64_t t_ns;
    if (trigger_pulse(sim_bench_trigger(t->b), 10, &t_ns, err) < 0)
        fail_msg("trigger_pulse: %s", err->msg);
    camera_frame_release(&t->fr);
    int rc = camera_wait_frame(sim_bench_camera(t->b), timeout_ns, &t->fr, err);
    sci_error e2 = {0};
    dmd_stop(d, &e2);
    return rc;
}

/* Largest |snapshot − y| before counts, and largest |counts − (dark + CPU·y)|. */
static double compare(const bench *t, const sci_cube *y, double *worst_counts)
{
    const float *last = sim_bench_last(t->b);
    assert_non_null(last);
    assert_int_equal(t->fr.width, W);
    assert_int_equal(t->fr.height, H);
    double worst = 0, wc = 0;
    for (int i = 0; i < W * H; i++) {
        worst = fmax(worst, fabs((double)last[i] - y->data[i]));
        wc = fmax(wc, fabs(t->fr.data[i] - (DARK + CPU * y->data[i])));
    }
    *worst_counts = wc;
    return worst;
}

static void test_ideal_timing_is_the_forward_model(void **state)
{
    bench t;
    bench_open(&t, W, H, 0);
    sci_error err = {0};
    assert_null(sim_bench_last(t.b));
    if (shoot(&t, t.mask, 2000000000LL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube *y;
    assert_int_equal(sci_cube_new(&y, W, H, 1, NULL), 0);
    sci_op_forward(t.mask, t.truth, y);
    double wc, d = compare(&t, y, &wc);
    printf("ideal timing: max |snapshot − A(mask, truth)| = %g; counts within %.3f of %g + %g·y\n", d, wc, DARK,
           CPU);
    assert_true(d < 1e-6);
    assert_true(wc <= 0.5);
    sci_cube_free(y);
    bench_close(&t);
}

static void test_wrong_mask_order_shows(void **state)
{
    bench t;
    bench_open(&t, W, H, 0);
    sci_error err = {0};
    sci_cube *y, *rev;
    assert_int_equal(sci_cube_new(&y, W, H, 1, NULL), 0);
    assert_int_equal(sci_cube_clone(&rev, t.mask, NULL), 0);
    for (int k = 0; k < N; k++) /* the operator's slip: masks uploaded in the wrong order */
        memcpy(sci_cube_frame(rev, k), sci_cube_frame(t.mask, N - 1 - k), sizeof(float) * W * H);
    if (shoot(&t, rev, 2000000000LL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_op_forward(t.mask, t.truth, y);
    double wc, d = compare(&t, y, &wc);
    printf("reversed upload: differs from the intended model by up to %g\n", d);
    assert_true(d > 0.5);
    sci_op_forward(rev, t.truth, y); /* ... and is the model of the masks actually shown */
    d = compare(&t, y, &wc);
    assert_true(d < 1e-6);
    sci_cube_free(rev);
    sci_cube_free(y);
    bench_close(&t);
}

static void test_late_dmd_and_missed_trigger_show(void **state)
{
    bench t;
    /* The DMD starts one slot after the edge that starts the exposure: the exposure ends before the last mask. */
    bench_open(&t, W, H, 1);
    sci_error err = {0};
    if (shoot(&t, t.mask, 2000000000LL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube *y, *m;
    assert_int_equal(sci_cube_new(&y, W, H, 1, NULL), 0);
    assert_int_equal(sci_cube_clone(&m, t.mask, NULL), 0);
    memset(sci_cube_frame(m, N - 1), 0, sizeof(float) * W * H);
    sci_op_forward(m, t.truth, y);
    double wc, d = compare(&t, y, &wc);
    printf("DMD late by one slot: equals the model without mask %d (max diff %g)\n", N - 1, d);
    assert_true(d < 1e-6);
    /* A lost trigger pulse: the camera never exposes and the wait times out. */
    sim_bench_trigger_miss(t.b, 1);
    int rc = shoot(&t, t.mask, 300000000LL, &err);
    printf("missed trigger: %s\n", err.msg);
    assert_int_equal(rc, -ETIMEDOUT);
    sci_cube_free(m);
    sci_cube_free(y);
    bench_close(&t);
}

static void test_white_target_and_larger_dmd(void **state)
{
    /* A DMD 16 mirrors wider and 8 taller: the camera sees its central W×H window. */
    bench t;
    const int dw = W + 16, dh = H + 8;
    bench_open(&t, dw, dh, 0);
    sci_error err = {0};
    sci_cube *big, *seen, *ones, *y;
    assert_int_equal(sci_cube_new(&big, dw, dh, N, NULL), 0);
    for (size_t i = 0; i < sci_cube_count(big); i++)
        big->data[i] = (float)((i * 2654435761u >> 7) & 1); /* masks outside the window must not count */
    for (int k = 0; k < N; k++)
        for (int r = 0; r < H; r++)
            memcpy(sci_cube_frame(big, k) + (size_t)(r + 4) * dw + 8, sci_cube_frame(t.mask, k) + (size_t)r * W,
                   sizeof(float) * W);
    assert_int_equal(sim_bench_crop(t.b, big, &seen, &err), 0);
    assert_memory_equal(seen->data, t.mask->data, sizeof(float) * sci_cube_count(t.mask));
    sim_bench_set_target(t.b, SIM_BENCH_TARGET_WHITE);
    if (shoot(&t, big, 2000000000LL, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(sci_cube_new(&ones, W, H, N, NULL), 0);
    for (size_t i = 0; i < sci_cube_count(ones); i++)
        ones->data[i] = 1;
    assert_int_equal(sci_cube_new(&y, W, H, 1, NULL), 0);
    sci_op_forward(t.mask, ones, y); /* on white: how many masks open each pixel */
    double wc, d = compare(&t, y, &wc);
    printf("white target through a %d×%d DMD: max diff %g, counts within %.3f\n", dw, dh, d, wc);
    assert_true(d < 1e-6);
    assert_true(wc <= 0.5);
    /* a DMD smaller than the camera is refused */
    sci_cube *small;
    assert_int_equal(sci_cube_new(&small, W - 1, H, 1, NULL), 0);
    assert_int_equal(sim_bench_crop(t.b, small, &seen, &err), SCI_ESHAPE);
    printf("smaller masks: %s\n", err.msg);
    sci_cube_free(small);
    sci_cube_free(y);
    sci_cube_free(ones);
    sci_cube_free(seen);
    sci_cube_free(big);
    bench_close(&t);
}

/* sim_bench_snapshot (what `scicap sim --bench` runs): the daemon's latencies and trigger jitter, snapshot 1 of
 * the scene; the measurement is the forward model of frames N … 2N − 1 to within the rounding to counts. */
static void test_snapshot_with_latencies(void **state)
{
    bench t;
    bench_open(&t, W, H, 0);
    sim_bench_close(t.b); /* again with the daemon's timing */
    sci_error err = {0};
    sim_bench_options o = sim_bench_options_default();
    assert_true(o.dmd_latency_ns > 0 && o.trigger_jitter_ns > 0);
    o.scene_path = NULL; /* the embedded default scene */
    o.read_noise = 0;
    if (sim_bench_open(&t.b, &o, &err) < 0)
        fail_msg("%s", err.msg);
    int w, h;
    sim_bench_size(t.b, &w, &h);
    dmd_close(t.inner);
    dmd_config dc = dmd_config_default();
    dc.width = w;
    dc.height = h;
    assert_int_equal(dmd_open(&t.inner, &dmd_sim_ops, &dc, &err), 0);
    sci_cube *mask, *y, *meas, *truth0;
    sim_mask_spec spec = {.kind = SIM_MASK_RANDOM, .density = 0.5, .block = 1, .step = 1, .dmd_w = w, .dmd_h = h,
                          .scale = 1};
    assert_int_equal(sim_masks_make(&spec, w, h, N, 3, &mask, &err), 0);
    assert_int_equal(sci_cube_new(&y, w, h, 1, NULL), 0);
    assert_int_equal(sci_cube_new(&meas, w, h, 1, NULL), 0);
    assert_int_equal(sim_bench_snapshot(t.b, mask, SLOT_US, meas, &err), -ENODEV); /* no DMD yet */
    sim_bench_attach_dmd(t.b, t.inner);
    assert_int_equal(sci_cube_clone(&truth0, sim_bench_truth(t.b, N, &err), NULL), 0);
    sim_bench_set_snapshot(t.b, 1);
    if (sim_bench_snapshot(t.b, mask, SLOT_US, meas, &err) < 0)
        fail_msg("%s", err.msg);
    const sci_cube *truth1 = sim_bench_truth(t.b, N, &err);
    assert_non_null(truth1);
    double moved = 0, worst = 0;
    for (size_t i = 0; i < sci_cube_count(truth0); i++)
        moved = fmax(moved, fabs(truth0->data[i] - truth1->data[i]));
    sci_op_forward(mask, truth1, y);
    for (int i = 0; i < w * h; i++)
        worst = fmax(worst, fabs(meas->data[i] - y->data[i]));
    printf("snapshot 1 with %.0f µs DMD latency: max |meas − A(mask, truth_1)| = %.3g (half a count: %.3g); the "
           "scene moved by up to %.3g since snapshot 0\n",
           o.dmd_latency_ns / 1e3, worst, 0.5 / o.counts_per_unit, moved);
    assert_true(moved > 0.1); /* the check below can tell snapshot 1 from snapshot 0 */
    assert_true(worst <= 0.5 / o.counts_per_unit + 1e-6);
    sci_cube_free(truth0);
    sci_cube_free(meas);
    sci_cube_free(y);
    sci_cube_free(mask);
    bench_close(&t);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ideal_timing_is_the_forward_model),
        cmocka_unit_test(test_wrong_mask_order_shows),
        cmocka_unit_test(test_late_dmd_and_missed_trigger_show),
        cmocka_unit_test(test_white_target_and_larger_dmd),
        cmocka_unit_test(test_snapshot_with_latencies),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
