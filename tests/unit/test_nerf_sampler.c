/* The ray sampler (recon/nerf/patch_sampler.h): stratified depths inside their bins, midpoints without jitter, and
 * the shared jitter of a window (share = R: sample s of every ray of a run at one depth, a fresh depth per run, the
 * stream advanced by L draws per run; share = 1 the former per-ray draws). */
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_depths_in_their_bins),
        cmocka_unit_test(test_window_shares_jitter),
        cmocka_unit_test(test_stream_advance),
        cmocka_unit_test(test_midpoints_without_jitter),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
