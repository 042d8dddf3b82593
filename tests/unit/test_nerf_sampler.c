/* The ray sampler (recon/nerf/patch_sampler.h): stratified depths inside their bins, midpoints without jitter, and
 * the shared jitter of a window (share = R: sample s of every ray of a run at one depth, a fresh depth per run, the
 * stream advanced by L draws per run; share = 1 the former per-ray draws), stratified window positions, and the
 * pixels of strided windows and of their inference tiling (every pixel in some window, every window inside), and
 * training windows of one stride or of strides drawn per window, and the stride narrowing over a run. */
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
        nerf_patch_pixels(3 * b, 5 * b, W, H, 1, px + b * R, py + b * R);
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

static void test_strided_window(void **state)
{
    (void)state;
    int px[8], py[8];
    nerf_patch_pixels(5, 7, 4, 2, 3, px, py); /* ray r = y·4 + x at (5 + 3x, 7 + 3y) */
    const int ex[8] = {5, 8, 11, 14, 5, 8, 11, 14}, ey[8] = {7, 7, 7, 7, 10, 10, 10, 10};
    for (int r = 0; r < 8; r++) {
        assert_int_equal(px[r], ex[r]);
        assert_int_equal(py[r], ey[r]);
    }
    assert_int_equal(nerf_patch_span(4, 3), 10);
    assert_int_equal(nerf_patch_span(2, 1), 2);
}

/* The coarse-to-fine stride (nerf_stride_at): from 3 to 1 over 1600 steps a quarter of the run at 3, half at 2,
 * the last quarter at 1, never widening; a start at or under the end stride is the end stride throughout. */
static void test_stride_schedule(void **state)
{
    (void)state;
    enum { ITERS = 1600 };
    int count[4] = {0}, prev = 3;
    for (int it = 1; it <= ITERS; it++) {
        const int d = nerf_stride_at(1, 3, it, ITERS);
        assert_true(d >= 1 && d <= prev);
        count[d]++, prev = d;
    }
    assert_int_equal(nerf_stride_at(1, 3, 1, ITERS), 3);
    assert_int_equal(nerf_stride_at(1, 3, ITERS, ITERS), 1);
    /* the boundary steps round half away from zero: one step either way */
    assert_in_range(count[3], ITERS / 4 - 1, ITERS / 4 + 1);
    assert_in_range(count[2], ITERS / 2 - 1, ITERS / 2 + 1);
    assert_in_range(count[1], ITERS / 4 - 1, ITERS / 4 + 1);
    for (int it = 1; it <= 10; it++) {
        assert_int_equal(nerf_stride_at(2, 2, it, 10), 2);
        assert_int_equal(nerf_stride_at(2, 0, it, 10), 2);
    }
}

/* Training windows (nerf_windows_pick): with one stride they are nerf_strata_pick's corners (or two uniforms each)
 * and nerf_patch_pixels' pixels, draw for draw; with strides 1 … 4 every window lies inside the image, is a grid of
 * one stride centred in the widest window's span, and every stride turns up about equally often (each 25 % of
 * 128 × 200 windows, within 2 %: the binomial spread is 0.3 %). */
static void test_windows_pick(void **state)
{
    (void)state;
    enum { B = 128, PW = 2, RW = PW * PW, IW = 37, IH = 29 };
    static int px[B * RW], py[B * RW], ex[B * RW], ey[B * RW];
    for (int strat = 0; strat <= 1; strat++) {
        sci_rng a, b;
        sci_rng_seed(&a, 5, 0), sci_rng_seed(&b, 5, 0);
        nerf_windows_pick(B, IW, IH, PW, PW, 2, 0, strat, &a, px, py);
        const int span = nerf_patch_span(PW, 2);
        if (strat)
            nerf_strata_pick(B, IW - span + 1, IH - span + 1, &b, ex, ey);
        for (int k = 0; k < B && !strat; k++) {
            ex[k] = (int)sci_rng_below(&b, IW - span + 1);
            ey[k] = (int)sci_rng_below(&b, IH - span + 1);
        }
        for (int k = B - 1; k >= 0; k--)
            nerf_patch_pixels(ex[k], ey[k], PW, PW, 2, ex + k * RW, ey + k * RW);
        assert_memory_equal(px, ex, sizeof px);
        assert_memory_equal(py, ey, sizeof py);
        assert_int_equal(sci_rng_below(&a, 1000000), sci_rng_below(&b, 1000000));
    }
    sci_rng rng;
    sci_rng_seed(&rng, 6, 0);
    long seen[5] = {0};
    for (int step = 0; step < 200; step++) {
        nerf_windows_pick(B, IW, IH, PW, PW, 1, 4, step & 1, &rng, px, py);
        for (int k = 0; k < B; k++) {
            const int *x = px + k * RW, *y = py + k * RW, d = x[1] - x[0];
            assert_true(d >= 1 && d <= 4);
            assert_true(x[2] == x[0] && x[3] == x[1] && y[1] == y[0] && y[2] - y[0] == d && y[3] == y[2]);
            assert_true(x[0] >= 0 && x[1] < IW && y[0] >= 0 && y[2] < IH);
            /* centred: the window's corner sits (4 − d)/2 pixels into the span of a stride-4 window, which fits */
            const int off = (4 - d) / 2;
            assert_true(x[0] - off >= 0 && x[0] - off + nerf_patch_span(PW, 4) <= IW);
            assert_true(y[0] - off >= 0 && y[0] - off + nerf_patch_span(PW, 4) <= IH);
            seen[d]++;
        }
    }
    for (int d = 1; d <= 4; d++)
        if (fabs(seen[d] - 200.0 * B / 4) > 0.02 * 200.0 * B / 4)
            fail_msg("stride %d in %ld of %d windows", d, seen[d], 200 * B);
    /* an image exactly as wide as the widest window (4 × 4 rays, stride 4: 13 pixels): one corner, every stride
     * centred on it and inside */
    for (int strat = 0; strat <= 1; strat++) {
        nerf_windows_pick(16, 13, 13, 4, 4, 1, 4, strat, &rng, px, py);
        for (int k = 0; k < 16 * 16; k++)
            assert_true(px[k] >= 0 && px[k] < 13 && py[k] >= 0 && py[k] < 13);
        for (int k = 0; k < 16; k++) /* centred on column 6, to the pixel below where the spare span is odd */
            assert_true(px[k * 16] + px[k * 16 + 3] == 12 || px[k * 16] + px[k * 16 + 3] == 11);
    }
}

/* Every tiling (sizes not multiples of the block, every stride and shift) covers each pixel, keeps each window
 * inside the image, and overlaps only where a clamped block meets its neighbour (the first and the last block of
 * an axis: a pixel in at most 3 × 3 windows of one tiling); with stride 1 and no shift a tiling of a multiple of
 * the window is a partition. */
static void test_tiling_covers(void **state)
{
    (void)state;
    enum { MAXW = 41 };
    static int hits[MAXW * MAXW];
    const int sizes[][2] = {{16, 16}, {17, 13}, {41, 23}, {8, 9}};
    for (size_t si = 0; si < sizeof sizes / sizeof sizes[0]; si++)
        for (int pw = 2; pw <= 4; pw += 2)
            for (int d = 1; d <= 4; d++) {
                const int w = sizes[si][0], h = sizes[si][1];
                if (w < pw * d || h < pw * d)
                    continue;
                for (int ox = 0; ox < pw * d; ox += pw * d / 2 > 0 ? pw * d / 2 : 1) {
                    const int oy = ox, n = nerf_tile_count(w, h, pw, pw, d, ox, oy);
                    memset(hits, 0, sizeof hits);
                    for (int t = 0; t < n; t++) {
                        int x0, y0, px[16], py[16];
                        nerf_tile_window(t, w, h, pw, pw, d, ox, oy, &x0, &y0);
                        nerf_patch_pixels(x0, y0, pw, pw, d, px, py);
                        for (int r = 0; r < pw * pw; r++) {
                            assert_true(px[r] >= 0 && px[r] < w && py[r] >= 0 && py[r] < h);
                            hits[py[r] * w + px[r]]++;
                        }
                    }
                    for (int p = 0; p < w * h; p++)
                        if (hits[p] < 1 || hits[p] > 9)
                            fail_msg("%dx%d, window %d stride %d shift %d: pixel (%d, %d) in %d windows", w, h, pw, d,
                                     ox, p % w, p / w, hits[p]);
                    if (d == 1 && ox == 0 && w % pw == 0 && h % pw == 0)
                        for (int p = 0; p < w * h; p++)
                            assert_int_equal(hits[p], 1);
                }
            }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_depths_in_their_bins),
        cmocka_unit_test(test_window_shares_jitter),
        cmocka_unit_test(test_stream_advance),
        cmocka_unit_test(test_midpoints_without_jitter),
        cmocka_unit_test(test_strata),
        cmocka_unit_test(test_strided_window),
        cmocka_unit_test(test_windows_pick),
        cmocka_unit_test(test_stride_schedule),
        cmocka_unit_test(test_tiling_covers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
