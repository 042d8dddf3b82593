/* tests/unit/test_nerf_adam.c — Adam (per-parameter steps, lazy ranges, extreme gradients) and lr schedules.
 * The optimiser is checked against a straightforward double implementation of the same update (relative 1e-6:
 * float storage of params and moments is the only difference).
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
#include "recon/nerf/adam.h"

static sci_rng RNG_;

static uint64_t test_seed(void)
{
    const char *e = getenv("SCICAP_TEST_SEED");
    uint64_t s = e ? strtoull(e, NULL, 0) : 20240609u;
    printf("seed %llu (set SCICAP_TEST_SEED to replay)\n", (unsigned long long)s);
    return s;
}

static void test_adam_matches_reference(void **s)
{
    (void)s;
    enum { n = 50, steps = 20 };
    nerf_adam_config c = {.beta1 = 0.9, .beta2 = 0.999, .eps = 1e-8, .weight_decay = 1e-3};
    nerf_adam *a;
    assert_int_equal(nerf_adam_new(&a, n, &c, NULL), 0);
    float p[n], g[n];
    double pd[n], m[n] = {0}, v[n] = {0};
    for (int j = 0; j < n; j++) pd[j] = p[j] = (float)sci_rng_normal(&RNG_);
    double worst = 0;
    for (int t = 1; t <= steps; t++) {
        for (int j = 0; j < n; j++) g[j] = (float)sci_rng_normal(&RNG_);
        nerf_adam_step(a, p, g, 0, n, 1e-2, 0, 1);
        for (int j = 0; j < n; j++) {
            double gg = g[j] + 1e-3 * pd[j];
            m[j] = 0.9 * m[j] + 0.1 * gg, v[j] = 0.999 * v[j] + 0.001 * gg * gg;
            pd[j] -= 1e-2 * sqrt(1 - pow(0.999, t)) / (1 - pow(0.9, t)) * m[j] / (sqrt(v[j]) + 1e-8);
            worst = fmax(worst, fabs(p[j] - pd[j]) / fmax(fabs(pd[j]), 1e-3));
        }
    }
    printf("adam vs double reference after %d steps: worst relative difference %.2g\n", steps, worst);
    assert_true(worst < 1e-5);
    for (int j = 0; j < n; j++) assert_int_equal(nerf_adam_steps_of(a, j), steps);
    nerf_adam_free(a);
}

/* Lazy range with sparse gradients: every parameter keeps its own step count and bias correction, also after the
 * state is written back through nerf_adam_buffers with counts far beyond the steps taken (a resumed run). */
static void test_adam_own_step_counts(void **s)
{
    (void)s;
    enum { n = 64, steps = 300 };
    const double b1 = 0.9, b2 = 0.99, eps = 1e-15, lr = 1e-2;
    nerf_adam_config c = {.beta1 = b1, .beta2 = b2, .eps = eps, .weight_decay = 0};
    nerf_adam *a;
    assert_int_equal(nerf_adam_new(&a, n, &c, NULL), 0);
    float p[n], g[n];
    double pd[n], m[n] = {0}, v[n] = {0};
    unsigned t[n] = {0};
    for (int j = 0; j < n; j++) pd[j] = p[j] = (float)sci_rng_normal(&RNG_);
    double worst = 0;
    for (int it = 0; it < steps + 2; it++) {
        if (it == steps) { /* restore: the counts move on by 40,000 (another run's state) */
            float *mm, *ss;
            uint32_t *tt;
            nerf_adam *b;
            assert_int_equal(nerf_adam_new(&b, n, &c, NULL), 0);
            nerf_adam_buffers(b, &mm, &ss, &tt);
            float *am, *as;
            uint32_t *at;
            nerf_adam_buffers(a, &am, &as, &at);
            for (int j = 0; j < n; j++) mm[j] = am[j], ss[j] = as[j], tt[j] = at[j] + 40000, t[j] += 40000;
            nerf_adam_free(a);
            a = b;
        }
        for (int j = 0; j < n; j++) g[j] = sci_rng_uniform(&RNG_) < 0.3 ? (float)sci_rng_normal(&RNG_) : 0.0f;
        nerf_adam_step(a, p, g, 0, n, lr, 1, 0);
        for (int j = 0; j < n; j++) {
            if (g[j] == 0.0f) continue;
            t[j]++;
            m[j] = b1 * m[j] + (1 - b1) * g[j], v[j] = b2 * v[j] + (1 - b2) * (double)g[j] * g[j];
            pd[j] -= lr * sqrt(1 - pow(b2, t[j])) / (1 - pow(b1, t[j])) * m[j] / (sqrt(v[j]) + eps);
            worst = fmax(worst, fabs(p[j] - pd[j]) / fmax(fabs(pd[j]), 1e-3));
        }
    }
    printf("adam, sparse gradients and a restored state: worst relative difference %.2g\n", worst);
    assert_true(worst < 1e-5);
    unsigned lo = ~0u, hi = 0;
    for (int j = 0; j < n; j++) {
        assert_int_equal(nerf_adam_steps_of(a, j), t[j]);
        lo = t[j] < lo ? t[j] : lo, hi = t[j] > hi ? t[j] : hi;
    }
    assert_true(hi > lo); /* the counts did differ */
    nerf_adam_free(a);
}

static void test_adam_zero_gradient(void **s)
{
    (void)s;
    nerf_adam_config c = {.beta1 = 0.9, .beta2 = 0.99, .eps = 1e-15, .weight_decay = 0};
    nerf_adam *a;
    assert_int_equal(nerf_adam_new(&a, 4, &c, NULL), 0);
    float p[4] = {1, 2, 3, 4}, g[4] = {0, 0, 0, 0};
    nerf_adam_step(a, p, g, 0, 2, 1e-2, 1, 0); /* lazy range: skipped entirely */
    nerf_adam_step(a, p, g, 2, 4, 1e-2, 0, 0); /* dense range: step counted, no movement (m = 0) */
    assert_float_equal(p[0], 1, 0), assert_float_equal(p[1], 2, 0), assert_float_equal(p[2], 3, 0), assert_float_equal(p[3], 4, 0);
    assert_int_equal(nerf_adam_steps_of(a, 0), 0);
    assert_int_equal(nerf_adam_steps_of(a, 2), 1);
    /* lazy: a later real gradient gets the bias correction of its own first step (moves by ~lr) */
    g[0] = 0.5f;
    nerf_adam_step(a, p, g, 0, 2, 1e-2, 1, 0);
    assert_float_equal(p[0], 1 - 1e-2, 1e-6);
    assert_float_equal(p[1], 2, 0);
    assert_int_equal(nerf_adam_steps_of(a, 0), 1);
    nerf_adam_free(a);
}

static void test_adam_huge_gradient(void **s)
{
    (void)s;
    nerf_adam_config c = {.beta1 = 0.9, .beta2 = 0.999, .eps = 1e-8, .weight_decay = 0};
    nerf_adam *a;
    assert_int_equal(nerf_adam_new(&a, 2, &c, NULL), 0);
    float p[2] = {0, 0}, g[2] = {1e30f, -1e30f};
    nerf_adam_step(a, p, g, 0, 2, 1e-3, 1, 0);
    printf("after a ±1e30 gradient: %g %g\n", p[0], p[1]);
    assert_true(isfinite(p[0]) && isfinite(p[1]));
    assert_float_equal(p[0], -1e-3, 1e-9);
    assert_float_equal(p[1], 1e-3, 1e-9);
    g[0] = 1.0f, g[1] = -1.0f; /* moments stay finite: later steps still move, in the right direction */
    for (int t = 0; t < 5; t++) nerf_adam_step(a, p, g, 0, 2, 1e-3, 1, 0);
    assert_true(isfinite(p[0]) && isfinite(p[1]));
    assert_true(p[0] < -1e-3 && p[1] > 1e-3);
    nerf_adam_free(a);
}

static void test_adam_config_errors(void **s)
{
    (void)s;
    nerf_adam *a = NULL;
    sci_error err = {0};
    nerf_adam_config c = {.beta1 = 1.0, .beta2 = 0.999, .eps = 1e-8};
    assert_int_equal(nerf_adam_new(&a, 2, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "beta1"));
    c.beta1 = 0.9, c.eps = 0;
    assert_int_equal(nerf_adam_new(&a, 2, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "eps"));
    assert_null(a);
}

static void test_lr_schedule(void **s)
{
    (void)s;
    nerf_lr_schedule sc = {.lr0 = 5e-4, .decay_rate = 0.1, .decay_steps = 200000};
    assert_float_equal(nerf_lr_at(&sc, 0), 5e-4, 1e-18);
    assert_float_equal(nerf_lr_at(&sc, 200000), 5e-5, 1e-15);
    assert_float_equal(nerf_lr_at(&sc, 100000), 5e-4 * sqrt(0.1), 1e-15);
    nerf_lr_schedule w = {.lr0 = 1e-2, .decay_rate = 1, .decay_steps = 0, .warmup_steps = 100, .warmup_start = 0.1};
    assert_float_equal(nerf_lr_at(&w, 0), 1e-3, 1e-15);
    assert_float_equal(nerf_lr_at(&w, 50), 1e-2 * 0.55, 1e-15);
    assert_float_equal(nerf_lr_at(&w, 100), 1e-2, 1e-15);
    assert_float_equal(nerf_lr_at(&w, 5000), 1e-2, 1e-15);
}

int main(void)
{
    sci_rng_seed(&RNG_, test_seed(), 6);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_adam_matches_reference), cmocka_unit_test(test_adam_own_step_counts),
        cmocka_unit_test(test_adam_zero_gradient),
        cmocka_unit_test(test_adam_huge_gradient),     cmocka_unit_test(test_adam_config_errors),
        cmocka_unit_test(test_lr_schedule),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
