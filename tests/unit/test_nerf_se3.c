/* tests/unit/test_nerf_se3.c — SE(3) exp/log, interpolation and pose gradients, in double.
 *
 * Jacobians are checked against central differences (h = 1e-7, error ~1e-9 relative) with the bound 1e-4
 * (in practice ~1e-9: everything here is double). Angles: θ = 0, 1e-12, 1e-6, 1e-3, 0.5, π − 1e-6, π.
 */
#include <errno.h>
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
#include "recon/nerf/ref.h"
#include "recon/nerf/render.h"
#include "recon/nerf/se3.h"

static sci_rng RNG_;

static uint64_t test_seed(void)
{
    const char *e = getenv("SCICAP_TEST_SEED");
    uint64_t s = e ? strtoull(e, NULL, 0) : 20240608u;
    printf("seed %llu (set SCICAP_TEST_SEED to replay)\n", (unsigned long long)s);
    return s;
}

static const double THETAS[] = {0.0, 1e-12, 1e-6, 1e-3, 0.5, M_PI - 1e-6, M_PI};
#define NTH (int)(sizeof THETAS / sizeof THETAS[0])

static void twist(double th, double xi[6])
{
    double a[3], n = 0;
    for (int i = 0; i < 3; i++) a[i] = sci_rng_normal(&RNG_), n += a[i] * a[i];
    n = sqrt(n);
    for (int i = 0; i < 3; i++) xi[i] = th * a[i] / n, xi[3 + i] = sci_rng_normal(&RNG_);
}

static double maxdiff(const double *a, const double *b, int n)
{
    double m = 0;
    for (int i = 0; i < n; i++) m = fmax(m, fabs(a[i] - b[i]));
    return m;
}

static void test_exp_log_roundtrip(void **s)
{
    (void)s;
    for (int k = 0; k < NTH; k++) {
        double xi[6], T[12], back[12], xl[6];
        twist(THETAS[k], xi);
        sci_se3_exp(xi, T, NULL);
        /* R orthonormal */
        double orth = 0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double d = 0;
                for (int q = 0; q < 3; q++) d += T[4 * i + q] * T[4 * j + q];
                orth = fmax(orth, fabs(d - (i == j)));
            }
        sci_se3_log(T, xl);
        sci_se3_exp(xl, back, NULL);
        double e_pose = maxdiff(T, back, 12);
        double e_xi = THETAS[k] < M_PI ? maxdiff(xi, xl, 6) : 0; /* at π exactly, ω and −ω are both logs */
        printf("theta %-18.17g orthonormality %.1e, exp(log T) − T %.1e, log(exp ξ) − ξ %.1e\n", THETAS[k], orth,
               e_pose, e_xi);
        for (int i = 0; i < 6; i++) assert_true(isfinite(xl[i]));
        assert_true(orth < 1e-14);
        assert_true(e_pose < 1e-9);
        assert_true(e_xi < 1e-9);
        double th = sqrt(xl[0] * xl[0] + xl[1] * xl[1] + xl[2] * xl[2]);
        assert_true(fabs(th - THETAS[k]) < 1e-9);
    }
    /* the Taylor branch agrees with the closed form where they meet */
    double a[6] = {0.0999999, 0, 0, 1, 2, 3}, b[6] = {0.1000001, 0, 0, 1, 2, 3}, Ta[12], Tb[12];
    sci_se3_exp(a, Ta, NULL), sci_se3_exp(b, Tb, NULL);
    assert_true(maxdiff(Ta, Tb, 12) < 1e-6);
}

static void test_exp_jacobian(void **s)
{
    (void)s;
    for (int k = 0; k < NTH; k++) {
        double xi[6], T[12], J[72];
        twist(THETAS[k], xi);
        sci_se3_exp(xi, T, J);
        double num = 0, den = 0;
        for (int c = 0; c < 6; c++) {
            double xp[6], xm[6], Tp[12], Tm[12];
            memcpy(xp, xi, sizeof xp), memcpy(xm, xi, sizeof xm);
            xp[c] += 1e-7, xm[c] -= 1e-7;
            sci_se3_exp(xp, Tp, NULL), sci_se3_exp(xm, Tm, NULL);
            for (int r = 0; r < 12; r++) {
                double g = (Tp[r] - Tm[r]) / 2e-7;
                num += (J[r * 6 + c] - g) * (J[r * 6 + c] - g), den += g * g;
                assert_true(isfinite(J[r * 6 + c]));
            }
        }
        printf("theta %-18.17g exp Jacobian rel err %.2g\n", THETAS[k], sqrt(num / den));
        assert_true(sqrt(num / den) < 1e-4);
    }
}

static void interp_check(const double x1[6], const double xN[6], const char *what)
{
    const int N = 8;
    double T1[12], TN[12];
    sci_se3_exp(x1, T1, NULL), sci_se3_exp(xN, TN, NULL);
    double worst = 0;
    for (int j = 0; j < N; j++) {
        double T[12], J[144];
        assert_int_equal(nerf_se3_interp(x1, xN, N, j, T, J), 0);
        if (j == 0) assert_memory_equal(T, T1, sizeof T1);
        if (j == N - 1) assert_memory_equal(T, TN, sizeof TN);
        double num = 0, den = 0;
        for (int c = 0; c < 12; c++) {
            double a[6], b[6], c1[6], c2[6], Tp[12], Tm[12];
            memcpy(a, x1, sizeof a), memcpy(b, xN, sizeof b), memcpy(c1, x1, sizeof c1), memcpy(c2, xN, sizeof c2);
            if (c < 6) a[c] += 1e-7, c1[c] -= 1e-7;
            else b[c - 6] += 1e-7, c2[c - 6] -= 1e-7;
            nerf_se3_interp(a, b, N, j, Tp, NULL), nerf_se3_interp(c1, c2, N, j, Tm, NULL);
            for (int r = 0; r < 12; r++) {
                double g = (Tp[r] - Tm[r]) / 2e-7;
                num += (J[r * 12 + c] - g) * (J[r * 12 + c] - g), den += g * g;
                assert_true(isfinite(J[r * 12 + c]));
            }
        }
        worst = fmax(worst, sqrt(num / den));
    }
    printf("interpolation %-28s ends exact, Jacobian rel err (worst pose) %.2g\n", what, worst);
    assert_true(worst < 1e-4);
}

static void test_interp(void **s)
{
    (void)s;
    double x1[6], xN[6];
    twist(0.3, x1), twist(0.2, xN);
    interp_check(x1, xN, "random");
    twist(0.05, x1), twist(0.001, xN);
    interp_check(x1, xN, "small rotations");
    /* relative rotation near π between the ends */
    double a[6] = {0, 0, 0, 0.1, 0.2, 0.3}, b[6] = {0, 0, M_PI - 1e-3, -0.1, 0.4, 0.0};
    interp_check(a, b, "relative rotation pi - 1e-3");
    assert_int_equal(nerf_se3_interp(a, b, 8, 8, (double[12]){0}, NULL), -EINVAL);
}

/* Identical start and end poses: every pose equals the start, the Jacobian is finite and right. */
static void test_interp_identical_ends(void **s)
{
    (void)s;
    double x[6];
    twist(0.4, x);
    double T1[12];
    sci_se3_exp(x, T1, NULL);
    for (int j = 0; j < 8; j++) {
        double T[12];
        nerf_se3_interp(x, x, 8, j, T, NULL);
        assert_true(maxdiff(T, T1, 12) < 1e-14);
    }
    interp_check(x, x, "identical start and end");
    double z[6] = {0};
    interp_check(z, z, "both identity");
}

/* Gradient of rendered colours w.r.t. the se(3) of T₁ and T_N, through points x = R·p + t, a smooth analytic field
 * and the volume renderer: analytic chain (render backward → field gradient → grad_from_points → Jᵀ) vs FD. */
enum { NRAY = 4, NS = 8, NPOSE = 5 };

static void field(const double x[3], double *sig, double c[3], double ds[3], double dc[3][3])
{
    *sig = 1.0 + x[0] * x[0] + 0.5 * sin(x[1]) + 0.3 * x[2];
    ds[0] = 2 * x[0], ds[1] = 0.5 * cos(x[1]), ds[2] = 0.3;
    for (int a = 0; a < 3; a++) {
        double s = 1 / (1 + exp(-(x[a] + 0.2 * x[(a + 1) % 3])));
        c[a] = s;
        for (int b = 0; b < 3; b++) dc[a][b] = 0;
        dc[a][a] = s * (1 - s), dc[a][(a + 1) % 3] = 0.2 * s * (1 - s);
    }
}

static double pose_loss(const double x1[6], const double xN[6], const double *pc, const double *wc)
{
    double L = 0;
    for (int j = 0; j < NPOSE; j++) {
        double T[12], sg[NRAY * NS], rgb[NRAY * NS * 3], dl[NRAY * NS], col[NRAY * 3];
        nerf_se3_interp(x1, xN, NPOSE, j, T, NULL);
        for (int i = 0; i < NRAY * NS; i++) {
            double x[3], ds[3], dc[3][3];
            for (int r = 0; r < 3; r++) x[r] = T[4 * r] * pc[3 * i] + T[4 * r + 1] * pc[3 * i + 1] + T[4 * r + 2] * pc[3 * i + 2] + T[4 * r + 3];
            field(x, &sg[i], &rgb[3 * i], ds, dc);
            dl[i] = 0.1;
        }
        nerf_ref_render(NRAY, NS, sg, rgb, dl, NULL, NULL, 0, col, NULL, NULL);
        for (int k = 0; k < NRAY * 3; k++) L += wc[j * NRAY * 3 + k] * col[k];
    }
    return L;
}

static void test_pose_gradient(void **s)
{
    (void)s;
    double x1[6], xN[6], pc[NRAY * NS * 3], wc[NPOSE * NRAY * 3];
    twist(0.1, x1), twist(0.15, xN);
    for (int i = 0; i < NRAY * NS; i++) {
        double z = -1.0 - 0.1 * (i % NS);
        pc[3 * i] = (float)(0.2 * (i / NS) * z), pc[3 * i + 1] = (float)(-0.1 * z), pc[3 * i + 2] = (float)z;
    }
    for (int k = 0; k < NPOSE * NRAY * 3; k++) wc[k] = sci_rng_normal(&RNG_);
    double g[12] = {0};
    for (int j = 0; j < NPOSE; j++) {
        double T[12], J[144];
        nerf_se3_interp(x1, xN, NPOSE, j, T, J);
        float sg[NRAY * NS], rgb[NRAY * NS * 3], dl[NRAY * NS], col[NRAY * 3], dcol[NRAY * 3], dsg[NRAY * NS];
        float drgb[NRAY * NS * 3], pf[NRAY * NS * 3], gx[NRAY * NS * 3];
        double dsd[NRAY * NS][3], dcd[NRAY * NS][3][3];
        for (int i = 0; i < NRAY * NS; i++) {
            double x[3], sd, cd[3];
            for (int r = 0; r < 3; r++) x[r] = T[4 * r] * pc[3 * i] + T[4 * r + 1] * pc[3 * i + 1] + T[4 * r + 2] * pc[3 * i + 2] + T[4 * r + 3];
            field(x, &sd, cd, dsd[i], dcd[i]);
            sg[i] = (float)sd, dl[i] = 0.1f;
            for (int a = 0; a < 3; a++) rgb[3 * i + a] = (float)cd[a], pf[3 * i + a] = (float)pc[3 * i + a];
        }
        for (int k = 0; k < NRAY * 3; k++) dcol[k] = (float)wc[j * NRAY * 3 + k];
        nerf_render_rays rr = {.n_rays = NRAY, .L = NS, .sigma = sg, .rgb = rgb, .delta = dl, .t_stop = 0};
        nerf_render_forward(&rr, col, NULL, NULL, NULL);
        nerf_render_backward(&rr, dcol, NULL, NULL, dsg, drgb, NULL);
        for (int i = 0; i < NRAY * NS; i++)
            for (int b = 0; b < 3; b++) {
                double v = dsg[i] * dsd[i][b];
                for (int a = 0; a < 3; a++) v += drgb[3 * i + a] * dcd[i][a][b];
                gx[3 * i + b] = (float)v;
            }
        double gT[12] = {0};
        nerf_se3_grad_from_points(NRAY * NS, pf, gx, 0, gT);
        nerf_se3_vjp(J, 12, gT, g);
    }
    double num = 0, den = 0;
    for (int c = 0; c < 12; c++) {
        double a[6], b[6], c1[6], c2[6];
        memcpy(a, x1, sizeof a), memcpy(b, xN, sizeof b), memcpy(c1, x1, sizeof c1), memcpy(c2, xN, sizeof c2);
        if (c < 6) a[c] += 1e-6, c1[c] -= 1e-6;
        else b[c - 6] += 1e-6, c2[c - 6] -= 1e-6;
        double fd = (pose_loss(a, b, pc, wc) - pose_loss(c1, c2, pc, wc)) / 2e-6;
        num += (g[c] - fd) * (g[c] - fd), den += fd * fd;
    }
    printf("pose gradient (se(3) of T1 and TN through render): rel err %.2g\n", sqrt(num / den));
    assert_true(sqrt(num / den) < 1e-4);
}

int main(void)
{
    sci_rng_seed(&RNG_, test_seed(), 5);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_exp_log_roundtrip), cmocka_unit_test(test_exp_jacobian),
        cmocka_unit_test(test_interp),            cmocka_unit_test(test_interp_identical_ends),
        cmocka_unit_test(test_pose_gradient),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
