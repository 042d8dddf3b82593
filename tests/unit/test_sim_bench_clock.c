/* The simulated bench's scene clock (sim/bench.h): snapshot j sees clock frames j·n … j·n + n − 1, played forward
 * and back over the scene's length (at least SIM_BENCH_LOOP_FRAMES for video2d), so that consecutive snapshots —
 * scicapd's consecutive captures — see the scene move on, for as long as they are taken, and nothing leaves the
 * scene's time. The first frames are the scene's own (what `scicap sim` renders). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "sim/bench.h"

static sim_bench *open_bench(const char *scene_json)
{
    sim_bench_options o = sim_bench_options_default();
    sci_error err = {0};
    if (scene_json && sim_scene_load_string(&o.scene, "clock.json", scene_json, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    sim_bench *b = NULL;
    if (sim_bench_open(&b, &o, &err) < 0)
        fail_msg("sim_bench_open: %s", err.msg);
    return b;
}

/* Forward, then back, one frame per frame: continuous, inside [0, len), the identity over the first len. */
static void check_clock(sim_bench *b, int n, int len, int snapshots)
{
    double prev = -1;
    for (int j = 0; j < snapshots; j++) {
        sim_bench_set_snapshot(b, (uint64_t)j);
        for (int k = 0; k < n; k++) {
            double t = sim_bench_frame_time(b, n, k);
            long f = (long)j * n + k;
            assert_true(t >= 0 && t <= len - 1);
            if (f < len)
                assert_true(t == (double)f);
            if (prev >= 0)
                assert_true(fabs(t - prev) == 1.0);
            prev = t;
        }
    }
}

static void default_scene_moves_on(void **state)
{
    sim_bench *b = open_bench(NULL); /* the daemon's: one snapshot of 8 frames, so the clock's 32 */
    check_clock(b, 8, SIM_BENCH_LOOP_FRAMES, 40);
    /* the bounce: snapshot 4 plays 30, 29, ..., 23 */
    sim_bench_set_snapshot(b, 4);
    for (int k = 0; k < 8; k++)
        assert_true(sim_bench_frame_time(b, 8, k) == 30 - k);
    /* each snapshot's truth differs from the one before, over two whole periods */
    sci_error err = {0};
    sci_cube *prev = NULL;
    double least = INFINITY;
    for (int j = 0; j < 16; j++) {
        sim_bench_set_snapshot(b, (uint64_t)j);
        const sci_cube *t = sim_bench_truth(b, 8, &err);
        assert_non_null(t);
        if (prev) {
            double moved = 0;
            for (size_t i = 0; i < sci_cube_count(t); i++)
                moved = fmax(moved, fabs(t->data[i] - prev->data[i]));
            least = fmin(least, moved);
            sci_cube_free(prev);
        }
        assert_int_equal(sci_cube_clone(&prev, t, &err), 0);
    }
    printf("16 consecutive snapshots of the default scene: each differs from the one before by at least %.3f\n",
           least);
    assert_true(least > 0.1);
    sci_cube_free(prev);
    sim_bench_close(b);
}

static void long_scene_plays_its_own_length(void **state)
{
    /* 6 snapshots of 8 frames: 48 frames, longer than the loop's minimum: its own length */
    sim_bench *b = open_bench("{\"kind\": \"video2d\", \"width\": 32, \"height\": 24, \"frames\": 8, \"snapshots\": 6,"
                              " \"layers\": [{\"shape\": \"disc\", \"size\": [6, 6], \"position\": [4, 12],"
                              " \"velocity\": [0.5, 0], \"texture\": {\"type\": \"constant\", \"value\": 1}}]}");
    check_clock(b, 8, 48, 30);
    sim_bench_close(b);
}

static void static3d_stays_on_its_path(void **state)
{
    /* a camera path is defined over the scene's frames only: no minimum length */
    sim_bench *b = open_bench(
        "{\"kind\": \"static3d\", \"width\": 24, \"height\": 24, \"frames\": 4, \"seed\": 5,"
        " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, -3], \"radius\": 0.8,"
        "  \"texture\": {\"type\": \"checkerboard\", \"cell\": 12}}],"
        " \"camera\": {\"fx\": 24, \"cx\": 12, \"cy\": 12, \"near\": 1.5, \"far\": 6,"
        "  \"start\": {\"position\": [-0.15, 0, 0], \"look_at\": [0, 0, -3]},"
        "  \"end\": {\"position\": [0.15, 0.05, 0], \"look_at\": [0, 0, -3]}}}");
    check_clock(b, 4, 4, 10);
    sim_bench_close(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(default_scene_moves_on),
        cmocka_unit_test(long_scene_plays_its_own_length),
        cmocka_unit_test(static3d_stays_on_its_path),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
