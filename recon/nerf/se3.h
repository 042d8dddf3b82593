/* recon/nerf/se3.h — what pose optimisation adds to base/se3.h: the interpolated pose between two twists with its
 * Jacobian, and pose gradients from per-point gradients. Poses, twists ([ω, u], rotation first), exp and log are
 * base/se3.h's.
 *
 * Interpolation (docs/conventions.md §12): pose j = 0 … N−1 of N is T₁·exp(τ_j·log(T₁⁻¹·T_N)) with
 * τ_j = j/(N − 1) (0 for N = 1), so j = 0 gives T₁ and j = N − 1 gives T_N exactly — not the paper's i/N.
 * This is the SE(3) geodesic (sci_se3_geodesic); SCINeRF's SO(3)×R³ variant differs when the rotation is not 0.
 *
 * Jacobians are ∂vec(T)/∂(parameters), 12 rows (the 12 entries of T) by 6 or 12 columns, exact (chain rule of
 * the closed forms; the log's derivative as the inverse of the exp Jacobian on the tangent space). A pose
 * gradient g_T (12, ∂loss/∂T entries) maps to the twist gradient Jᵀ·g_T (nerf_se3_vjp).
 * Pure functions: reentrant and thread-safe.
 */
#ifndef SCICAP_RECON_NERF_SE3_H
#define SCICAP_RECON_NERF_SE3_H

#include "base/se3.h"

/* Pose j of N interpolated between exp(ξ₁) and exp(ξ_N); J (nullable) = ∂vec(T_j)/∂[ξ₁, ξ_N], 12×12 row-major.
 * Returns 0, or -EINVAL (N < 1 or j outside 0 … N−1; T untouched). */
int nerf_se3_interp(const double xi1[6], const double xiN[6], int N, int j, double T[12], double J[144]);
/* g_xi (ncols) += Jᵀ g_T for a 12 × ncols Jacobian. */
void nerf_se3_vjp(const double *J, int ncols, const double g_T[12], double *g_xi);

/* Pose gradient from per-point gradients: for world points x = R·p + t (is_direction = 0) or directions
 * d = R·p (is_direction = 1), given p (n×3, camera frame) and g = ∂loss/∂x (n×3), add ∂loss/∂T to g_T
 * (sums in double, fixed order). */
void nerf_se3_grad_from_points(int n, const float *p, const float *g, int is_direction, double g_T[12]);

#endif
