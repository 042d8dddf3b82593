/* The ray sampler (recon/nerf/patch_sampler.h): stratified depths inside their bins, midpoints without jitter, and
 * the shared jitter of a window (share = R: sample s of every ray of a run at one depth, a fresh depth per run, the
 * stream advanced by L draws per run; share = 1 the former per-ray draws), and stratified window positions. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "base/rng.h"
#include "recon/nerf/patch_sampler.h"

enum { W = 2, H = 2, R = W * H, RUNS = 3, NR = R * RUNS, L = 6 };

static const sci_camera cam = {.fx = 20, .fy = 20, .cx = 8, .cy = 8, .n = 1, .near_m = 1.5, .far_m = 7.5};

/* Rays of RUNS windows at different places; depth t of point k is −pcam_z. */
static void rays(sci_rng *rng, int share, nerf_spacing sp, float *t)
{
    int px[NR], py[NR];
    for (int b = 0; b < RUNS; b++)
        nerf_patch_pixels(3 * b, 5 * b, W, H, px + b * R, py + b * R);
    float pcam[NR * L * 3], dcam[NR * 3], delta[NR * L];
    nerf_rays_camera(&cam, NR, px, py, L, cam.near_m, cam.far_m, sp, rng, share, pcam, dcam, delta);
    for (int k = 0; k < NR * L; k++)
        t[k] = -pcam[3 * k + 2];
}

static void test_depths_in_their_bins(void **state)
{
    (void)state;
    for (int sp = NERF_SPACING_LINEAR; sp <= NERF_SPACING_LOG; sp++)
        for (int share = 1; share <= R; share += R - 1) {
            sci_rng rng;
            sci_rng_seed(&rng, 7, 0);
            float t[NR * L];
            rays(&rng, share, (nerf_spacing)sp, t);
            for (int r = 0; r < NR; r++)
                for (int s = 0; s < L; s++) {
                    double lo = nerf_depth_at((nerf_spacing)sp, cam.near_m, cam.far_m, (double)s / L);
                    double hi = nerf_depth_at((nerf_spacing)sp, cam.near_m, cam.far_m, (s + 1.0) / L);
                    float v = t[r * L + s];
                    assert_true(v >= lo - 1e-5 && v <= hi + 1e-5);
                }
        }
}

/* share = R: within a run every ray has the same depths, and runs differ (the draws are used, not replayed for
 * the whole batch). share = 1: the rays of a window differ. */
static void test_window_shares_jitter(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, 11, 0);
    float t[NR * L];
    rays(&rng, R, NERF_SPACING_LINEAR, t);
    for (int b = 0; b < RUNS; b++)
        for (int r = 1; r < R; r++)
            assert_memory_equal(t + (b * R + r) * L, t + b * R * L, sizeof(float) * L);
    assert_memory_not_equal(t, t + R * L, sizeof(float) * L);
    assert_memory_not_equal(t + R * L, t + 2 * R * L, sizeof(float) * L);

    sci_rng_seed(&rng, 11, 0);
    rays(&rng, 1, NERF_SPACING_LINEAR, t);
    for (int r = 1; r < R; r++)
        assert_memory_not_equal(t + r * L, t, sizeof(float) * L);
}

/* The stream after a call: per run of `share` rays, L draws. share = 1 is the per-ray sampler: the first ray's
 * depths are the same whatever share is, since both start from the same state. */
static void test_stream_advance(void **state)
{
    (void)state;
    for (int share = 1; share <= R; share += R - 1) {
        sci_rng a, b;
        sci_rng_seed(&a, 5, 0);
        sci_rng_seed(&b, 5, 0);
        float t[NR * L];
        rays(&a, share, NERF_SPACING_LINEAR, t);
        for (int k = 0; k < NR / share * L; k++)
            (void)sci_rng_uniform(&b);
        assert_int_equal(sci_rng_u64(&a), sci_rng_u64(&b));
    }
    sci_rng a, b;
    sci_rng_seed(&a, 5, 0);
    sci_rng_seed(&b, 5, 0);
    float t1[NR * L], tR[NR * L];
    rays(&a, 1, NERF_SPACING_LINEAR, t1);
    rays(&b, R, NERF_SPACING_LINEAR, tR);
    assert_memory_equal(t1, tR, sizeof(float) * L);
}

/* Without jitter every sample sits at its bin's midpoint, whatever share is. */
static void test_midpoints_without_jitter(void **state)
{
    (void)state;
    float t[NR * L];
    rays(NULL, R, NERF_SPACING_LINEAR, t);
    for (int r = 0; r < NR; r++)
        for (int s = 0; s < L; s++)
            assert_float_equal(t[r * L + s], cam.near_m + (s + 0.5) * (cam.far_m - cam.near_m) / L, 1e-5);
}

/* Stratified positions: one per cell where the grid has exactly n cells (16 over 16 × 16: one in each 4 × 4 block,
 * every step), in range for the 128² image's 2 × 2 windows (127 × 127, 132 cells for 128) and for a rectangle with
 * fewer pixels than positions, and every pixel equally likely over many steps even where the span does not divide
 * by the grid (6 × 5 with 4 cells: pixels split between cells; counts within 5 % of the mean, the binomial spread
 * at 120,000 draws a pixel being 0.3 %). */
static void test_strata(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, 11, 0);
    int x[128], y[128];
    for (int step = 0; step < 50; step++) {
        int block[16] = {0};
        nerf_strata_pick(16, 16, 16, &rng, x, y);
        for (int k = 0; k < 16; k++)
            block[(y[k] / 4) * 4 + x[k] / 4]++;
        for (int b = 0; b < 16; b++)
            assert_int_equal(block[b], 1);
        nerf_strata_pick(128, 127, 127, &rng, x, y);
        for (int k = 0; k < 128; k++)
            assert_true(x[k] >= 0 && x[k] < 127 && y[k] >= 0 && y[k] < 127);
        nerf_strata_pick(10, 2, 3, &rng, x, y);
        for (int k = 0; k < 10; k++)
            assert_true(x[k] >= 0 && x[k] < 2 && y[k] >= 0 && y[k] < 3);
    }
    enum { SX = 6, SY = 5, DRAWS = 900000 };
    long count[SX * SY] = {0};
    for (int d = 0; d < DRAWS; d++) {
        nerf_strata_pick(4, SX, SY, &rng, x, y);
        for (int k = 0; k < 4; k++)
            count[y[k] * SX + x[k]]++;
    }
    const double mean = 4.0 * DRAWS / (SX * SY);
    for (int p = 0; p < SX * SY; p++)
        if (fabs(count[p] - mean) > 0.05 * mean)
            fail_msg("pixel (%d, %d) drawn %ld times, the mean is %.0f", p % SX, p / SX, count[p], mean);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_depths_in_their_bins),
        cmocka_unit_test(test_window_shares_jitter),
        cmocka_unit_test(test_stream_advance),
        cmocka_unit_test(test_midpoints_without_jitter),
        cmocka_unit_test(test_strata),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
