/* recon/nerf/poses.h — the N camera poses of one snapshot as trainable parameters (SCINeRF, docs/conventions.md §7).
 *
 * Modes:
 *   NERF_POSES_KNOWN      the poses are given (problem->camera) and fixed: no parameters.
 *   NERF_POSES_LINEAR     12 parameters [ξ₁, ξ_N] (twists, rotation first); pose j = the SE(3) geodesic
 *                         T₁·exp(τ_j·log(T₁⁻¹T_N)), τ_j = j/(N−1) (se3.h: not the paper's i/N).
 *   NERF_POSES_PER_FRAME  6N parameters, pose j = exp(ξ_j).
 * Poses are camera-to-world 3×4 row-major (problem.h convention). Parameters are absolute twists (the scene's gauge
 * is whatever the optimised poses make it); the optimiser is a small Adam in double inside the object.
 *
 * Gradients: the trainer turns per-point gradients into ∂loss/∂T_j (nerf_se3_grad_from_points) and hands them to
 * nerf_poses_add_grad; nerf_poses_step applies Adam and clears the gradient.
 * Not thread-safe per object; plain memory, no failure after _new.
 */
#ifndef SCICAP_RECON_NERF_POSES_H
#define SCICAP_RECON_NERF_POSES_H

#include <stdint.h>

#include "base/error.h"

typedef enum nerf_poses_mode { NERF_POSES_KNOWN = 0, NERF_POSES_LINEAR = 1, NERF_POSES_PER_FRAME = 2 } nerf_poses_mode;

typedef struct nerf_poses nerf_poses;

/* init: n poses to start from (3×4 each), e.g. the camera's; NULL starts from the identity. With LINEAR only the
 * first and last are used (the others follow from the interpolation). perturb_rot_rad / perturb_trans (scene units):
 * each parameter component gets U(−a, a) added (seeded), 0 for none; ignored for KNOWN.
 * -EINVAL for n < 1 or a bad mode, -ENOMEM. */
int nerf_poses_new(nerf_poses **out, nerf_poses_mode mode, int n, const double (*init)[12], double perturb_rot_rad,
                   double perturb_trans, uint64_t seed, sci_error *err);
void nerf_poses_free(nerf_poses *p);
nerf_poses_mode nerf_poses_mode_of(const nerf_poses *p);
int nerf_poses_count(const nerf_poses *p);       /* N */
int nerf_poses_param_count(const nerf_poses *p); /* 0, 12 or 6N */
double *nerf_poses_params(nerf_poses *p);        /* the parameters (twists), param_count doubles; borrowed */

/* Pose j (0 … N−1) into T. */
void nerf_poses_get(const nerf_poses *p, int j, double T[12]);
/* Add ∂loss/∂T_j (12 entries) to the parameter gradient (no-op for KNOWN). */
void nerf_poses_add_grad(nerf_poses *p, int j, const double g_T[12]);
/* One Adam step (β 0.9, 0.999, ε 1e-8) with learning rate lr, then zero the gradient. Held parameters (below)
 * neither move nor gather moments. */
void nerf_poses_step(nerf_poses *p, double lr);
/* Gauge: hold pose 1 fixed (its 6 twist components: ξ₁ of LINEAR, ξ_0 of PER_FRAME). Off by default. */
void nerf_poses_set_hold_first(nerf_poses *p, int hold);
/* Adam state for checkpoints: 3·param_count doubles (m, v, grad) plus the step count. */
double *nerf_poses_state(nerf_poses *p, long **step);

/* Mean rotation angle (radians) and translation distance between the poses and `ref` (n poses): how far they are. */
void nerf_poses_distance(const nerf_poses *p, const double (*ref)[12], double *rot_rad, double *trans);
/* Error of the motion relative to pose 1, blind to the gauge (a rigid motion of the whole trajectory), P the poses,
 * R the reference, means over j = 2 … N:
 *   rot_rad   rotation angle of (R₁⁻¹R_j)⁻¹·(P₁⁻¹P_j)
 *   trans     ‖t(P₁⁻¹P_j) − t(R₁⁻¹R_j)‖
 *   trans_scaled  the same after scaling the estimated relative translations by the least-squares factor `scale`
 *             (a scene and its camera path scaled together give the same images: scale is a gauge too)
 * All 0 for N = 1 (scale 1). */
typedef struct nerf_pose_error {
    double rot_rad, trans, trans_scaled, scale;
} nerf_pose_error;
nerf_pose_error nerf_poses_relative_error(const nerf_poses *p, const double (*ref)[12]);

#endif
