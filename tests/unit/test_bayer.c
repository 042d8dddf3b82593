/* recon/bayer, recon/demosaic, sci_psnr_rgb: the CFA tables of the four patterns, the mask × mosaic forward model
 * splitting exactly into four plane problems (each plane's y is the plane's own SCI forward model) and merging
 * back bit for bit, demosaicing exact where it must be (constant colour everywhere, linear ramps in the interior,
 * both methods), Malvar-He-Cutler beating bilinear on a smooth colour image, and the RGB PSNR convention. Seeded. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "base/rng.h"
#include "recon/bayer.h"
#include "recon/metrics.h"
#include "recon/sci_ops.h"

static sci_cube *cube(int w, int h, int n)
{
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, w, h, n, NULL), 0);
    return c;
}

static void test_cfa_tables(void **state)
{
    /* Colour at (0,0) (1,0) (0,1) (1,1), 0 R 1 G 2 B, and the name round trip. */
    const struct { const char *name; int c[4]; } t[] = {
        {"RGGB", {0, 1, 1, 2}}, {"BGGR", {2, 1, 1, 0}}, {"GRBG", {1, 0, 2, 1}}, {"GBRG", {1, 2, 0, 1}}};
    for (int i = 0; i < 4; i++) {
        sci_cfa cfa;
        assert_int_equal(sci_cfa_parse(t[i].name, &cfa), 0);
        assert_string_equal(sci_cfa_name(cfa), t[i].name);
        for (int j = 0; j < 4; j++) {
            assert_int_equal(sci_cfa_color(cfa, j & 1, j >> 1), t[i].c[j]);
            assert_int_equal(sci_cfa_color(cfa, (j & 1) + 6, (j >> 1) + 10), t[i].c[j]); /* periodic */
        }
    }
    sci_cfa cfa;
    assert_int_equal(sci_cfa_parse("rggb", &cfa), 0);
    assert_int_equal(sci_cfa_parse("RGBG", &cfa), -EINVAL);
}

/* y = Σ M ⊙ mosaic(x): plane i's y equals the plane's forward model of its masks and mosaicked truth, and the
 * four truths merge back to the mosaic exactly. */
static void test_split_is_the_forward_model(void **state)
{
    const int w = 12, h = 8, n = 3;
    unsigned long long seed = 18;
    printf("seed %llu\n", seed);
    sci_rng rng;
    sci_rng_seed(&rng, seed, 0);
    for (int pat = SCI_CFA_RGGB; pat <= SCI_CFA_GBRG; pat++) {
        sci_cube *rgb = cube(w, h, 3 * n), *raw = cube(w, h, n);
        sci_problem p = {.mask = cube(w, h, n), .meas = cube(w, h, 1), .truth = raw, .peak = 1};
        snprintf(p.name, sizeof p.name, "t");
        for (size_t i = 0; i < sci_cube_count(rgb); i++)
            rgb->data[i] = (float)sci_rng_uniform(&rng);
        for (size_t i = 0; i < sci_cube_count(p.mask); i++)
            p.mask->data[i] = sci_rng_uniform(&rng) < 0.5 ? 1.0f : 0.0f;
        sci_cfa_mosaic((sci_cfa)pat, rgb, raw);
        for (int f = 0; f < n; f++)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++)
                    assert_true(sci_cube_frame(raw, f)[y * w + x] ==
                                sci_cube_frame(rgb, 3 * f + sci_cfa_color((sci_cfa)pat, x, y))[y * w + x]);
        sci_op_forward(p.mask, raw, p.meas);
        sci_problem *planes[4];
        sci_error err = {0};
        if (sci_bayer_split(&p, (sci_cfa)pat, planes, &err) < 0)
            fail_msg("%s", err.msg);
        sci_cube *back = cube(w, h, n), *ts[4];
        for (int i = 0; i < 4; i++) {
            assert_int_equal(planes[i]->mask->w, w / 2);
            sci_cube *yp = cube(w / 2, h / 2, 1);
            sci_op_forward(planes[i]->mask, planes[i]->truth, yp);
            assert_memory_equal(yp->data, planes[i]->meas->data, sizeof(float) * (size_t)(w / 2) * (h / 2));
            sci_cube_free(yp);
            ts[i] = planes[i]->truth;
        }
        sci_bayer_merge(ts, back);
        assert_memory_equal(back->data, raw->data, sizeof(float) * sci_cube_count(raw));
        printf("%s: planes %s %s %s %s\n", sci_cfa_name((sci_cfa)pat), planes[0]->name, planes[1]->name,
               planes[2]->name, planes[3]->name);
        for (int i = 0; i < 4; i++)
            sci_problem_free(planes[i]);
        sci_cube_free(back);
        sci_cube_free(rgb);
        sci_cube_free(p.mask);
        sci_cube_free(p.meas);
        sci_cube_free(raw);
    }
    /* Odd sizes are refused. */
    sci_problem odd = {.mask = cube(7, 8, 1), .meas = cube(7, 8, 1)};
    sci_problem *planes[4];
    sci_error err = {0};
    assert_int_equal(sci_bayer_split(&odd, SCI_CFA_RGGB, planes, &err), SCI_ESHAPE);
    sci_cube_free(odd.mask);
    sci_cube_free(odd.meas);
}

typedef double (*field_fn)(int c, double x, double y);
static double f_const(int c, double x, double y) { return 0.2 + 0.3 * c; }
static double f_linear(int c, double x, double y) { return 0.1 + 0.01 * (c + 1) * x + 0.007 * (3 - c) * y; }
static double f_smooth(int c, double x, double y)
{
    /* Like a natural image: channels share their detail (one luminance pattern, scaled and offset per channel),
     * which is what MHC's cross-channel Laplacian uses. */
    const double lum = 0.5 + 0.3 * sin(0.6 * x) * cos(0.45 * y);
    return lum * (0.8 + 0.1 * c) + 0.05 * c;
}

/* Max error over the pixels at least `margin` from the border, and the RGB PSNR over all. */
static double demosaic_err(sci_cfa cfa, sci_demosaic_method m, field_fn fn, int margin, double *psnr)
{
    const int w = 32, h = 24;
    sci_cube *rgb = cube(w, h, 3), *raw = cube(w, h, 1), *out = cube(w, h, 3);
    for (int c = 0; c < 3; c++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                sci_cube_frame(rgb, c)[y * w + x] = (float)fn(c, x, y);
    sci_cfa_mosaic(cfa, rgb, raw);
    sci_demosaic(cfa, m, raw->data, w, h, sci_cube_frame(out, 0), sci_cube_frame(out, 1), sci_cube_frame(out, 2));
    double e = 0;
    for (int c = 0; c < 3; c++)
        for (int y = margin; y < h - margin; y++)
            for (int x = margin; x < w - margin; x++)
                e = fmax(e, fabs(sci_cube_frame(out, c)[y * w + x] - sci_cube_frame(rgb, c)[y * w + x]));
    if (psnr)
        *psnr = sci_psnr_rgb(out, rgb, SCI_PEAK_FIXED, 1, NULL);
    sci_cube_free(rgb);
    sci_cube_free(raw);
    sci_cube_free(out);
    return e;
}

static void test_demosaic_exact_cases(void **state)
{
    for (int pat = SCI_CFA_RGGB; pat <= SCI_CFA_GBRG; pat++)
        for (int m = 0; m < 2; m++) {
            assert_true(demosaic_err((sci_cfa)pat, (sci_demosaic_method)m, f_const, 0, NULL) < 1e-6);
            assert_true(demosaic_err((sci_cfa)pat, (sci_demosaic_method)m, f_linear, 2, NULL) < 1e-5);
        }
}

static void test_mhc_beats_bilinear_on_smooth_colour(void **state)
{
    for (int pat = SCI_CFA_RGGB; pat <= SCI_CFA_GBRG; pat++) {
        double pb, pm;
        demosaic_err((sci_cfa)pat, SCI_DEMOSAIC_BILINEAR, f_smooth, 2, &pb);
        demosaic_err((sci_cfa)pat, SCI_DEMOSAIC_MHC, f_smooth, 2, &pm);
        printf("%s: bilinear %.2f dB, mhc %.2f dB\n", sci_cfa_name((sci_cfa)pat), pb, pm);
        assert_true(pm > pb + 1.0);
    }
}

/* Mean over R, G, B of per-channel PSNR, then over frames: channels with MSE 1e-2, 1e-3, 1e-4 at peak 1 give
 * 20, 30, 40 dB → 30 dB (not the PSNR of the pooled MSE, 24.3 dB). */
static void test_psnr_rgb_convention(void **state)
{
    sci_cube *t = cube(4, 4, 6), *x = cube(4, 4, 6);
    for (size_t i = 0; i < sci_cube_count(t); i++)
        t->data[i] = 0.5f;
    const double d[3] = {0.1, sqrt(1e-3), 0.01};
    for (int f = 0; f < 2; f++)
        for (int c = 0; c < 3; c++)
            for (int i = 0; i < 16; i++)
                sci_cube_frame(x, 3 * f + c)[i] = (float)(0.5 + d[c]);
    double per[2];
    double m = sci_psnr_rgb(x, t, SCI_PEAK_FIXED, 1, per);
    printf("rgb psnr %.4f (frames %.4f %.4f)\n", m, per[0], per[1]);
    assert_true(fabs(m - 30) < 1e-3 && fabs(per[1] - 30) < 1e-3);
    sci_cube_free(t);
    sci_cube_free(x);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cfa_tables),
        cmocka_unit_test(test_split_is_the_forward_model),
        cmocka_unit_test(test_demosaic_exact_cases),
        cmocka_unit_test(test_mhc_beats_bilinear_on_smooth_colour),
        cmocka_unit_test(test_psnr_rgb_convention),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
