/* tests/unit/test_nerf_render.c — volume rendering and losses: gradient checks and the hard cases.
 *
 * Rendering: analytic float backward vs central differences (step 1e-6·max(|x|, 1e-3)) of the double reference
 * nerf_ref_render, norm-wise relative error < 1e-4 (float outputs carry ~1e-7 rounding; the backward itself runs in
 * double). Losses are computed in double from float inputs: the measurement loss is quadratic, so a central
 * difference with a float-representable step is exact up to rounding; TV (ε = 0.05) uses step 2^-12 (truncation ~4e-6).
 */
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
#include "recon/nerf/loss.h"
#include "recon/nerf/ref.h"
#include "recon/nerf/render.h"

static sci_rng RNG_;

static uint64_t test_seed(void)
{
    const char *e = getenv("SCICAP_TEST_SEED");
    uint64_t s = e ? strtoull(e, NULL, 0) : 20240607u;
    printf("seed %llu (set SCICAP_TEST_SEED to replay)\n", (unsigned long long)s);
    return s;
}

static double unif(double a, double b) { return a + (b - a) * sci_rng_uniform(&RNG_); }

enum { NR = 6, L = 16 };

typedef struct rcase {
    double sigma[NR * L], rgb[NR * L * 3], delta[NR * L], t[NR * L], wc[NR * 3], wd[NR], wo[NR];
    int nvalid[NR], use_nvalid;
    double t_stop;
} rcase;

static double rloss(const rcase *c)
{
    double col[NR * 3], dep[NR], op[NR], s = 0;
    nerf_ref_render(NR, L, c->sigma, c->rgb, c->delta, c->t, c->use_nvalid ? c->nvalid : NULL, c->t_stop, col, dep, op);
    for (int k = 0; k < NR; k++) {
        for (int a = 0; a < 3; a++) s += c->wc[3 * k + a] * col[3 * k + a];
        s += c->wd[k] * dep[k] + c->wo[k] * op[k];
    }
    return s;
}

static double fdr(rcase *c, double *v)
{
    double x0 = *v, h = 1e-6 * (fabs(x0) > 1e-3 ? fabs(x0) : 1e-3); /* below 1e-3 a relative step drowns in rounding */
    *v = x0 + h;
    double a = rloss(c);
    *v = x0 - h;
    double b = rloss(c);
    *v = x0;
    return (a - b) / (2 * h);
}

static void run_case(rcase *c, const char *what)
{
    float s[NR * L], rgb[NR * L * 3], d[NR * L], t[NR * L], col[NR * 3], dep[NR], op[NR];
    float wc[NR * 3], wd[NR], wo[NR], ds[NR * L], drgb[NR * L * 3], dd[NR * L];
    for (int i = 0; i < NR * L; i++) {
        s[i] = (float)c->sigma[i], d[i] = (float)c->delta[i], t[i] = (float)c->t[i];
        c->sigma[i] = s[i], c->delta[i] = d[i], c->t[i] = t[i];
    }
    for (int i = 0; i < NR * L * 3; i++) rgb[i] = (float)c->rgb[i], c->rgb[i] = rgb[i];
    for (int k = 0; k < NR; k++) {
        for (int a = 0; a < 3; a++) wc[3 * k + a] = (float)c->wc[3 * k + a], c->wc[3 * k + a] = wc[3 * k + a];
        wd[k] = (float)c->wd[k], c->wd[k] = wd[k], wo[k] = (float)c->wo[k], c->wo[k] = wo[k];
    }
    nerf_render_rays r = {.n_rays = NR, .L = L, .sigma = s, .rgb = rgb, .delta = d, .t = t,
                          .n_valid = c->use_nvalid ? c->nvalid : NULL, .t_stop = (float)c->t_stop};
    int used[NR];
    nerf_render_forward(&r, col, dep, op, used);
    nerf_render_backward(&r, wc, wd, wo, ds, drgb, dd);
    double rc[NR * 3], rd[NR], ro[NR], fn = 0, fe = 0;
    nerf_ref_render(NR, L, c->sigma, c->rgb, c->delta, c->t, r.n_valid, c->t_stop, rc, rd, ro);
    for (int k = 0; k < NR; k++) {
        for (int a = 0; a < 3; a++) fe += pow(col[3 * k + a] - rc[3 * k + a], 2), fn += rc[3 * k + a] * rc[3 * k + a];
        fe += pow(dep[k] - rd[k], 2) + pow(op[k] - ro[k], 2), fn += rd[k] * rd[k] + ro[k] * ro[k];
        assert_true(isfinite(col[3 * k]) && isfinite(dep[k]) && isfinite(op[k]));
    }
    double num = 0, den = 0;
    for (int i = 0; i < NR * L; i++) {
        assert_true(isfinite(ds[i]) && isfinite(dd[i]));
        double g = fdr(c, &c->sigma[i]);
        if (getenv("NERF_DEBUG") && fabs(ds[i] - g) > 1e-3 * fabs(g)) printf("  sigma %d: %g vs %g (sigma %g delta %g)\n", i, ds[i], g, c->sigma[i], c->delta[i]);
        num += (ds[i] - g) * (ds[i] - g), den += g * g;
        g = fdr(c, &c->delta[i]);
        if (getenv("NERF_DEBUG") && fabs(dd[i] - g) > 1e-3 * fabs(g)) printf("  delta %d: %g vs %g (sigma %g delta %g)\n", i, dd[i], g, c->sigma[i], c->delta[i]);
        num += (dd[i] - g) * (dd[i] - g), den += g * g;
        for (int a = 0; a < 3; a++) {
            assert_true(isfinite(drgb[3 * i + a]));
            g = fdr(c, &c->rgb[3 * i + a]);
            num += (drgb[3 * i + a] - g) * (drgb[3 * i + a] - g), den += g * g;
        }
    }
    double fr = fn > 0 ? sqrt(fe / fn) : sqrt(fe), gr = den > 0 ? sqrt(num / den) : sqrt(num);
    printf("render %-28s forward %.2g, gradient %.2g (samples marched:", what, fr, gr);
    for (int k = 0; k < NR; k++) printf(" %d", used[k]);
    printf(")\n");
    assert_true(fr < 1e-6);
    assert_true(gr < 1e-4);
}

static void fill(rcase *c, double smax, double dlo, double dhi, int logd)
{
    memset(c, 0, sizeof *c);
    for (int k = 0; k < NR; k++) {
        double tt = 2.0;
        for (int i = 0; i < L; i++) {
            int j = k * L + i;
            c->sigma[j] = unif(0, smax);
            c->delta[j] = logd ? exp(unif(log(dlo), log(dhi))) : unif(dlo, dhi);
            c->t[j] = tt, tt += c->delta[j];
            for (int a = 0; a < 3; a++) c->rgb[3 * j + a] = unif(0, 1);
        }
        for (int a = 0; a < 3; a++) c->wc[3 * k + a] = unif(-1, 1);
        c->wd[k] = unif(-1, 1), c->wo[k] = unif(-1, 1);
    }
}

static void test_render_random(void **s)
{
    (void)s;
    rcase c;
    fill(&c, 3, 0.01, 0.1, 0);
    c.t_stop = 0;
    run_case(&c, "random, full march");
    fill(&c, 3, 0.01, 0.1, 0);
    c.t_stop = 1e-4;
    run_case(&c, "random, t_stop 1e-4");
}

static void test_render_sigma_zero(void **s)
{
    (void)s;
    rcase c;
    fill(&c, 0, 0.01, 0.1, 0);
    c.t_stop = 1e-4;
    run_case(&c, "sigma = 0 everywhere");
}

static void test_render_opaque(void **s)
{
    (void)s;
    rcase c;
    fill(&c, 3, 0.01, 0.1, 0);
    for (int i = 0; i < NR * L; i++) c.sigma[i] = 1e6;
    c.t_stop = 1e-4;
    run_case(&c, "sigma = 1e6 (opaque)");
    /* the colour is the first sample's exactly */
    float sg[L], rgb[L * 3], d[L], col[3];
    for (int i = 0; i < L; i++) sg[i] = 1e6f, d[i] = 0.01f, rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = (float)i / L;
    rgb[0] = 0.25f, rgb[1] = 0.5f, rgb[2] = 0.75f;
    nerf_render_rays r = {.n_rays = 1, .L = L, .sigma = sg, .rgb = rgb, .delta = d, .t_stop = 1e-4f};
    int used;
    nerf_render_forward(&r, col, NULL, NULL, &used);
    assert_int_equal(used, 1);
    assert_float_equal(col[0], 0.25f, 0), assert_float_equal(col[1], 0.5f, 0), assert_float_equal(col[2], 0.75f, 0);
}

static void test_render_delta_range(void **s)
{
    (void)s;
    rcase c;
    fill(&c, 3, 1e-8, 1e3, 1);
    c.t_stop = 0;
    run_case(&c, "delta 1e-8 … 1e3");
    /* tiny δ: α = −expm1(−τ) keeps full precision where 1 − exp(−τ) would give 0 in float */
    float sg = 1.0f, rgb[3] = {1, 1, 1}, d = 1e-8f, op;
    nerf_render_rays r = {.n_rays = 1, .L = 1, .sigma = &sg, .rgb = rgb, .delta = &d, .t_stop = 0};
    nerf_render_forward(&r, rgb, NULL, &op, NULL);
    assert_float_equal(op, 1e-8f, 1e-15);
}

static void test_render_early_end(void **s)
{
    (void)s;
    rcase c;
    fill(&c, 1, 0.01, 0.1, 0);
    c.use_nvalid = 1;
    for (int k = 0; k < NR; k++) c.nvalid[k] = k * 3; /* 0, 3, 6, … valid samples */
    c.t_stop = 1e-4;
    run_case(&c, "rays with 0 … 15 valid samples");
    fill(&c, 1, 0.01, 0.1, 0);
    for (int k = 0; k < NR; k++) c.sigma[k * L + 4] = 2000.0; /* wall at sample 4: early termination */
    c.t_stop = 1e-4;
    run_case(&c, "early termination (wall)");
}

/* ------------------------------------------------------------------ losses */

static void test_loss_measurement(void **s)
{
    (void)s;
    enum { P = 10, N = 4, CH = 3 };
    float Y[P * CH], M[N * P], C[N * P * CH], dC[N * P * CH] = {0};
    for (int i = 0; i < P * CH; i++) Y[i] = (float)unif(0, 3);
    for (int i = 0; i < N * P; i++) M[i] = (float)(sci_rng_below(&RNG_, 2));
    for (int i = 0; i < N * P * CH; i++) C[i] = (float)unif(0, 1);
    double L0 = nerf_loss_measurement(P, N, CH, Y, M, C, dC);
    double num = 0, den = 0, ref = 0;
    for (int p = 0; p < P; p++)
        for (int a = 0; a < CH; a++) {
            double r = Y[p * CH + a];
            for (int i = 0; i < N; i++) r -= (double)M[i * P + p] * C[(i * P + p) * CH + a];
            ref += r * r;
        }
    assert_true(fabs(L0 - ref) <= 1e-12 * ref);
    for (int i = 0; i < N * P * CH; i++) {
        float c0 = C[i];
        C[i] = c0 + 0.0625f;
        double a = nerf_loss_measurement(P, N, CH, Y, M, C, NULL);
        C[i] = c0 - 0.0625f;
        double b = nerf_loss_measurement(P, N, CH, Y, M, C, NULL);
        C[i] = c0;
        double g = (a - b) / 0.125;
        num += (dC[i] - g) * (dC[i] - g), den += g * g;
    }
    printf("measurement loss gradient %.2g\n", sqrt(num / den));
    assert_true(sqrt(num / den) < 1e-4);
}

static void test_loss_tv(void **s)
{
    (void)s;
    enum { Q = 2, W = 4, H = 3, CH = 3, n = Q * W * H * CH };
    float C[n], dC[n] = {0};
    for (int i = 0; i < n; i++) C[i] = (float)unif(0, 1);
    double tv = nerf_loss_tv(Q, W, H, CH, C, 5e-2, 0.5, dC);
    assert_true(tv > 0);
    double num = 0, den = 0;
    for (int i = 0; i < n; i++) {
        float c0 = C[i];
        C[i] = c0 + 0x1p-12f;
        double hp = (double)C[i] - c0;
        double a = nerf_loss_tv(Q, W, H, CH, C, 5e-2, 0.5, NULL);
        C[i] = c0 - 0x1p-12f;
        double hm = c0 - (double)C[i];
        double b = nerf_loss_tv(Q, W, H, CH, C, 5e-2, 0.5, NULL);
        C[i] = c0;
        double g = (a - b) / (hp + hm);
        num += (dC[i] - g) * (dC[i] - g), den += g * g;
    }
    printf("TV (eps 5e-2) gradient %.2g\n", sqrt(num / den));
    assert_true(sqrt(num / den) < 1e-4);
    /* ε = 0: plain anisotropic TV of a known patch; constant patch gives 0 and zero gradient */
    float K[4] = {0, 1, 3, 6}, dK[4] = {0};
    assert_float_equal(nerf_loss_tv(1, 2, 2, 1, K, 0, 1, dK), 1 + 3 + 3 + 5, 1e-12);
    float Z[4] = {2, 2, 2, 2}, dZ[4] = {0};
    assert_float_equal(nerf_loss_tv(1, 2, 2, 1, Z, 0, 1, dZ), 0, 0);
    for (int i = 0; i < 4; i++) assert_float_equal(dZ[i], 0, 0);
}

/* Distortion loss: gradient w.r.t. σ against central differences in σ; a ray whose weight sits in one bin beats
 * the same total weight spread over the ray (fog); σ = 0 gives 0; extreme σ and δ stay finite. */
static void test_loss_distortion(void **s)
{
    (void)s;
    enum { NRAY = 3, LS = 12, n = NRAY * LS };
    float sg[n], dl[n], ds[n] = {0};
    for (int i = 0; i < n; i++) sg[i] = (float)unif(0.05, 3), dl[i] = (float)unif(0.05, 0.4);
    double ld = nerf_loss_distortion(NRAY, LS, sg, dl, 0.7, ds);
    assert_true(ld > 0 && isfinite(ld));
    double num = 0, den = 0;
    for (int i = 0; i < n; i++) {
        float s0 = sg[i], h = 0x1p-10f * fmaxf(1.0f, s0);
        sg[i] = s0 + h;
        double hp = (double)sg[i] - s0, a = nerf_loss_distortion(NRAY, LS, sg, dl, 0.7, NULL);
        sg[i] = s0 - h;
        double hm = s0 - (double)sg[i], b = nerf_loss_distortion(NRAY, LS, sg, dl, 0.7, NULL);
        sg[i] = s0;
        double g = (a - b) / (hp + hm);
        num += (ds[i] - g) * (ds[i] - g), den += g * g;
    }
    printf("distortion gradient %.2g\n", sqrt(num / den));
    assert_true(sqrt(num / den) < 1e-3);
    /* a surface (all weight in bin 5) against fog (opacity 0.91 spread along the ray) */
    float surf[LS] = {0}, fog[LS], one[LS];
    surf[5] = 50;
    for (int i = 0; i < LS; i++) fog[i] = 0.2f, one[i] = 1; /* optical depth 2.4 spread along the ray */
    double ls = nerf_loss_distortion(1, LS, surf, one, 1, NULL), lf = nerf_loss_distortion(1, LS, fog, one, 1, NULL);
    printf("distortion: surface %.4g, fog %.4g\n", ls, lf);
    assert_true(ls < 0.2 * lf);
    assert_float_equal(ls, 1.0 / (3 * LS), 1e-6); /* w = 1 in one bin: only the self term (1/3)·w²/LS */
    float zero[LS] = {0}, dz[LS] = {0};
    assert_float_equal(nerf_loss_distortion(1, LS, zero, one, 1, dz), 0, 0);
    for (int i = 0; i < LS; i++) assert_float_equal(dz[i], 0, 0);
    /* hard cases: σ 1e30 (opaque at once), δ 1e-30 … 1e6, a ray longer than the stack buffer */
    enum { LL = 300 };
    float big[LL], dd[LL], dg[LL] = {0};
    for (int i = 0; i < LL; i++) big[i] = i % 7 == 0 ? 1e30f : 1e-3f, dd[i] = i % 2 ? 1e-30f : 1e6f;
    double lb = nerf_loss_distortion(1, LL, big, dd, 1, dg);
    assert_true(isfinite(lb));
    for (int i = 0; i < LL; i++) assert_true(isfinite(dg[i]));
}

int main(void)
{
    sci_rng_seed(&RNG_, test_seed(), 4);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_render_random),      cmocka_unit_test(test_render_sigma_zero),
        cmocka_unit_test(test_render_opaque),      cmocka_unit_test(test_render_delta_range),
        cmocka_unit_test(test_render_early_end),   cmocka_unit_test(test_loss_measurement),
        cmocka_unit_test(test_loss_tv),            cmocka_unit_test(test_loss_distortion),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
