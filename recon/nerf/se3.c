/* recon/nerf/se3.c — SE(3) exp/log/interpolation with Jacobians (see se3.h). */
#include "recon/nerf/se3.h"

#include <errno.h>
#include <math.h>
#include <string.h>

/* Coefficients of exp and their derivatives divided by θ. Series Σ_k (−1)^k θ^2k / (2k + m)! for m = 1, 2, 3. */
typedef struct coef {
    double A, B, C, dA, dB, dC; /* dX = X'(θ)/θ */
} coef;

static void coefs(double th, coef *c)
{
    if (th < NERF_SE3_TAYLOR_THETA) {
        /* derivative series computed with θ^(2k−2) directly to stay valid at θ = 0 */
        double th2 = th * th;
        for (int m = 1; m <= 3; m++) {
            double fact = 1.0;
            for (int i = 2; i <= m; i++) fact *= i;
            double v = 0.0, dv = 0.0, p = 1.0, pm = 0.0; /* pm = θ^(2k−2) */
            for (int k = 0; k < 8; k++) {
                double sgn = (k & 1) ? -1.0 : 1.0;
                v += sgn * p / fact;
                if (k >= 1) dv += sgn * 2.0 * k * pm / fact;
                fact *= (double)(2 * k + m + 1) * (2 * k + m + 2);
                pm = p;
                p *= th2;
            }
            if (m == 1) c->A = v, c->dA = dv;
            if (m == 2) c->B = v, c->dB = dv;
            if (m == 3) c->C = v, c->dC = dv;
        }
        return;
    }
    double s = sin(th), co = cos(th), h = sin(0.5 * th);
    double omc = 2.0 * h * h; /* 1 − cosθ without cancellation */
    double t2 = th * th, t3 = t2 * th, t4 = t2 * t2, t5 = t4 * th;
    c->A = s / th;
    c->B = omc / t2;
    c->C = (th - s) / t3;
    c->dA = co / t2 - s / t3;
    c->dB = s / t3 - 2.0 * omc / t4;
    c->dC = omc / t4 - 3.0 * (th - s) / t5;
}

static void hat(const double w[3], double W[9])
{
    W[0] = 0, W[1] = -w[2], W[2] = w[1];
    W[3] = w[2], W[4] = 0, W[5] = -w[0];
    W[6] = -w[1], W[7] = w[0], W[8] = 0;
}

static void mm3(const double *A, const double *B, double *C)
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

void nerf_se3_identity(double T[12])
{
    memset(T, 0, 12 * sizeof *T);
    T[0] = T[5] = T[10] = 1.0;
}

void nerf_se3_mul(const double A[12], const double B[12], double AB[12])
{
    double o[12];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 4; c++) {
            double s = c == 3 ? A[4 * r + 3] : 0.0;
            for (int k = 0; k < 3; k++) s += A[4 * r + k] * B[4 * k + c];
            o[4 * r + c] = s;
        }
    memcpy(AB, o, sizeof o);
}

void nerf_se3_inv(const double T[12], double Ti[12])
{
    double o[12];
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) o[4 * r + c] = T[4 * c + r];
        o[4 * r + 3] = -(T[r] * T[3] + T[4 + r] * T[7] + T[8 + r] * T[11]);
    }
    memcpy(Ti, o, sizeof o);
}

void nerf_se3_exp(const double xi[6], double T[12], double J[72])
{
    const double *w = xi, *u = xi + 3;
    double th = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    coef c;
    coefs(th, &c);
    double W[9], W2[9], R[9], V[9];
    hat(w, W);
    mm3(W, W, W2);
    for (int i = 0; i < 9; i++) {
        double I = (i % 4 == 0) ? 1.0 : 0.0;
        R[i] = I + c.A * W[i] + c.B * W2[i];
        V[i] = I + c.B * W[i] + c.C * W2[i];
    }
    double o[12];
    for (int r = 0; r < 3; r++) {
        for (int k = 0; k < 3; k++) o[4 * r + k] = R[3 * r + k];
        o[4 * r + 3] = V[3 * r] * u[0] + V[3 * r + 1] * u[1] + V[3 * r + 2] * u[2];
    }
    if (J) {
        memset(J, 0, 72 * sizeof *J);
        for (int k = 0; k < 3; k++) {
            double e[3] = {0, 0, 0}, E[9], EW[9], WE[9];
            e[k] = 1.0;
            hat(e, E);
            mm3(E, W, EW);
            mm3(W, E, WE);
            double dR[9], dV[9];
            for (int i = 0; i < 9; i++) {
                double sym = EW[i] + WE[i];
                dR[i] = c.dA * w[k] * W[i] + c.A * E[i] + c.dB * w[k] * W2[i] + c.B * sym;
                dV[i] = c.dB * w[k] * W[i] + c.B * E[i] + c.dC * w[k] * W2[i] + c.C * sym;
            }
            for (int r = 0; r < 3; r++) {
                for (int q = 0; q < 3; q++) J[(4 * r + q) * 6 + k] = dR[3 * r + q];
                J[(4 * r + 3) * 6 + k] = dV[3 * r] * u[0] + dV[3 * r + 1] * u[1] + dV[3 * r + 2] * u[2];
            }
        }
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++) J[(4 * r + 3) * 6 + 3 + k] = V[3 * r + k];
    }
    memcpy(T, o, sizeof o);
}

void nerf_se3_log(const double T[12], double xi[6])
{
    const double r00 = T[0], r11 = T[5], r22 = T[10], tr = r00 + r11 + r22;
    double q[4]; /* w, x, y, z */
    if (tr >= r00 && tr >= r11 && tr >= r22) {
        double s = 2.0 * sqrt(1.0 + tr);
        q[0] = 0.25 * s;
        q[1] = (T[9] - T[6]) / s;
        q[2] = (T[2] - T[8]) / s;
        q[3] = (T[4] - T[1]) / s;
    } else if (r00 >= r11 && r00 >= r22) {
        double s = 2.0 * sqrt(1.0 + r00 - r11 - r22);
        q[0] = (T[9] - T[6]) / s;
        q[1] = 0.25 * s;
        q[2] = (T[1] + T[4]) / s;
        q[3] = (T[2] + T[8]) / s;
    } else if (r11 >= r22) {
        double s = 2.0 * sqrt(1.0 - r00 + r11 - r22);
        q[0] = (T[2] - T[8]) / s;
        q[1] = (T[1] + T[4]) / s;
        q[2] = 0.25 * s;
        q[3] = (T[6] + T[9]) / s;
    } else {
        double s = 2.0 * sqrt(1.0 - r00 - r11 + r22);
        q[0] = (T[4] - T[1]) / s;
        q[1] = (T[2] + T[8]) / s;
        q[2] = (T[6] + T[9]) / s;
        q[3] = 0.25 * s;
    }
    if (q[0] < 0.0)
        for (int i = 0; i < 4; i++) q[i] = -q[i];
    double qn = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int i = 0; i < 4; i++) q[i] /= qn;
    double n = sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]), w0 = q[0];
    double k = n < 1e-8 ? 2.0 / w0 * (1.0 - n * n / (3.0 * w0 * w0)) : 2.0 * atan2(n, w0) / n;
    double om[3] = {k * q[1], k * q[2], k * q[3]};
    double th = sqrt(om[0] * om[0] + om[1] * om[1] + om[2] * om[2]);
    double D;
    if (th < NERF_SE3_TAYLOR_THETA) {
        double t2 = th * th;
        D = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1209600.0;
    } else {
        double h = 0.5 * th;
        D = (1.0 - h * cos(h) / sin(h)) / (th * th);
    }
    double W[9], W2[9];
    hat(om, W);
    mm3(W, W, W2);
    const double t[3] = {T[3], T[7], T[11]};
    for (int r = 0; r < 3; r++) {
        double s = t[r];
        for (int c = 0; c < 3; c++) s += (-0.5 * W[3 * r + c] + D * W2[3 * r + c]) * t[c];
        xi[3 + r] = s;
    }
    xi[0] = om[0], xi[1] = om[1], xi[2] = om[2];
}

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
    nerf_se3_exp(xi1, T1, E1);
    nerf_se3_exp(xiN, TN, EN);
    nerf_se3_inv(T1, T1i);
    nerf_se3_mul(T1i, TN, D);
    nerf_se3_log(D, zeta);
    for (int i = 0; i < 6; i++) tz[i] = tau * zeta[i];
    nerf_se3_exp(tz, S, ES);
    double out[12];
    if (j == 0) memcpy(out, T1, sizeof out); /* exact ends: no round trip through log/exp */
    else if (j == N - 1) memcpy(out, TN, sizeof out);
    else nerf_se3_mul(T1, S, out);
    if (J) {
        nerf_se3_exp(zeta, D, Ez); /* Jacobian of exp at ζ (D recomputed, identical up to rounding) */
        nerf_se3_mul(T1i, TN, D);
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
