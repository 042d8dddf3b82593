/* base/se3.c — SE(3) exp/log in double, the one implementation recon/ and sim/ share (see se3.h). */
#include "base/se3.h"

#include <math.h>
#include <string.h>

/* Coefficients of exp and their derivatives divided by θ. Series Σ_k (−1)^k θ^2k / (2k + m)! for m = 1, 2, 3. */
typedef struct coef {
    double A, B, C, dA, dB, dC; /* dX = X'(θ)/θ */
} coef;

static void coefs(double th, coef *c)
{
    if (th < SCI_SE3_TAYLOR_THETA) {
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

void sci_se3_identity(double T[12])
{
    memset(T, 0, 12 * sizeof *T);
    T[0] = T[5] = T[10] = 1.0;
}

void sci_se3_mul(const double A[12], const double B[12], double AB[12])
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

void sci_se3_inv(const double T[12], double Ti[12])
{
    double o[12];
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) o[4 * r + c] = T[4 * c + r];
        o[4 * r + 3] = -(T[r] * T[3] + T[4 + r] * T[7] + T[8 + r] * T[11]);
    }
    memcpy(Ti, o, sizeof o);
}

void sci_se3_exp(const double xi[6], double T[12], double J[72])
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

void sci_se3_log(const double T[12], double xi[6])
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
    if (th < SCI_SE3_TAYLOR_THETA) {
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

void sci_se3_rot_exp(const double w[3], double R[9])
{
    const double th = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    coef c;
    coefs(th, &c);
    double W[9], W2[9];
    hat(w, W);
    mm3(W, W, W2);
    for (int i = 0; i < 9; i++)
        R[i] = ((i % 4 == 0) ? 1.0 : 0.0) + c.A * W[i] + c.B * W2[i];
}

void sci_se3_geodesic(const double T0[12], const double T1[12], double tau, double T[12])
{
    /* the ends exactly: no round trip through log/exp */
    if (tau == 0) {
        memmove(T, T0, 12 * sizeof *T);
        return;
    }
    if (tau == 1) {
        memmove(T, T1, 12 * sizeof *T);
        return;
    }
    double inv[12], rel[12], xi[6], step[12];
    sci_se3_inv(T0, inv);
    sci_se3_mul(inv, T1, rel);
    sci_se3_log(rel, xi);
    for (int i = 0; i < 6; i++)
        xi[i] *= tau;
    sci_se3_exp(xi, step, NULL);
    sci_se3_mul(T0, step, T);
}
