#include "sim/pose.h"

#include <math.h>
#include <string.h>

/* Below this angle the closed forms of C and D lose digits to cancellation; the Taylor forms, truncated after
 * θ⁴, are accurate to ~1e-14 there. */
#define SIM_POSE_TAYLOR_THETA 0.05

static void hat(const double w[3], double W[9])
{
    W[0] = 0;     W[1] = -w[2]; W[2] = w[1];
    W[3] = w[2];  W[4] = 0;     W[5] = -w[0];
    W[6] = -w[1]; W[7] = w[0];  W[8] = 0;
}

static void mat3_mul(const double A[9], const double B[9], double C[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/* A = sinθ/θ, B = (1−cosθ)/θ², C = (θ−sinθ)/θ³. */
static void exp_coeffs(double th, double *a, double *b, double *c)
{
    double t2 = th * th;
    if (th < SIM_POSE_TAYLOR_THETA) {
        *a = 1 - t2 / 6 + t2 * t2 / 120;
        *b = 0.5 - t2 / 24 + t2 * t2 / 720;
        *c = 1.0 / 6 - t2 / 120 + t2 * t2 / 5040;
    } else {
        double s = sin(th), h = sin(0.5 * th);
        *a = s / th;
        *b = 2 * h * h / t2;
        *c = (th - s) / (t2 * th);
    }
}

void sim_rot_exp(const double w[3], double R[9])
{
    double th = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]), a, b, c, W[9], W2[9];
    exp_coeffs(th, &a, &b, &c);
    hat(w, W);
    mat3_mul(W, W, W2);
    for (int i = 0; i < 9; i++)
        R[i] = (i % 4 == 0) + a * W[i] + b * W2[i];
}

void sim_pose_exp(const double xi[6], double T[12])
{
    const double *rho = xi, *w = xi + 3;
    double th = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]), a, b, c, W[9], W2[9], V[9];
    exp_coeffs(th, &a, &b, &c);
    hat(w, W);
    mat3_mul(W, W, W2);
    for (int i = 0; i < 9; i++) {
        double I = (i % 4 == 0);
        T[(i / 3) * 4 + i % 3] = I + a * W[i] + b * W2[i];
        V[i] = I + b * W[i] + c * W2[i];
    }
    for (int i = 0; i < 3; i++)
        T[4 * i + 3] = V[3 * i] * rho[0] + V[3 * i + 1] * rho[1] + V[3 * i + 2] * rho[2];
}

/* Rotation vector of R via the quaternion (Shepperd's method picks the largest diagonal term, so no division
 * by a small number), folded to w >= 0 so the angle is in [0, π]. */
static void rot_log(const double R[12], double out[3])
{
    double m00 = R[0], m11 = R[5], m22 = R[10], tr = m00 + m11 + m22, q[4]; /* w x y z */
    if (tr > m00 && tr > m11 && tr > m22) {
        double s = 2 * sqrt(1 + tr);
        q[0] = 0.25 * s;
        q[1] = (R[9] - R[6]) / s;
        q[2] = (R[2] - R[8]) / s;
        q[3] = (R[4] - R[1]) / s;
    } else if (m00 >= m11 && m00 >= m22) {
        double s = 2 * sqrt(1 + m00 - m11 - m22);
        q[0] = (R[9] - R[6]) / s;
        q[1] = 0.25 * s;
        q[2] = (R[1] + R[4]) / s;
        q[3] = (R[2] + R[8]) / s;
    } else if (m11 >= m22) {
        double s = 2 * sqrt(1 + m11 - m00 - m22);
        q[0] = (R[2] - R[8]) / s;
        q[1] = (R[1] + R[4]) / s;
        q[2] = 0.25 * s;
        q[3] = (R[6] + R[9]) / s;
    } else {
        double s = 2 * sqrt(1 + m22 - m00 - m11);
        q[0] = (R[4] - R[1]) / s;
        q[1] = (R[2] + R[8]) / s;
        q[2] = (R[6] + R[9]) / s;
        q[3] = 0.25 * s;
    }
    if (q[0] < 0)
        for (int i = 0; i < 4; i++)
            q[i] = -q[i];
    double n = sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]), k;
    if (n < 1e-8)
        k = 2 / q[0] - (2.0 / 3.0) * n * n / (q[0] * q[0] * q[0]);
    else
        k = 2 * atan2(n, q[0]) / n;
    for (int i = 0; i < 3; i++)
        out[i] = k * q[i + 1];
}

void sim_pose_log(const double T[12], double xi[6])
{
    double *w = xi + 3, W[9], W2[9], d;
    rot_log(T, w);
    double th = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]), t2 = th * th;
    if (th < SIM_POSE_TAYLOR_THETA)
        d = 1.0 / 12 + t2 / 720 + t2 * t2 / 30240;
    else
        d = (1 - 0.5 * th * cos(0.5 * th) / sin(0.5 * th)) / t2;
    hat(w, W);
    mat3_mul(W, W, W2);
    for (int i = 0; i < 3; i++) {
        double r = 0;
        for (int j = 0; j < 3; j++)
            r += ((i == j) - 0.5 * W[3 * i + j] + d * W2[3 * i + j]) * T[4 * j + 3];
        xi[i] = r;
    }
}

void sim_pose_mul(const double A[12], const double B[12], double C[12])
{
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 4; j++)
            C[4 * i + j] = A[4 * i] * B[j] + A[4 * i + 1] * B[4 + j] + A[4 * i + 2] * B[8 + j];
        C[4 * i + 3] += A[4 * i + 3];
    }
}

void sim_pose_inv(const double T[12], double Ti[12])
{
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            Ti[4 * i + j] = T[4 * j + i];
        Ti[4 * i + 3] = -(T[i] * T[3] + T[4 + i] * T[7] + T[8 + i] * T[11]);
    }
}

void sim_pose_interp(const double T0[12], const double T1[12], double tau, double T[12])
{
    if (tau == 0) {
        memcpy(T, T0, 12 * sizeof *T);
        return;
    }
    if (tau == 1) {
        memcpy(T, T1, 12 * sizeof *T);
        return;
    }
    double inv[12], rel[12], xi[6], step[12];
    sim_pose_inv(T0, inv);
    sim_pose_mul(inv, T1, rel);
    sim_pose_log(rel, xi);
    for (int i = 0; i < 6; i++)
        xi[i] *= tau;
    sim_pose_exp(xi, step);
    sim_pose_mul(T0, step, T);
}

static int normalize(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(n > 1e-12))
        return -1;
    for (int i = 0; i < 3; i++)
        v[i] /= n;
    return 0;
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

int sim_pose_look_at(const double eye[3], const double target[3], const double up[3], double T[12])
{
    double z[3] = {eye[0] - target[0], eye[1] - target[1], eye[2] - target[2]}, x[3], y[3];
    if (normalize(z) < 0)
        return -1;
    cross(up, z, x);
    if (normalize(x) < 0)
        return -1;
    cross(z, x, y);
    for (int i = 0; i < 3; i++) {
        T[4 * i + 0] = x[i];
        T[4 * i + 1] = y[i];
        T[4 * i + 2] = z[i];
        T[4 * i + 3] = eye[i];
    }
    return 0;
}
