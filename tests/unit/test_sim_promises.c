/* The simulator's three promises, each a test:
 *   1. with no effects listed, the measurement equals the plain forward model bit for bit;
 *   2. turning one effect on or off never changes the random draws of another;
 *   3. an effect that is not listed costs nothing: no allocation, no pass over the data, no random draw. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>
#include <omp.h>

#include "io/problem_dir.h"
#include "recon/sci_ops.h"
#include "sim/simulate.h"

static unsigned long long test_seed(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    unsigned long long seed = s ? strtoull(s, NULL, 0) : 7;
    printf("seed %llu (set SCICAP_TEST_SEED to change)\n", seed);
    return seed;
}

/* Every effect with parameters that make it act visibly. */
static const char *const fx_json[SIM_FX_COUNT] = {
    "\"motion_blur\": {\"samples\": 3}",
    "\"blur\": {\"sigma_px\": 1.2}",
    "\"vignetting\": {\"corner\": 0.6}",
    "\"dmd_contrast\": {\"leakage\": 0.01, \"fill_factor\": 0.9}",
    "\"misregistration\": {\"shift_px\": [0.4, -0.3], \"rotation_rad\": 0.01}",
    "\"jitter\": {\"sigma\": 0.1}",
    "\"shot_noise\": true",
    "\"dark_offset\": {\"e\": 20}",
    "\"saturation\": true",
    "\"read_noise\": {\"sigma_e\": 5}",
    "\"quantization\": true",
};

static sim_scene *scene_with(int kind3d, unsigned listed, unsigned long long seed)
{
    char fx[2048] = "", text[8192];
    for (int e = 0; e < SIM_FX_COUNT; e++)
        if (listed & (1u << e)) {
            size_t l = strlen(fx);
            snprintf(fx + l, sizeof fx - l, "%s%s", l ? ", " : "", fx_json[e]);
        }
    if (!kind3d)
        snprintf(text, sizeof text,
                 "{\"kind\": \"video2d\", \"width\": 64, \"height\": 48, \"frames\": 8, \"snapshots\": 2,"
                 " \"seed\": %llu, \"bit_depth\": 10, \"sensor\": {\"photons_white\": 200, \"full_well_e\": 900},"
                 " \"layers\": [{\"texture\": {\"type\": \"noise\", \"cell\": 12}},"
                 "  {\"shape\": \"disc\", \"size\": [20, 20], \"position\": [20, 20], \"velocity\": [2, 1],"
                 "   \"texture\": {\"type\": \"checkerboard\", \"cell\": 4}}],"
                 " \"masks\": {\"type\": \"random\", \"density\": 0.5}, \"effects\": {%s}}",
                 seed, fx);
    else
        snprintf(text, sizeof text,
                 "{\"kind\": \"static3d\", \"width\": 48, \"height\": 40, \"frames\": 4, \"seed\": %llu,"
                 " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, -3], \"radius\": 0.8,"
                 "   \"texture\": {\"type\": \"checkerboard\", \"cell\": 4}},"
                 "  {\"type\": \"plane\", \"center\": [0, 0, -5], \"size\": [8, 8], \"texture\": {\"type\": \"noise\"}}],"
                 " \"camera\": {\"start\": {\"position\": [0, 0, 0], \"look_at\": [0, 0, -3]},"
                 "            \"end\": {\"position\": [0.3, 0.1, 0], \"look_at\": [0, 0, -3]}},"
                 " \"effects\": {%s}}",
                 seed, fx);
    sim_scene *sc = NULL;
    sci_error err = {0};
    if (sim_scene_load_string(&sc, "promise.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    return sc;
}

static sci_problem **run(const sim_scene *sc, int *k, sim_stats *st)
{
    sci_problem **p;
    sci_error err = {0};
    if (sim_run(sc, &p, k, st, NULL, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    return p;
}

/* Promise 1, for both scene kinds and every snapshot; and the stats say nothing ran. */
static void test_no_effects_is_the_forward_model(void **state)
{
    unsigned long long seed = test_seed();
    for (int kind = 0; kind < 2; kind++) {
        sim_scene *sc = scene_with(kind, 0, seed);
        int k;
        sim_stats st;
        sci_problem **p = run(sc, &k, &st);
        for (int s = 0; s < k; s++) {
            sci_cube *y;
            assert_int_equal(sci_cube_new(&y, sc->w, sc->h, 1, NULL), 0);
            sci_op_forward(p[s]->mask, p[s]->truth, y);
            assert_memory_equal(y->data, p[s]->meas->data, sci_cube_count(y) * sizeof(float));
            assert_true(p[s]->peak == 1);
            sci_cube_free(y);
        }
        printf("%s: %d snapshot(s) equal A(mask, truth) bit for bit\n", kind ? "static3d" : "video2d", k);
        sci_problem_array_free(p, k);
        sim_scene_free(sc);
    }
}

/* Promise 2. Each random effect's draws (count and hash of every variate with its position) stay the same when
 * any other effect is turned on. Shot noise draws Poisson(λ) with λ the light that reaches the sensor, so effects
 * upstream of it change its variates by design (not its stream); for it the others toggled are those that leave
 * λ alone: every effect after it. */
static void test_draws_independent_of_other_effects(void **state)
{
    unsigned long long seed = test_seed();
    const int random_fx[] = {SIM_FX_JITTER, SIM_FX_SHOT_NOISE, SIM_FX_READ_NOISE};
    int checked = 0;
    for (int r = 0; r < 3; r++) {
        int e = random_fx[r];
        sim_scene *alone = scene_with(0, 1u << e, seed);
        int k;
        sim_stats st0;
        sci_problem **p0 = run(alone, &k, &st0);
        assert_true(st0.draws[e] > 0);
        for (int f = 0; f < SIM_FX_COUNT; f++) {
            if (f == e || (e == SIM_FX_SHOT_NOISE && f < SIM_FX_SHOT_NOISE))
                continue;
            sim_scene *both = scene_with(0, (1u << e) | (1u << f), seed);
            sim_stats st1;
            sci_problem **p1 = run(both, &k, &st1);
            if (st1.draws[e] != st0.draws[e] || st1.draw_hash[e] != st0.draw_hash[e])
                fail_msg("%s's draws changed when %s was turned on", sim_fx_name(e), sim_fx_name(f));
            /* Masks and truth have their own streams too. */
            for (int s = 0; s < k; s++) {
                assert_memory_equal(p1[s]->mask->data, p0[s]->mask->data, sci_cube_count(p0[s]->mask) * 4);
                assert_memory_equal(p1[s]->truth->data, p0[s]->truth->data, sci_cube_count(p0[s]->truth) * 4);
            }
            checked++;
            sci_problem_array_free(p1, k);
            sim_scene_free(both);
        }
        sci_problem_array_free(p0, k);
        sim_scene_free(alone);
    }
    printf("%d (effect, other effect) pairs: draws unchanged\n", checked);
    /* The same on values: the read noise added is identical with and without shot noise before it. */
    int k;
    sim_scene *a = scene_with(0, 0, seed), *b = scene_with(0, 1u << SIM_FX_READ_NOISE, seed),
              *c = scene_with(0, 1u << SIM_FX_SHOT_NOISE, seed),
              *d = scene_with(0, (1u << SIM_FX_SHOT_NOISE) | (1u << SIM_FX_READ_NOISE), seed);
    sci_problem **pa = run(a, &k, NULL), **pb = run(b, &k, NULL), **pc = run(c, &k, NULL), **pd = run(d, &k, NULL);
    double worst = 0;
    for (size_t i = 0; i < sci_cube_count(pa[0]->meas); i++) {
        double n1 = (double)pb[0]->meas->data[i] - pa[0]->meas->data[i];
        double n2 = (double)pd[0]->meas->data[i] - pc[0]->meas->data[i];
        worst = fmax(worst, fabs(n1 - n2));
    }
    printf("read noise with vs without shot noise: max difference %.2e (noise sd %.3f)\n", worst, 5.0 / 200);
    assert_true(worst < 2e-6 * 8);
    sim_scene *all[4] = {a, b, c, d};
    sci_problem **ps[4] = {pa, pb, pc, pd};
    for (int i = 0; i < 4; i++) {
        sci_problem_array_free(ps[i], k);
        sim_scene_free(all[i]);
    }
}

/* Promise 3. With one effect listed, every other effect made no pass and no draw; with none listed, the plan
 * holds no memory at all. */
static void test_unlisted_effects_cost_nothing(void **state)
{
    unsigned long long seed = test_seed();
    sim_scene *none = scene_with(0, 0, seed);
    int k;
    sim_stats st;
    sci_problem **p = run(none, &k, &st);
    for (int f = 0; f < SIM_FX_COUNT; f++) {
        assert_int_equal(st.passes[f], 0);
        assert_int_equal(st.draws[f], 0);
    }
    assert_int_equal(st.work_bytes, 0);
    sci_problem_array_free(p, k);
    sim_scene_free(none);
    for (int e = 0; e < SIM_FX_COUNT; e++) {
        sim_scene *sc = scene_with(0, 1u << e, seed);
        p = run(sc, &k, &st);
        for (int f = 0; f < SIM_FX_COUNT; f++) {
            if (f == e) {
                assert_int_equal(st.passes[f], k); /* one pass per snapshot */
                continue;
            }
            if (st.passes[f] || st.draws[f])
                fail_msg("with only %s listed, %s made %lld passes and %lld draws", sim_fx_name(e), sim_fx_name(f),
                         st.passes[f], st.draws[f]);
        }
        /* Sensor effects need no working memory; scene- and DMD-side ones hold only their own buffers. */
        if (e >= SIM_FX_SHOT_NOISE)
            assert_int_equal(st.work_bytes, 0);
        printf("%-16s alone: %lld passes, %lld draws, %zu working bytes; all others zero\n", sim_fx_name(e),
               st.passes[e], st.draws[e], st.work_bytes);
        sci_problem_array_free(p, k);
        sim_scene_free(sc);
    }
}

/* Each effect, alone, really changes the measurement (so the tests above test something). */
static void test_each_effect_acts(void **state)
{
    unsigned long long seed = test_seed();
    int k;
    sim_scene *none = scene_with(0, 0, seed);
    sci_problem **p0 = run(none, &k, NULL);
    for (int e = 0; e < SIM_FX_COUNT; e++) {
        sim_scene *sc = scene_with(0, 1u << e, seed);
        sci_problem **p = run(sc, &k, NULL);
        double diff = 0;
        for (size_t i = 0; i < sci_cube_count(p[0]->meas); i++)
            diff += fabs((double)p[0]->meas->data[i] - p0[0]->meas->data[i]);
        printf("%-16s mean |Δy| = %.4g\n", sim_fx_name(e), diff / sci_cube_count(p[0]->meas));
        assert_true(diff > 0);
        /* The problem keeps the sharp truth and the nominal masks. */
        assert_memory_equal(p[0]->truth->data, p0[0]->truth->data, sci_cube_count(p0[0]->truth) * 4);
        assert_memory_equal(p[0]->mask->data, p0[0]->mask->data, sci_cube_count(p0[0]->mask) * 4);
        sci_problem_array_free(p, k);
        sim_scene_free(sc);
    }
    sci_problem_array_free(p0, k);
    sim_scene_free(none);
}

/* Same seed, same result; at 1 and at 2 threads. */
static void test_deterministic(void **state)
{
    unsigned long long seed = test_seed();
    unsigned all = (1u << SIM_FX_COUNT) - 1;
    sim_scene *sc = scene_with(0, all, seed);
    int k;
    sci_problem **p1 = run(sc, &k, NULL);
    int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    sci_problem **p2 = run(sc, &k, NULL);
    omp_set_num_threads(threads);
    printf("all effects: %d threads and 1 thread give the same measurement\n", threads);
    for (int s = 0; s < k; s++)
        assert_memory_equal(p1[s]->meas->data, p2[s]->meas->data, sci_cube_count(p1[s]->meas) * 4);
    sci_problem_array_free(p1, k);
    sci_problem_array_free(p2, k);
    sim_scene_free(sc);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_no_effects_is_the_forward_model),
        cmocka_unit_test(test_draws_independent_of_other_effects),
        cmocka_unit_test(test_unlisted_effects_cost_nothing),
        cmocka_unit_test(test_each_effect_acts),
        cmocka_unit_test(test_deterministic),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
