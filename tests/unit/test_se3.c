/* tests/unit/test_se3.c — base/se3.h, the one SE(3) implementation of sim/ and recon/: exp/log round trips at
 * tiny angles, across the Taylor switch and near π (where the log must stay exact), the tie-breaks of the
 * quaternion pivot, the geodesic's exact ends, aliasing, and exp against a reference matrix exponential. */
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
#include "base/se3.h"
#include "tests/helpers/nerf_scene.h"

static double maxdiff(const double *a, const double *b, int n)
{
    double m = 0;
    for (int i = 0; i < n; i++)
        m = fmax(m, fabs(a[i] - b[i]));
    return m;
}

/* exp([ω]×) by its power series in long double (80-bit here): a reference independent of the closed forms. */
static void rot_ref(const double w[3], double R[9])
{
    long double W[9] = {0, -w[2], w[1], w[2], 0, -w[0], -w[1], w[0], 0}, P[9], S[9];
    for (int i = 0; i < 9; i++)
        P[i] = S[i] = i % 4 == 0;
    for (int k = 1; k < 60; k++) {
        long double Q[9];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                Q[3 * i + j] = (P[3 * i] * W[j] + P[3 * i + 1] * W[3 + j] + P[3 * i + 2] * W[6 + j]) / k;
        for (int i = 0; i < 9; i++)
            P[i] = Q[i], S[i] += Q[i];
    }
    for (int i = 0; i < 9; i++)
        R[i] = (double)S[i];
}

static void random_twist(sci_rng *r, double angle, double xi[6])
{
    double a[3], n = 0;
    for (int i = 0; i < 3; i++)
        a[i] = sci_rng_normal(r), n += a[i] * a[i];
    for (int i = 0; i < 3; i++)
        xi[i] = a[i] / sqrt(n) * angle, xi[3 + i] = 2 * sci_rng_uniform(r) - 1;
}

/* Angles from 0 to π − 1e-9, both sides of the Taylor switch: R matches the reference, log(exp(ξ)) = ξ. */
static void test_round_trip_and_reference(void **state)
{
    (void)state;
    const unsigned long long seed = test_seed_env(11);
    printf("seed %llu\n", seed);
    sci_rng r;
    sci_rng_seed(&r, seed, 1);
    const double angles[] = {0, 1e-300, 1e-12, 1e-8, 1e-4, 0.05, SCI_SE3_TAYLOR_THETA * (1 - 1e-12),
                             SCI_SE3_TAYLOR_THETA, SCI_SE3_TAYLOR_THETA * (1 + 1e-12), 0.5, 2, 3, M_PI - 1e-3,
                             M_PI - 1e-6, M_PI - 1e-9};
    double worst_r = 0, worst_xi = 0, worst_rel_pi = 0;
    for (size_t a = 0; a < sizeof angles / sizeof angles[0]; a++)
        for (int t = 0; t < 40; t++) {
            double xi[6], T[12], R[9], Rr[9], back[6];
            random_twist(&r, angles[a], xi);
            sci_se3_exp(xi, T, NULL);
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    R[3 * i + j] = T[4 * i + j];
            rot_ref(xi, Rr);
            worst_r = fmax(worst_r, maxdiff(R, Rr, 9));
            double Ro[9];
            sci_se3_rot_exp(xi, Ro);
            assert_memory_equal(Ro, R, sizeof R); /* one rotation formula */
            sci_se3_log(T, back);
            const double e = maxdiff(back, xi, 6);
            worst_xi = fmax(worst_xi, e);
            if (angles[a] > 3)
                worst_rel_pi = fmax(worst_rel_pi, e);
        }
    printf("R against the series: worst %.3g; log(exp(xi)) - xi: worst %.3g (near pi: %.3g)\n", worst_r, worst_xi,
           worst_rel_pi);
    assert_true(worst_r < 1e-14);
    /* near π the log's conditioning is 1/sin(θ/2)-free (quaternion), so even π − 1e-9 round-trips to ~1e-7 */
    assert_true(worst_xi < 1e-6);
    assert_true(worst_rel_pi < 1e-6);
}

/* The coefficients are continuous across the Taylor switch: exp just below and just above agree to rounding. */
static void test_taylor_switch_is_continuous(void **state)
{
    (void)state;
    const double th = SCI_SE3_TAYLOR_THETA;
    double lo[6] = {nextafter(th, 0), 0, 0, 0.3, -0.2, 0.1}, hi[6] = {th, 0, 0, 0.3, -0.2, 0.1}, Tl[12], Th[12];
    double Jl[72], Jh[72];
    sci_se3_exp(lo, Tl, Jl);
    sci_se3_exp(hi, Th, Jh);
    printf("exp across the switch: %.3g, Jacobian %.3g\n", maxdiff(Tl, Th, 12), maxdiff(Jl, Jh, 72));
    assert_true(maxdiff(Tl, Th, 12) < 1e-14);
    assert_true(maxdiff(Jl, Jh, 72) < 1e-12);
    double zero[6] = {0}, T0[12], I[12];
    sci_se3_exp(zero, T0, NULL);
    sci_se3_identity(I);
    assert_memory_equal(T0, I, sizeof I);
    double xi0[6];
    sci_se3_log(I, xi0);
    for (int i = 0; i < 6; i++)
        assert_true(xi0[i] == 0);
}

/* θ = π exactly (the log's sign choice) and the pivot's ties: exp(log(T)) = T whichever branch is taken. */
static void test_pi_and_pivot_ties(void **state)
{
    (void)state;
    /* half turns about x, y, z and a diagonal axis: ω and −ω are the same rotation; the log must return one of
     * them with θ = π */
    const double axes[4][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1 / M_SQRT2, 0, 1 / M_SQRT2}};
    for (int a = 0; a < 4; a++) {
        double xi[6] = {M_PI * axes[a][0], M_PI * axes[a][1], M_PI * axes[a][2], 0.5, -1, 2}, T[12], back[6], T2[12];
        sci_se3_exp(xi, T, NULL);
        sci_se3_log(T, back);
        const double th = sqrt(back[0] * back[0] + back[1] * back[1] + back[2] * back[2]);
        sci_se3_exp(back, T2, NULL);
        printf("half turn %d: theta - pi = %.3g, exp(log T) - T = %.3g\n", a, th - M_PI, maxdiff(T, T2, 12));
        assert_true(fabs(th - M_PI) < 1e-7);
        assert_true(maxdiff(T, T2, 12) < 1e-12);
    }
    /* trace equal to the largest diagonal entry (a quarter turn about x: tr = r00 = 1): the trace branch wins */
    double q[12] = {1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0}, w[6];
    sci_se3_log(q, w);
    printf("quarter turn about x: %.17g %.3g %.3g\n", w[0], w[1], w[2]);
    assert_true(fabs(w[0] - M_PI / 2) < 1e-15 && w[1] == 0 && w[2] == 0);
}

/* The geodesic hits its ends bit for bit, moves at constant speed, and may write over its inputs. */
static void test_geodesic(void **state)
{
    (void)state;
    double a[6] = {0.1, -0.4, 0.3, 1, 2, 3}, b[6] = {-0.5, 0.2, 2.9, -1, 0.5, 0}, T0[12], T1[12], T[12];
    sci_se3_exp(a, T0, NULL);
    sci_se3_exp(b, T1, NULL);
    sci_se3_geodesic(T0, T1, 0, T);
    assert_memory_equal(T, T0, sizeof T);
    sci_se3_geodesic(T0, T1, 1, T);
    assert_memory_equal(T, T1, sizeof T);
    /* equal steps: log(T(k/4)⁻¹ T((k+1)/4)) is the same twist for every k */
    double step0[6] = {0};
    for (int k = 0; k < 4; k++) {
        double A[12], B[12], Ai[12], D[12], xi[6];
        sci_se3_geodesic(T0, T1, k / 4.0, A);
        sci_se3_geodesic(T0, T1, (k + 1) / 4.0, B);
        sci_se3_inv(A, Ai);
        sci_se3_mul(Ai, B, D);
        sci_se3_log(D, xi);
        if (k == 0)
            memcpy(step0, xi, sizeof xi);
        assert_true(maxdiff(xi, step0, 6) < 1e-12);
    }
    /* aliasing: out = first input */
    double X[12], Y[12];
    memcpy(X, T0, sizeof X);
    sci_se3_geodesic(T0, T1, 0.3, Y);
    sci_se3_geodesic(X, T1, 0.3, X);
    assert_memory_equal(X, Y, sizeof X);
    memcpy(X, T0, sizeof X);
    sci_se3_mul(X, T1, X);
    sci_se3_mul(T0, T1, Y);
    assert_memory_equal(X, Y, sizeof X);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip_and_reference),
        cmocka_unit_test(test_taylor_switch_is_continuous),
        cmocka_unit_test(test_pi_and_pivot_ties),
        cmocka_unit_test(test_geodesic),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
