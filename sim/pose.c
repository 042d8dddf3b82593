/* sim/pose.c — the simulator's pose helpers on base/se3.c, the one SE(3) implementation (see pose.h). */
#include "sim/pose.h"

#include <math.h>
#include <string.h>

#include "base/se3.h"

void sim_rot_exp(const double w[3], double R[9])
{
    sci_se3_rot_exp(w, R);
}

/* sim's twists are (ρ, ω); base/se3.h's are [ω, u]. */
void sim_pose_exp(const double xi[6], double T[12])
{
    const double x[6] = {xi[3], xi[4], xi[5], xi[0], xi[1], xi[2]};
    sci_se3_exp(x, T, NULL);
}

void sim_pose_log(const double T[12], double xi[6])
{
    double x[6];
    sci_se3_log(T, x);
    for (int i = 0; i < 3; i++)
        xi[i] = x[3 + i], xi[3 + i] = x[i];
}

void sim_pose_mul(const double A[12], const double B[12], double C[12])
{
    sci_se3_mul(A, B, C);
}

void sim_pose_inv(const double T[12], double Ti[12])
{
    sci_se3_inv(T, Ti);
}

void sim_pose_interp(const double T0[12], const double T1[12], double tau, double T[12])
{
    sci_se3_geodesic(T0, T1, tau, T);
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
