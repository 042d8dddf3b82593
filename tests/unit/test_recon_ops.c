/* SCI operators, TV denoiser and metrics: algebraic identities and hand-computed values. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>

#include "base/rng.h"
#include "recon/metrics.h"
#include "recon/sci_ops.h"
#include "recon/tv.h"

static uint64_t seed_from_env(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    uint64_t seed = s ? strtoull(s, NULL, 0) : (uint64_t)time(NULL);
    printf("seed %llu (set SCICAP_TEST_SEED to repeat)\n", (unsigned long long)seed);
    return seed;
}

static sci_cube *random_cube(sci_rng *rng, int w, int h, int n, int binary)
{
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, w, h, n, NULL), 0);
    for (size_t i = 0; i < sci_cube_count(c); i++)
        c->data[i] = binary ? (float)(sci_rng_u64(rng) & 1) : sci_rng_uniformf(rng);
    return c;
}

/* <A x, y> = <x, Aᵀ y> for random x, y, M: A and Aᵀ are adjoint. */
static void test_adjoint(void **state)
{
    sci_rng rng;
    sci_rng_seed(&rng, seed_from_env(), 1);
    const int sizes[][3] = {{1, 1, 1}, {7, 5, 3}, {64, 33, 8}, {256, 256, 8}};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        int w = sizes[s][0], h = sizes[s][1], n = sizes[s][2];
        sci_cube *m = random_cube(&rng, w, h, n, 0), *x = random_cube(&rng, w, h, n, 0);
        sci_cube *y = random_cube(&rng, w, h, 1, 0), *ax, *aty;
        assert_int_equal(sci_cube_new(&ax, w, h, 1, NULL), 0);
        assert_int_equal(sci_cube_new(&aty, w, h, n, NULL), 0);
        sci_op_forward(m, x, ax);
        sci_op_adjoint(m, y, aty);
        double l = 0, r = 0;
        for (size_t i = 0; i < sci_cube_count(ax); i++)
            l += (double)ax->data[i] * y->data[i];
        for (size_t i = 0; i < sci_cube_count(x); i++)
            r += (double)x->data[i] * aty->data[i];
        assert_true(fabs(l - r) <= 1e-5 * fabs(l));
        sci_cube_free(m);
        sci_cube_free(x);
        sci_cube_free(y);
        sci_cube_free(ax);
        sci_cube_free(aty);
    }
}

/* Φ_sum = Σ M², with zeros replaced by 1 and counted. */
static void test_phi_guard(void **state)
{
    sci_cube *m, *phi;
    assert_int_equal(sci_cube_new(&m, 3, 1, 2, NULL), 0);
    assert_int_equal(sci_cube_new(&phi, 3, 1, 1, NULL), 0);
    float v[] = {0, 1, 0.5f, 0, 1, 2};
    memcpy(m->data, v, sizeof v);
    assert_int_equal(sci_op_phi_sum(m, phi), 1);
    assert_true(phi->data[0] == 1.0f);
    assert_true(phi->data[1] == 2.0f);
    assert_true(phi->data[2] == 4.25f);
    sci_cube_free(m);
    sci_cube_free(phi);
}

/* Straight transcription of TV_denoising.m (dual updates after every pass, output before the last), used as
 * the reference for the fused one-sweep implementation. Column-major MATLAB indexing mapped to rows/columns. */
static void tv_reference(const float *f, float *u, int w, int h, float lam, int iters)
{
    float *zh = calloc((size_t)h * w, sizeof *zh), *zv = calloc((size_t)h * w, sizeof *zv);
    float *x0 = malloc((size_t)h * w * sizeof *x0);
    for (int it = 0; it < iters; it++) {
        for (int r = 0; r < h; r++)
            for (int c = 0; c < w; c++) {
                float dht = (c == 0 ? -zh[r * w] : (c == w - 1 ? zh[r * w + w - 2] : zh[r * w + c - 1] - zh[r * w + c]));
                float dvt = (r == 0 ? -zv[c] : (r == h - 1 ? zv[(h - 2) * w + c] : zv[(r - 1) * w + c] - zv[r * w + c]));
                if (w == 1)
                    dht = 0;
                if (h == 1)
                    dvt = 0;
                x0[r * w + c] = ((f[r * w + c] - dht) + (f[r * w + c] - dvt)) / 2;
            }
        for (int r = 0; r < h; r++)
            for (int c = 0; c + 1 < w; c++) {
                float z = zh[r * w + c] + (x0[r * w + c + 1] - x0[r * w + c]) / 5.0f;
                zh[r * w + c] = z > lam / 2 ? lam / 2 : (z < -lam / 2 ? -lam / 2 : z);
            }
        for (int r = 0; r + 1 < h; r++)
            for (int c = 0; c < w; c++) {
                float z = zv[r * w + c] + (x0[(r + 1) * w + c] - x0[r * w + c]) / 5.0f;
                zv[r * w + c] = z > lam / 2 ? lam / 2 : (z < -lam / 2 ? -lam / 2 : z);
            }
    }
    memcpy(u, x0, (size_t)h * w * sizeof *u);
    free(zh);
    free(zv);
    free(x0);
}

static void test_tv_matches_reference(void **state)
{
    sci_rng rng;
    sci_rng_seed(&rng, seed_from_env(), 2);
    const int sizes[][2] = {{1, 1}, {1, 9}, {9, 1}, {2, 2}, {17, 13}, {64, 64}};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        int w = sizes[s][0], h = sizes[s][1];
        for (int iters = 1; iters <= 6; iters++) {
            sci_cube *x = random_cube(&rng, w, h, 3, 0), *ref;
            assert_int_equal(sci_cube_clone(&ref, x, NULL), 0);
            for (int k = 0; k < 3; k++)
                tv_reference(sci_cube_frame(x, k), sci_cube_frame(ref, k), w, h, 0.3f, iters);
            sci_tv *tv;
            assert_int_equal(sci_tv_new(&tv, w, h, NULL), 0);
            sci_tv_denoise(tv, x, 0.3f, iters);
            double maxd = 0;
            for (size_t i = 0; i < sci_cube_count(x); i++)
                maxd = fmax(maxd, fabs((double)x->data[i] - ref->data[i]));
            if (maxd > 1e-6)
                fail_msg("TV %dx%d, %d passes: differs from the reference by %g", w, h, iters, maxd);
            sci_tv_free(tv);
            sci_cube_free(x);
            sci_cube_free(ref);
        }
    }
}

/* TV with weight 0 or one pass is the identity; with a large weight a step edge shrinks. */
static void test_tv_edges(void **state)
{
    sci_cube *x;
    assert_int_equal(sci_cube_new(&x, 8, 1, 1, NULL), 0);
    for (int c = 4; c < 8; c++)
        x->data[c] = 1;
    sci_tv *tv;
    assert_int_equal(sci_tv_new(&tv, 8, 1, NULL), 0);
    sci_tv_denoise(tv, x, 0, 5);
    assert_true(x->data[3] == 0 && x->data[4] == 1);
    sci_tv_denoise(tv, x, 1.0f, 50);
    assert_true(x->data[3] > 0.01f && x->data[4] < 0.99f);
    assert_true(x->data[3] < x->data[4]);
    sci_tv_free(tv);
    sci_cube_free(x);
}

static void test_psnr_values(void **state)
{
    float t[4] = {0, 0.5f, 1, 0.25f}, x[4] = {0.1f, 0.5f, 1, 0.25f};
    /* MSE = 0.01/4 -> PSNR with peak 1 = 10 log10(400) */
    assert_true(fabs(sci_psnr_frame(x, t, 4, 1.0) - 10 * log10(400.0)) < 1e-5);
    assert_true(isinf(sci_psnr_frame(t, t, 4, 1.0)));
    sci_cube *a, *b;
    assert_int_equal(sci_cube_new(&a, 2, 2, 1, NULL), 0);
    assert_int_equal(sci_cube_new(&b, 2, 2, 1, NULL), 0);
    memcpy(a->data, x, sizeof x);
    for (int i = 0; i < 4; i++)
        b->data[i] = t[i] * 0.5f; /* frame max 0.5 */
    for (int i = 0; i < 4; i++)
        a->data[i] = b->data[i] + (i == 0 ? 0.05f : 0);
    double mse = 0.05 * 0.05 / 4;
    assert_true(fabs(sci_psnr(a, b, SCI_PEAK_FRAME_MAX, 0, NULL) - 10 * log10(0.25 / mse)) < 1e-4);
    assert_true(fabs(sci_psnr(a, b, SCI_PEAK_FIXED, 1.0, NULL) - 10 * log10(1 / mse)) < 1e-4);
    sci_cube_free(a);
    sci_cube_free(b);
}

/* SSIM: identical images give 1; a constant offset of the full range gives the closed form
 * (2µxµy + C1)/(µx² + µy² + C1) for flat images. */
static void test_ssim_values(void **state)
{
    enum { W = 32, H = 24 };
    float a[W * H], b[W * H];
    for (int i = 0; i < W * H; i++) {
        a[i] = 0.25f;
        b[i] = 0.75f;
    }
    assert_true(fabs(sci_ssim_frame(a, a, W, H, 1.0) - 1.0) < 1e-12);
    double c1 = 0.01 * 0.01, expect = (2 * 0.25 * 0.75 + c1) / (0.25 * 0.25 + 0.75 * 0.75 + c1);
    assert_true(fabs(sci_ssim_frame(a, b, W, H, 1.0) - expect) < 1e-9);
    sci_rng rng;
    sci_rng_seed(&rng, 7, 0);
    for (int i = 0; i < W * H; i++) {
        a[i] = sci_rng_uniformf(&rng);
        b[i] = a[i] + 0.1f * (sci_rng_uniformf(&rng) - 0.5f);
    }
    double s = sci_ssim_frame(a, b, W, H, 1.0);
    assert_true(s > 0.5 && s < 1.0);
    assert_true(fabs(sci_ssim_frame(b, a, W, H, 1.0) - s) < 1e-12); /* symmetric */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_adjoint),       cmocka_unit_test(test_phi_guard),
        cmocka_unit_test(test_tv_matches_reference), cmocka_unit_test(test_tv_edges),
        cmocka_unit_test(test_psnr_values),   cmocka_unit_test(test_ssim_values),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
