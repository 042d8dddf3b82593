#include "recon/nerf/poses.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "recon/nerf/se3.h"

struct nerf_poses {
    nerf_poses_mode mode;
    int n, np;
    double (*fixed)[12]; /* KNOWN: the poses */
    double *xi;          /* np parameters */
    double *state;       /* m, v, grad: 3·np */
    long step;
    int hold_first;
};

int nerf_poses_new(nerf_poses **out, nerf_poses_mode mode, int n, const double (*init)[12], double perturb_rot_rad,
                   double perturb_trans, uint64_t seed, sci_error *err)
{
    *out = NULL;
    if (n < 1)
        return sci_error_set(err, -EINVAL, "poses: count must be >= 1 (got %d)", n);
    int np;
    switch (mode) {
    case NERF_POSES_KNOWN: np = 0; break;
    case NERF_POSES_LINEAR: np = 12; break;
    case NERF_POSES_PER_FRAME: np = 6 * n; break;
    default: return sci_error_set(err, -EINVAL, "poses: unknown mode %d", (int)mode);
    }
    nerf_poses *p = calloc(1, sizeof *p);
    if (!p)
        return sci_error_set(err, -ENOMEM, "poses: out of memory");
    p->mode = mode;
    p->n = n;
    p->np = np;
    p->fixed = malloc((size_t)n * sizeof *p->fixed);
    p->xi = calloc((size_t)np + 1, sizeof *p->xi);
    p->state = calloc(3 * (size_t)np + 1, sizeof *p->state);
    if (!p->fixed || !p->xi || !p->state) {
        nerf_poses_free(p);
        return sci_error_set(err, -ENOMEM, "poses: out of memory");
    }
    for (int j = 0; j < n; j++) {
        if (init)
            memcpy(p->fixed[j], init[j], sizeof p->fixed[j]);
        else
            sci_se3_identity(p->fixed[j]);
    }
    if (mode == NERF_POSES_LINEAR) {
        sci_se3_log(p->fixed[0], p->xi);
        sci_se3_log(p->fixed[n - 1], p->xi + 6);
    } else if (mode == NERF_POSES_PER_FRAME) {
        for (int j = 0; j < n; j++)
            sci_se3_log(p->fixed[j], p->xi + 6 * j);
    }
    sci_rng rng;
    sci_rng_seed(&rng, seed, 0x905e5);
    for (int i = 0; i < np; i++) {
        double a = (i % 6) < 3 ? perturb_rot_rad : perturb_trans;
        p->xi[i] += a * (2 * sci_rng_uniform(&rng) - 1);
    }
    *out = p;
    return 0;
}

void nerf_poses_free(nerf_poses *p)
{
    if (!p)
        return;
    free(p->fixed);
    free(p->xi);
    free(p->state);
    free(p);
}

nerf_poses_mode nerf_poses_mode_of(const nerf_poses *p) { return p->mode; }
int nerf_poses_count(const nerf_poses *p) { return p->n; }
int nerf_poses_param_count(const nerf_poses *p) { return p->np; }
double *nerf_poses_params(nerf_poses *p) { return p->xi; }

double *nerf_poses_state(nerf_poses *p, long **step)
{
    *step = &p->step;
    return p->state;
}

void nerf_poses_get(const nerf_poses *p, int j, double T[12])
{
    switch (p->mode) {
    case NERF_POSES_KNOWN: memcpy(T, p->fixed[j], 12 * sizeof *T); break;
    case NERF_POSES_LINEAR: nerf_se3_interp(p->xi, p->xi + 6, p->n, j, T, NULL); break;
    case NERF_POSES_PER_FRAME: sci_se3_exp(p->xi + 6 * j, T, NULL); break;
    }
}

void nerf_poses_add_grad(nerf_poses *p, int j, const double g_T[12])
{
    double T[12], J[144];
    double *g = p->state + 2 * (size_t)p->np;
    switch (p->mode) {
    case NERF_POSES_KNOWN: break;
    case NERF_POSES_LINEAR:
        nerf_se3_interp(p->xi, p->xi + 6, p->n, j, T, J);
        nerf_se3_vjp(J, 12, g_T, g);
        break;
    case NERF_POSES_PER_FRAME:
        sci_se3_exp(p->xi + 6 * j, T, J);
        nerf_se3_vjp(J, 6, g_T, g + 6 * j);
        break;
    }
}

void nerf_poses_step(nerf_poses *p, double lr)
{
    if (p->np == 0)
        return;
    const double b1 = 0.9, b2 = 0.999, eps = 1e-8;
    double *m = p->state, *v = m + p->np, *g = v + p->np;
    p->step++;
    double c1 = 1 - pow(b1, (double)p->step), c2 = 1 - pow(b2, (double)p->step);
    for (int i = 0; i < p->np; i++) {
        if (p->hold_first && i < 6) {
            g[i] = 0;
            continue;
        }
        double gi = isfinite(g[i]) ? g[i] : 0;
        m[i] = b1 * m[i] + (1 - b1) * gi;
        v[i] = b2 * v[i] + (1 - b2) * gi * gi;
        p->xi[i] -= lr * (m[i] / c1) / (sqrt(v[i] / c2) + eps);
        g[i] = 0;
    }
}

void nerf_poses_distance(const nerf_poses *p, const double (*ref)[12], double *rot_rad, double *trans)
{
    double sr = 0, st = 0;
    for (int j = 0; j < p->n; j++) {
        double T[12], Ti[12], D[12], xi[6];
        nerf_poses_get(p, j, T);
        sci_se3_inv(ref[j], Ti);
        sci_se3_mul(Ti, T, D);
        sci_se3_log(D, xi);
        sr += sqrt(xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2]);
        st += sqrt(D[3] * D[3] + D[7] * D[7] + D[11] * D[11]);
    }
    *rot_rad = sr / p->n;
    *trans = st / p->n;
}

void nerf_poses_set_hold_first(nerf_poses *p, int hold) { p->hold_first = hold != 0; }

nerf_pose_error nerf_poses_relative_error(const nerf_poses *p, const double (*ref)[12])
{
    nerf_pose_error e = {.scale = 1};
    if (p->n < 2)
        return e;
    double P0[12], P0i[12], R0i[12], num = 0, den = 0;
    nerf_poses_get(p, 0, P0);
    sci_se3_inv(P0, P0i);
    sci_se3_inv(ref[0], R0i);
    double(*qp)[3] = malloc((size_t)p->n * sizeof *qp), (*qr)[3] = malloc((size_t)p->n * sizeof *qr);
    if (!qp || !qr) {
        free(qp), free(qr);
        return (nerf_pose_error){NAN, NAN, NAN, NAN};
    }
    for (int j = 1; j < p->n; j++) {
        double Pj[12], Qp[12], Qr[12], Qri[12], D[12], xi[6];
        nerf_poses_get(p, j, Pj);
        sci_se3_mul(P0i, Pj, Qp);
        sci_se3_mul(R0i, ref[j], Qr);
        sci_se3_inv(Qr, Qri);
        sci_se3_mul(Qri, Qp, D);
        sci_se3_log(D, xi);
        e.rot_rad += sqrt(xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2]);
        for (int k = 0; k < 3; k++) {
            qp[j][k] = Qp[4 * k + 3], qr[j][k] = Qr[4 * k + 3];
            num += qp[j][k] * qr[j][k], den += qp[j][k] * qp[j][k];
        }
    }
    e.scale = den > 0 ? num / den : 1;
    for (int j = 1; j < p->n; j++) {
        double a = 0, b = 0;
        for (int k = 0; k < 3; k++) {
            double d = qp[j][k] - qr[j][k], ds = e.scale * qp[j][k] - qr[j][k];
            a += d * d, b += ds * ds;
        }
        e.trans += sqrt(a), e.trans_scaled += sqrt(b);
    }
    free(qp), free(qr);
    e.rot_rad /= p->n - 1, e.trans /= p->n - 1, e.trans_scaled /= p->n - 1;
    return e;
}
