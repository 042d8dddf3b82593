/* recon/nerf/se3.c — pose interpolation between two twists with its Jacobian, and pose gradients (see se3.h); exp
 * and log are base/se3.c's. */
#include "recon/nerf/se3.h"

#include "base/se3.h"

#include <errno.h>
#include <math.h>
#include <string.h>

/* Solve the 6×6 normal equations (EᵀE) x = Eᵀ b for each of `nrhs` columns of b (12 × nrhs) → x (6 × nrhs). */
static void tangent_solve(const double E[72], const double *b, int nrhs, double *x)
{
    double M[36], rhs[6 * 12];
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 6; j++) {
            double s = 0.0;
            for (int r = 0; r < 12; r++) s += E[r * 6 + i] * E[r * 6 + j];
            M[6 * i + j] = s;
        }
    for (int i = 0; i < 6; i++)
        for (int c = 0; c < nrhs; c++) {
            double s = 0.0;
            for (int r = 0; r < 12; r++) s += E[r * 6 + i] * b[r * nrhs + c];
            rhs[i * nrhs + c] = s;
        }
    /* Cholesky: M is symmetric positive definite for θ < 2π */
    double Lc[36] = {0};
    for (int i = 0; i < 6; i++)
        for (int j = 0; j <= i; j++) {
            double s = M[6 * i + j];
            for (int k = 0; k < j; k++) s -= Lc[6 * i + k] * Lc[6 * j + k];
            Lc[6 * i + j] = i == j ? sqrt(s) : s / Lc[6 * j + j];
        }
    for (int c = 0; c < nrhs; c++) {
        double y[6];
        for (int i = 0; i < 6; i++) {
            double s = rhs[i * nrhs + c];
            for (int k = 0; k < i; k++) s -= Lc[6 * i + k] * y[k];
            y[i] = s / Lc[6 * i + i];
        }
        for (int i = 5; i >= 0; i--) {
            double s = y[i];
            for (int k = i + 1; k < 6; k++) s -= Lc[6 * k + i] * x[k * nrhs + c];
            x[i * nrhs + c] = s / Lc[6 * i + i];
        }
    }
}

/* Differential of a product of poses: d(A·B) = dA·B + A·dB for 3×4 [R|t] (homogeneous bottom row 0 0 0 1 / 0). */
static void dmul(const double A[12], const double dA[12], const double B[12], const double dB[12], double out[12])
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 4; c++) {
            double s = 0.0;
            for (int k = 0; k < 3; k++) s += dA[4 * r + k] * B[4 * k + c] + A[4 * r + k] * dB[4 * k + c];
            if (c == 3) s += dA[4 * r + 3];
            out[4 * r + c] = s;
        }
}

int nerf_se3_interp(const double xi1[6], const double xiN[6], int N, int j, double T[12], double J[144])
{
    if (N < 1 || j < 0 || j >= N) return -EINVAL;
    double tau = N > 1 ? (double)j / (double)(N - 1) : 0.0;
    double T1[12], TN[12], E1[72], EN[72], T1i[12], D[12], zeta[6], Ez[72], S[12], ES[72], tz[6];
    sci_se3_exp(xi1, T1, E1);
    sci_se3_exp(xiN, TN, EN);
    sci_se3_inv(T1, T1i);
    sci_se3_mul(T1i, TN, D);
    sci_se3_log(D, zeta);
    for (int i = 0; i < 6; i++) tz[i] = tau * zeta[i];
    sci_se3_exp(tz, S, ES);
    double out[12];
    if (j == 0) memcpy(out, T1, sizeof out); /* exact ends: no round trip through log/exp */
    else if (j == N - 1) memcpy(out, TN, sizeof out);
    else sci_se3_mul(T1, S, out);
    if (J) {
        sci_se3_exp(zeta, D, Ez); /* Jacobian of exp at ζ (D recomputed, identical up to rounding) */
        sci_se3_mul(T1i, TN, D);
        double dD[12 * 12]; /* column c: dD for parameter c */
        double zero[12] = {0};
        for (int c = 0; c < 12; c++) {
            double dT1[12] = {0}, dTN[12] = {0}, col[12];
            if (c < 6)
                for (int r = 0; r < 12; r++) dT1[r] = E1[r * 6 + c];
            else
                for (int r = 0; r < 12; r++) dTN[r] = EN[r * 6 + c - 6];
            /* D = T1⁻¹ TN: dD = −T1⁻¹ dT1 D + T1⁻¹ dTN */
            double b[12], t1[12];
            dmul(zero, dT1, D, zero, t1);      /* dT1·D  (A = 0, dA = dT1) */
            dmul(T1i, zero, zero, t1, b);      /* T1⁻¹·(dT1·D) */
            dmul(T1i, zero, zero, dTN, col);   /* T1⁻¹·dTN */
            for (int r = 0; r < 12; r++) dD[r * 12 + c] = col[r] - b[r];
        }
        double dz[6 * 12];
        tangent_solve(Ez, dD, 12, dz);
        for (int c = 0; c < 12; c++) {
            double dT1[12] = {0}, dS[12], col[12];
            if (c < 6)
                for (int r = 0; r < 12; r++) dT1[r] = E1[r * 6 + c];
            for (int r = 0; r < 12; r++) {
                double s = 0.0;
                for (int i = 0; i < 6; i++) s += ES[r * 6 + i] * tau * dz[i * 12 + c];
                dS[r] = s;
            }
            dmul(T1, dT1, S, dS, col);
            for (int r = 0; r < 12; r++) J[r * 12 + c] = col[r];
        }
    }
    memcpy(T, out, sizeof out);
    return 0;
}

void nerf_se3_vjp(const double *J, int ncols, const double g_T[12], double *g_xi)
{
    for (int c = 0; c < ncols; c++) {
        double s = 0.0;
        for (int r = 0; r < 12; r++) s += J[r * ncols + c] * g_T[r];
        g_xi[c] += s;
    }
}

void nerf_se3_grad_from_points(int n, const float *p, const float *g, int is_direction, double g_T[12])
{
    double acc[12] = {0};
    for (int i = 0; i < n; i++)
        for (int r = 0; r < 3; r++) {
            double gr = g[3 * (size_t)i + r];
            for (int c = 0; c < 3; c++) acc[4 * r + c] += gr * p[3 * (size_t)i + c];
            if (!is_direction) acc[4 * r + 3] += gr;
        }
    for (int k = 0; k < 12; k++) g_T[k] += acc[k];
}
