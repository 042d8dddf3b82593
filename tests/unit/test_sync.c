/* The sync report: which masks fell inside the exposure, partial overlaps, timing error, and the flags that mark
 * a snapshot broken (missed DMD trigger, missing or extra edges, jitter, offset, no frame). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include <errno.h>

#include "base/rng.h"
#include "drivers/sync.h"

#define T0 1000000000LL /* 1 s: an arbitrary CLOCK_MONOTONIC origin */
static uint64_t g_seed;
static sync_timeline g_tl;
static sync_report g_rep;

/* 8 patterns of 1000 µs with 100 µs dark, starting 100 µs into a 9 ms exposure. */
static void plan8(void) { assert_int_equal(sync_timeline_uniform(&g_tl, T0 + 100000, 8, 1000, 100, NULL), 0); }

static void edges_at_plan(int64_t *e, int64_t offset)
{
    for (int i = 0; i < g_tl.count; i++)
        e[i] = sync_timeline_pattern_start_ns(&g_tl, i) + offset;
}

/* The 8-pattern plan observed through edges e (n of them, `offset` ns after the plan) within an exposure of 9 ms from
 * T0, measured or not; the report lands in g_rep. Returns the observation for a second look. */
static sync_observation observe_plan8(int64_t e[8], int n, int64_t offset, int measured)
{
    plan8();
    edges_at_plan(e, offset);
    sync_observation obs = {.dmd_edges_ns = e, .dmd_edge_count = n, .exposure_start_ns = T0,
                            .exposure_end_ns = T0 + 9000000, .exposure_measured = measured};
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, NULL), 0);
    return obs;
}

static void perfect_sync(void **state)
{
    (void)state;
    int64_t e[8];
    observe_plan8(e, 8, 0, 1);
    assert_int_equal(g_rep.inside, 8);
    assert_int_equal(g_rep.partial + g_rep.outside, 0);
    assert_int_equal(g_rep.edges_matched, 8);
    assert_int_equal(g_rep.offset_ns, 0);
    assert_int_equal(g_rep.jitter_ns, 0);
    assert_int_equal(g_rep.flags, 0);
    assert_false(g_rep.broken);
    assert_int_equal(g_rep.lead_ns, 100000);
    assert_int_equal(g_rep.trail_ns, 9000000 - 100000 - 7 * 1100000 - 1000000);
    assert_int_equal(sync_timeline_end_ns(&g_tl), T0 + 100000 + 7 * 1100000 + 1000000);
}

static void constant_latency_is_offset_not_jitter(void **state)
{
    (void)state;
    int64_t e[8];
    sync_observation obs = observe_plan8(e, 8, 30000, 1); /* 30 µs late, every pattern */
    assert_int_equal(g_rep.offset_ns, 30000);
    assert_int_equal(g_rep.max_abs_error_ns, 30000);
    assert_int_equal(g_rep.jitter_ns, 0);
    assert_false(g_rep.broken);
    assert_int_equal(g_rep.masks[3].error_ns, 30000);
    /* 60 µs is beyond the default 50 µs offset tolerance */
    edges_at_plan(e, 60000);
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, NULL), 0);
    assert_true(g_rep.flags & SYNC_FLAG_OFFSET);
    assert_true(g_rep.broken);
}

static void jitter_is_measured_and_flagged(void **state)
{
    (void)state;
    plan8();
    int64_t e[8];
    edges_at_plan(e, 0);
    e[5] += 25000; /* one late pattern: mean 3125 ns, deviation 21875 ns */
    sync_observation obs = {e, 8, T0, T0 + 9000000, 1};
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, NULL), 0);
    assert_int_equal(g_rep.offset_ns, 3125);
    assert_int_equal(g_rep.jitter_ns, 21875);
    assert_int_equal(g_rep.flags, SYNC_FLAG_JITTER);
    assert_true(g_rep.broken);
    sync_tolerance tol = sync_tolerance_default();
    tol.max_jitter_ns = 30000;
    assert_int_equal(sync_report_compute(&g_tl, &obs, &tol, &g_rep, NULL), 0);
    assert_false(g_rep.broken);
}

static void short_exposure_gives_partial_and_outside(void **state)
{
    (void)state;
    plan8();
    int64_t e[8];
    edges_at_plan(e, 0);
    /* exposure ends 500 µs into pattern 6: pattern 6 is half inside, pattern 7 outside */
    int64_t end = sync_timeline_pattern_start_ns(&g_tl, 6) + 500000;
    sync_observation obs = {e, 8, T0, end, 1};
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, NULL), 0);
    assert_int_equal(g_rep.inside, 6);
    assert_int_equal(g_rep.partial, 1);
    assert_int_equal(g_rep.outside, 1);
    assert_int_equal(g_rep.masks[6].state, SYNC_MASK_PARTIAL);
    assert_true(g_rep.masks[6].overlap > 0.499 && g_rep.masks[6].overlap < 0.501);
    assert_int_equal(g_rep.masks[7].state, SYNC_MASK_OUTSIDE);
    assert_int_equal(g_rep.flags, SYNC_FLAG_PARTIAL_MASK | SYNC_FLAG_MASK_OUTSIDE);
    assert_true(g_rep.broken);
    assert_true(g_rep.trail_ns < 0);
    /* exposure starting late clips the first mask instead */
    obs.exposure_start_ns = T0 + 100000 + 1000000 - 1; /* 1 ns of pattern 0 inside */
    obs.exposure_end_ns = T0 + 9000000;
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, NULL), 0);
    assert_int_equal(g_rep.masks[0].state, SYNC_MASK_PARTIAL);
    assert_true(g_rep.lead_ns < 0);
}

static void missed_dmd_trigger(void **state)
{
    (void)state;
    plan8();
    sync_observation obs = {NULL, 0, T0, T0 + 9000000, 1};
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, NULL), 0);
    assert_true(g_rep.flags & SYNC_FLAG_NO_DMD_EDGES);
    assert_true(g_rep.broken);
    assert_int_equal(g_rep.edges_matched, 0);
    assert_false(g_rep.masks[0].measured);
    assert_int_equal(g_rep.masks[0].start_ns, T0 + 100000); /* placed at the plan */
}

static void missing_and_extra_edges_pair_correctly(void **state)
{
    (void)state;
    plan8();
    int64_t full[8], e[9];
    edges_at_plan(full, 20000);
    /* drop pattern 4's edge: the others still pair with their own pattern */
    int m = 0;
    for (int i = 0; i < 8; i++)
        if (i != 4)
            e[m++] = full[i];
    sync_observation obs = {e, m, T0, T0 + 9000000, 1};
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, NULL), 0);
    assert_int_equal(g_rep.edges_matched, 7);
    assert_false(g_rep.masks[4].measured);
    assert_true(g_rep.masks[5].measured);
    assert_int_equal(g_rep.masks[5].error_ns, 20000);
    assert_int_equal(g_rep.masks[4].start_ns, sync_timeline_pattern_start_ns(&g_tl, 4) + 20000);
    assert_int_equal(g_rep.flags, SYNC_FLAG_MISSING_EDGES);
    assert_int_equal(g_rep.jitter_ns, 0);
    /* a glitch between patterns 2 and 3 as a ninth edge */
    m = 0;
    for (int i = 0; i < 8; i++) {
        e[m++] = full[i];
        if (i == 2)
            e[m++] = full[2] + 550000;
    }
    obs.dmd_edge_count = m;
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, NULL), 0);
    assert_int_equal(g_rep.edges_seen, 9);
    assert_int_equal(g_rep.edges_matched, 8);
    assert_int_equal(g_rep.flags, SYNC_FLAG_EXTRA_EDGES);
    assert_true(g_rep.broken);
}

static void no_frame_and_estimated_exposure(void **state)
{
    (void)state;
    int64_t e[8];
    observe_plan8(e, 8, 0, 0);
    assert_int_equal(g_rep.flags, SYNC_FLAG_EXPOSURE_ESTIMATED);
    assert_false(g_rep.broken); /* informational only */
    assert_int_equal(sync_report_compute(&g_tl, NULL, NULL, &g_rep, NULL), 0);
    assert_true(g_rep.flags & SYNC_FLAG_NO_FRAME);
    assert_int_equal(g_rep.outside, 8);
    assert_true(g_rep.broken);
    char buf[128];
    assert_string_equal(sync_flags_describe(g_rep.flags, buf, sizeof buf), "no_dmd_edges,mask_outside,no_frame");
    assert_string_equal(sync_flags_describe(0, buf, sizeof buf), "ok");
}

static void bad_input_is_named(void **state)
{
    (void)state;
    sci_error err = {0};
    plan8();
    sync_observation obs = {NULL, 0, T0, T0, 1};
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "exposure window"));
    g_tl.exposure_us[3] = 0;
    obs.exposure_end_ns = T0 + 1;
    assert_int_equal(sync_report_compute(&g_tl, &obs, NULL, &g_rep, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "pattern 3"));
    assert_int_equal(sync_timeline_uniform(&g_tl, 0, 0, 10, 0, &err), -EINVAL);
    assert_int_equal(sync_timeline_uniform(&g_tl, 0, SYNC_MAX_PATTERNS + 1, 10, 0, &err), -EINVAL);
    enum sync_mode m;
    assert_int_equal(sync_mode_from_name("camera-master", &m, &err), 0);
    assert_int_equal(m, SYNC_MODE_CAMERA_MASTER);
    assert_int_equal(sync_mode_from_name("slave", &m, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "\"slave\""));
}

/* Random timelines and windows: overlaps agree with a reference computed per mask by clipping in double,
 * and the state counts add up. */
static void random_windows_match_reference(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, g_seed, 4);
    int64_t e[64];
    for (int trial = 0; trial < 500; trial++) {
        int n = 1 + (int)sci_rng_below(&rng, 64);
        g_tl.start_ns = T0 + (int64_t)sci_rng_below(&rng, 1000000);
        g_tl.count = n;
        for (int i = 0; i < n; i++) {
            g_tl.exposure_us[i] = 1 + (uint32_t)sci_rng_below(&rng, 2000);
            g_tl.dark_us[i] = (uint32_t)sci_rng_below(&rng, 200);
        }
        int64_t jit = (int64_t)sci_rng_below(&rng, 5000);
        for (int i = 0; i < n; i++)
            e[i] = sync_timeline_pattern_start_ns(&g_tl, i) + (int64_t)sci_rng_below(&rng, (uint64_t)jit + 1);
        int64_t a = T0 + (int64_t)sci_rng_below(&rng, 50000000), b = a + 1 + (int64_t)sci_rng_below(&rng, 80000000);
        sync_observation obs = {e, n, a, b, 1};
        sync_tolerance tol = {.max_offset_ns = 1000000, .max_jitter_ns = 1000000, .inside_slack = 0};
        assert_int_equal(sync_report_compute(&g_tl, &obs, &tol, &g_rep, NULL), 0);
        assert_int_equal(g_rep.inside + g_rep.partial + g_rep.outside, n);
        for (int i = 0; i < n; i++) {
            double s = (double)e[i], t = s + 1000.0 * g_tl.exposure_us[i];
            double lo = s > (double)a ? s : (double)a, hi = t < (double)b ? t : (double)b;
            double ref = hi > lo ? (hi - lo) / (t - s) : 0.0;
            if (g_rep.masks[i].overlap < ref - 1e-12 || g_rep.masks[i].overlap > ref + 1e-12)
                fail_msg("trial %d mask %d: overlap %.15f, reference %.15f", trial, i, g_rep.masks[i].overlap, ref);
            enum sync_mask_state want = ref >= 1.0 ? SYNC_MASK_INSIDE : ref > 0 ? SYNC_MASK_PARTIAL : SYNC_MASK_OUTSIDE;
            assert_int_equal(g_rep.masks[i].state, want);
        }
        assert_int_equal(g_rep.broken, g_rep.inside != n);
    }
}

static void report_as_json(void **state)
{
    (void)state;
    int64_t e[8];
    observe_plan8(e, 7, 0, 1);
    json_t *j = sync_report_to_json(&g_rep);
    assert_non_null(j);
    assert_true(json_is_true(json_object_get(j, "broken")));
    assert_string_equal(json_string_value(json_array_get(json_object_get(j, "flags"), 0)), "missing_edges");
    assert_int_equal(json_array_size(json_object_get(j, "mask_state")), 8);
    assert_true(json_is_null(json_array_get(json_object_get(j, "mask_error_ns"), 7)));
    json_decref(j);
}

int main(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    g_seed = s ? strtoull(s, NULL, 0) : 99u;
    printf("test_sync: seed %llu (set SCICAP_TEST_SEED to change)\n", (unsigned long long)g_seed);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(perfect_sync),
        cmocka_unit_test(constant_latency_is_offset_not_jitter),
        cmocka_unit_test(jitter_is_measured_and_flagged),
        cmocka_unit_test(short_exposure_gives_partial_and_outside),
        cmocka_unit_test(missed_dmd_trigger),
        cmocka_unit_test(missing_and_extra_edges_pair_correctly),
        cmocka_unit_test(no_frame_and_estimated_exposure),
        cmocka_unit_test(bad_input_is_named),
        cmocka_unit_test(random_windows_match_reference),
        cmocka_unit_test(report_as_json),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
