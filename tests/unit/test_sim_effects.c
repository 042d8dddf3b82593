/* The physics of each simulator effect (sim/effects.h), one property per test, on hand-made truth and masks. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "base/rng.h"
#include "recon/sci_ops.h"
#include "sim/effects.h"

static uint64_t test_seed(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    uint64_t seed = s ? strtoull(s, NULL, 0) : 20261121;
    printf("seed %llu (set SCICAP_TEST_SEED to change)\n", (unsigned long long)seed);
    return seed;
}

static sim_effects_spec spec_default(int n, int bits)
{
    sim_effects_spec s = {0};
    s.motion_samples = 8;
    s.blur_sigma_px = 1.5;
    s.vignetting_corner = 0.5;
    s.leakage = 0.01;
    s.fill_factor = 0.9;
    s.jitter_sigma = 0.2;
    s.dark_e = 10;
    s.read_sigma_e = 3;
    s.photons_white = 1000;
    s.full_well_e = 1000.0 * n;
    s.bit_depth = bits;
    s.gain_e_per_dn = s.full_well_e / ((1 << bits) - 1);
    return s;
}

static sci_cube *cube(int w, int h, int n, float v)
{
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, w, h, n, NULL), 0);
    for (size_t i = 0; i < sci_cube_count(c); i++)
        c->data[i] = v;
    return c;
}

static sci_cube *random_cube(int w, int h, int n, uint64_t seed, uint64_t stream, int binary)
{
    sci_cube *c = cube(w, h, n, 0);
    sci_rng r;
    sci_rng_seed(&r, seed, stream);
    for (size_t i = 0; i < sci_cube_count(c); i++)
        c->data[i] = binary ? (sci_rng_uniform(&r) < 0.5) : sci_rng_uniformf(&r);
    return c;
}

static void measure(const sim_effects_spec *s, int snapshot, uint64_t seed, const sci_cube *x, const sci_cube *m,
                    sci_cube *y, sim_stats *st)
{
    sim_effects *fx;
    sci_error err = {0};
    assert_int_equal(sim_effects_new(&fx, s, x->w, x->h, x->n, seed, &err), 0);
    int rc = sim_effects_measure(fx, snapshot, x, m, NULL, NULL, y, st, &err);
    if (rc < 0)
        fail_msg("%s", err.msg);
    sim_effects_free(fx);
}

/* Shot noise: electrons ~ Poisson(λ), so over many pixels of one level, mean and variance both equal λ. */
static void test_poisson_mean_equals_variance(void **state)
{
    uint64_t seed = test_seed();
    const int w = 256, h = 256;
    double levels[] = {3.0, 50.0, 400.0};
    for (int li = 0; li < 3; li++) {
        sim_effects_spec s = spec_default(1, 16);
        s.listed = 1u << SIM_FX_SHOT_NOISE;
        s.photons_white = levels[li]; /* white frame through an open mask: λ electrons */
        sci_cube *x = cube(w, h, 1, 1), *m = cube(w, h, 1, 1), *y = cube(w, h, 1, 0);
        measure(&s, 0, seed, x, m, y, NULL);
        double sum = 0, sum2 = 0, N = (double)w * h;
        for (size_t i = 0; i < sci_cube_count(y); i++) {
            double e = y->data[i] * s.photons_white;
            assert_true(fabs(e - nearbyint(e)) < 1e-3 * fmax(1, e)); /* whole electrons */
            sum += e;
            sum2 += e * e;
        }
        double mean = sum / N, var = sum2 / N - mean * mean, lam = levels[li];
        /* 5 standard errors: se(mean) = sqrt(λ/N); se(var) ≈ λ·sqrt(2/N) (+ 1/N·λ for the excess kurtosis). */
        double se_m = sqrt(lam / N), se_v = sqrt((2 * lam * lam + lam) / N);
        printf("λ = %g: mean %.4f (±%.4f) variance %.4f (±%.4f)\n", lam, mean, se_m, var, se_v);
        assert_true(fabs(mean - lam) < 5 * se_m);
        assert_true(fabs(var - lam) < 5 * se_v);
        assert_true(fabs(var / mean - 1) < 0.05);
        sci_cube_free(x);
        sci_cube_free(m);
        sci_cube_free(y);
    }
}

/* A Gaussian and an image PSF both conserve the total energy of content that stays away from the edges. */
static void test_blur_conserves_energy(void **state)
{
    uint64_t seed = test_seed();
    const int w = 96, h = 80, n = 3;
    sci_cube *x = cube(w, h, n, 0), *m = cube(w, h, n, 1), *y = cube(w, h, 1, 0), *y0 = cube(w, h, 1, 0);
    sci_rng r;
    sci_rng_seed(&r, seed, 1);
    for (int k = 0; k < n; k++) /* content in the interior: border of 20 px > kernel radius (3.5σ ≤ 11) */
        for (int yy = 20; yy < h - 20; yy++)
            for (int xx = 20; xx < w - 20; xx++)
                sci_cube_frame(x, k)[yy * w + xx] = sci_rng_uniformf(&r);
    sim_effects_spec none = spec_default(n, 12);
    measure(&none, 0, seed, x, m, y0, NULL);
    double e0 = 0;
    for (size_t i = 0; i < sci_cube_count(y0); i++)
        e0 += y0->data[i];
    double sigmas[] = {0.6, 1.5, 3.0};
    for (int si = 0; si < 3; si++) {
        sim_effects_spec s = spec_default(n, 12);
        s.listed = 1u << SIM_FX_BLUR;
        s.blur_sigma_px = sigmas[si];
        measure(&s, 0, seed, x, m, y, NULL);
        double e = 0, diff = 0;
        for (size_t i = 0; i < sci_cube_count(y); i++) {
            e += y->data[i];
            diff += fabs(y->data[i] - y0->data[i]);
        }
        printf("sigma %.1f px: energy %.6f vs %.6f (rel %.2e), changed by %.1f\n", sigmas[si], e, e0,
               fabs(e - e0) / e0, diff);
        assert_true(fabs(e - e0) / e0 < 1e-5);
        assert_true(diff > 1); /* it did blur */
    }
    /* An asymmetric image PSF (normalised by the parser; here by hand). */
    sim_effects_spec s = spec_default(n, 12);
    s.listed = 1u << SIM_FX_BLUR;
    sci_cube *psf = cube(5, 3, 1, 0);
    float taps[15] = {0, 1, 2, 0, 0, 1, 4, 6, 1, 0, 0, 0, 3, 2, 0};
    for (int i = 0; i < 15; i++)
        psf->data[i] = taps[i] / 20.0f;
    s.psf = psf;
    measure(&s, 0, seed, x, m, y, NULL);
    double e = 0;
    for (size_t i = 0; i < sci_cube_count(y); i++)
        e += y->data[i];
    printf("image PSF: energy %.6f vs %.6f\n", e, e0);
    assert_true(fabs(e - e0) / e0 < 1e-5);
    sci_cube_free(psf);
    sci_cube_free(x);
    sci_cube_free(m);
    sci_cube_free(y);
    sci_cube_free(y0);
}

/* Quantization: |y' − y| ≤ half a step (step = gain/photons on the measurement scale) inside the ADC range. */
static void test_quantization_half_step(void **state)
{
    uint64_t seed = test_seed();
    const int w = 128, h = 128, n = 8;
    int depths[] = {4, 8, 12};
    for (int di = 0; di < 3; di++) {
        sim_effects_spec s = spec_default(n, depths[di]);
        s.listed = 1u << SIM_FX_QUANTIZATION;
        sci_cube *x = random_cube(w, h, n, seed, 2, 0), *m = random_cube(w, h, n, seed, 3, 1);
        sci_cube *y0 = cube(w, h, 1, 0), *y = cube(w, h, 1, 0);
        sci_op_forward(m, x, y0);
        measure(&s, 0, seed, x, m, y, NULL);
        double step = s.gain_e_per_dn / s.photons_white, worst = 0;
        long on_grid = 0;
        for (size_t i = 0; i < sci_cube_count(y); i++) {
            worst = fmax(worst, fabs((double)y->data[i] - y0->data[i]));
            double q = y->data[i] / step;
            on_grid += fabs(q - nearbyint(q)) < 1e-3;
        }
        printf("%d bits: step %.5f, worst error %.5f (%.3f steps), %ld/%zu on the grid\n", depths[di], step, worst,
               worst / step, on_grid, sci_cube_count(y));
        assert_true(worst <= 0.5 * step * (1 + 1e-5));
        assert_int_equal(on_grid, (long)sci_cube_count(y));
        sci_cube_free(x);
        sci_cube_free(m);
        sci_cube_free(y0);
        sci_cube_free(y);
    }
}

/* Saturation: values above the full well become exactly full_well/photons; values below are untouched. */
static void test_saturation_clamps(void **state)
{
    uint64_t seed = test_seed();
    const int w = 64, h = 64, n = 8;
    sim_effects_spec s = spec_default(n, 12);
    s.listed = 1u << SIM_FX_SATURATION;
    s.full_well_e = 3000; /* 3 white sub-frames */
    sci_cube *x = random_cube(w, h, n, seed, 4, 0), *m = random_cube(w, h, n, seed, 5, 1);
    sci_cube *y0 = cube(w, h, 1, 0), *y = cube(w, h, 1, 0);
    sci_op_forward(m, x, y0);
    measure(&s, 0, seed, x, m, y, NULL);
    float cap = (float)(s.full_well_e / s.photons_white);
    long clamped = 0;
    for (size_t i = 0; i < sci_cube_count(y); i++) {
        if (y0->data[i] > cap) {
            assert_true(y->data[i] == cap);
            clamped++;
        } else
            assert_true(y->data[i] == y0->data[i]);
    }
    printf("%ld of %zu pixels clamped at %.3f\n", clamped, sci_cube_count(y), cap);
    assert_true(clamped > 0 && clamped < (long)sci_cube_count(y));
    sci_cube_free(x);
    sci_cube_free(m);
    sci_cube_free(y0);
    sci_cube_free(y);
}

/* An integer misregistration (dx, dy) equals the forward model under masks shifted by (dx, dy) with dark borders. */
static void test_integer_misregistration_is_a_shift(void **state)
{
    uint64_t seed = test_seed();
    const int w = 40, h = 30, n = 4;
    int shifts[][2] = {{2, -1}, {-3, 0}, {0, 5}, {0, 0}};
    sci_cube *x = random_cube(w, h, n, seed, 6, 0), *m = random_cube(w, h, n, seed, 7, 1);
    for (int t = 0; t < 4; t++) {
        int dx = shifts[t][0], dy = shifts[t][1];
        sim_effects_spec s = spec_default(n, 12);
        s.listed = 1u << SIM_FX_MISREGISTRATION;
        s.misreg_dx_px = dx;
        s.misreg_dy_px = dy;
        s.misreg_rotation_rad = 0;
        sci_cube *ms = cube(w, h, n, 0), *ye = cube(w, h, 1, 0), *y = cube(w, h, 1, 0);
        for (int k = 0; k < n; k++)
            for (int yy = 0; yy < h; yy++)
                for (int xx = 0; xx < w; xx++) {
                    int sx = xx - dx, sy = yy - dy;
                    if (sx >= 0 && sx < w && sy >= 0 && sy < h)
                        sci_cube_frame(ms, k)[yy * w + xx] = sci_cube_frame(m, k)[sy * w + sx];
                }
        sci_op_forward(ms, x, ye);
        measure(&s, 0, seed, x, m, y, NULL);
        assert_memory_equal(y->data, ye->data, sci_cube_count(y) * sizeof(float));
        printf("shift (%d, %d): equals the shifted masks bit for bit\n", dx, dy);
        sci_cube_free(ms);
        sci_cube_free(ye);
        sci_cube_free(y);
    }
    /* A half-pixel shift is not a shift of whole pixels: it must differ. */
    sim_effects_spec s = spec_default(n, 12);
    s.listed = 1u << SIM_FX_MISREGISTRATION;
    s.misreg_dx_px = 0.5;
    sci_cube *y = cube(w, h, 1, 0), *y0 = cube(w, h, 1, 0);
    sci_op_forward(m, x, y0);
    measure(&s, 0, seed, x, m, y, NULL);
    assert_memory_not_equal(y->data, y0->data, sci_cube_count(y) * sizeof(float));
    sci_cube_free(y);
    sci_cube_free(y0);
    sci_cube_free(x);
    sci_cube_free(m);
}

/* Jitter redistributes exposure between masks but keeps the total: weights sum to N, and a white scene under
 * open masks still measures N everywhere. */
static void test_jitter_keeps_total_exposure(void **state)
{
    uint64_t seed = test_seed();
    const int w = 32, h = 32, n = 8;
    sim_effects_spec s = spec_default(n, 12);
    s.listed = 1u << SIM_FX_JITTER;
    s.jitter_sigma = 0.3;
    double wk[8];
    for (int snap = 0; snap < 20; snap++) {
        sim_effects_jitter_weights(&s, seed, snap, n, wk, NULL);
        double sum = 0, dev = 0;
        for (int k = 0; k < n; k++) {
            sum += wk[k];
            dev = fmax(dev, fabs(wk[k] - 1));
            assert_true(wk[k] >= 0);
        }
        assert_true(fabs(sum - n) < 1e-12);
        assert_true(dev > 1e-3); /* the shares really vary */
    }
    sci_cube *x = cube(w, h, n, 1), *m = cube(w, h, n, 1), *y = cube(w, h, 1, 0);
    measure(&s, 3, seed, x, m, y, NULL);
    for (size_t i = 0; i < sci_cube_count(y); i++)
        assert_true(fabs(y->data[i] - n) < 1e-5);
    /* ... while a scene that changes over time does measure differently. */
    sci_cube *xv = random_cube(w, h, n, seed, 8, 0), *y0 = cube(w, h, 1, 0);
    sci_op_forward(m, xv, y0);
    measure(&s, 3, seed, xv, m, y, NULL);
    assert_memory_not_equal(y->data, y0->data, sci_cube_count(y) * sizeof(float));
    printf("jitter: Σw = N for 20 snapshots; white scene measures N exactly\n");
    sci_cube_free(x);
    sci_cube_free(xv);
    sci_cube_free(m);
    sci_cube_free(y);
    sci_cube_free(y0);
}

/* DMD contrast: a closed mirror passes fill·leakage, an open one fill. Vignetting: centre 1, corner `corner`. */
static void test_contrast_and_vignetting(void **state)
{
    const int w = 64, h = 48, n = 2;
    sim_effects_spec s = spec_default(n, 12);
    s.listed = 1u << SIM_FX_DMD_CONTRAST;
    sci_cube *x = cube(w, h, n, 1), *m = cube(w, h, n, 0), *y = cube(w, h, 1, 0);
    for (int i = 0; i < w * h; i++)
        m->data[i] = 1; /* frame 0 open, frame 1 closed */
    measure(&s, 0, 1, x, m, y, NULL);
    double expect = s.fill_factor + s.fill_factor * s.leakage;
    for (size_t i = 0; i < sci_cube_count(y); i++)
        assert_true(fabs(y->data[i] - expect) < 1e-6);
    s.listed = 1u << SIM_FX_VIGNETTING;
    s.vignetting_corner = 0.5;
    for (size_t i = 0; i < sci_cube_count(m); i++)
        m->data[i] = 1;
    measure(&s, 0, 1, x, m, y, NULL);
    /* Pixel centres nearest the middle and the corner. */
    double c = y->data[(h / 2) * w + w / 2] / n, corner = y->data[0] / n;
    printf("vignetting: centre %.4f, corner pixel %.4f (corner of the frame 0.5)\n", c, corner);
    assert_true(c > 0.999 && c <= 1.0);
    assert_true(corner > 0.5 && corner < 0.53);
    sci_cube_free(x);
    sci_cube_free(m);
    sci_cube_free(y);
}

/* Read noise and dark offset in electrons: mean shift dark_e, standard deviation sigma_e. */
static void test_read_noise_and_dark(void **state)
{
    uint64_t seed = test_seed();
    const int w = 256, h = 128, n = 1;
    sim_effects_spec s = spec_default(n, 12);
    s.listed = (1u << SIM_FX_READ_NOISE) | (1u << SIM_FX_DARK_OFFSET);
    s.read_sigma_e = 4;
    s.dark_e = 25;
    sci_cube *x = cube(w, h, n, 0.5), *m = cube(w, h, n, 1), *y = cube(w, h, 1, 0);
    measure(&s, 0, seed, x, m, y, NULL);
    double sum = 0, sum2 = 0, N = (double)w * h;
    for (size_t i = 0; i < sci_cube_count(y); i++) {
        double e = y->data[i] * s.photons_white - 500;
        sum += e;
        sum2 += e * e;
    }
    double mean = sum / N, sd = sqrt(sum2 / N - mean * mean);
    printf("dark + read: mean %.3f e (expect 25), sd %.3f e (expect 4)\n", mean, sd);
    assert_true(fabs(mean - 25) < 5 * 4 / sqrt(N));
    assert_true(fabs(sd - 4) < 5 * 4 / sqrt(2 * N));
    sci_cube_free(x);
    sci_cube_free(m);
    sci_cube_free(y);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_poisson_mean_equals_variance),
        cmocka_unit_test(test_blur_conserves_energy),
        cmocka_unit_test(test_quantization_half_step),
        cmocka_unit_test(test_saturation_clamps),
        cmocka_unit_test(test_integer_misregistration_is_a_shift),
        cmocka_unit_test(test_jitter_keeps_total_exposure),
        cmocka_unit_test(test_contrast_and_vignetting),
        cmocka_unit_test(test_read_noise_and_dark),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
