/* recon/nerf/se3.h — SE(3) in double precision: exp, log, pose interpolation and their Jacobians.
 *
 * A pose is a row-major 3×4 [R | t] (double[12], element (r, c) at 4r + c), camera-to-world as in sci_camera.
 * A twist ξ = [ω (3), u (3)] (rotation first, SCINeRF order); θ = ‖ω‖, W = [ω]×.
 *   exp: R = I + A·W + B·W², t = V·u, V = I + B·W + C·W²,  A = sinθ/θ, B = (1 − cosθ)/θ², C = (θ − sinθ)/θ³.
 *   log: R → unit quaternion (Shepperd: largest diagonal pivot, no acos) → ω = 2·atan2(n, w)/n · v with w >= 0,
 *        so θ ∈ [0, π] and θ near π stays exact; u = V⁻¹ t, V⁻¹ = I − ½W + D·W², D = (1 − (θ/2)cot(θ/2))/θ².
 * A, B, C, D and the derivative coefficients A'/θ, B'/θ, C'/θ switch to their Taylor series below θ = 0.1
 * (cancellation-free there; closed forms above), so θ = 0, 1e-12, 1e-6 … π are all finite and accurate. Only the
 * selected branch is evaluated (no mask-multiplied branches: §13).
 *
 * Interpolation (sci-reconstruction.md §12): pose j = 0 … N−1 of N is T₁·exp(τ_j·log(T₁⁻¹·T_N)) with
 * τ_j = j/(N − 1) (0 for N = 1), so j = 0 gives T₁ and j = N − 1 gives T_N exactly — not the paper's i/N.
 * This is the SE(3) geodesic; SCINeRF's SO(3)×R³ variant differs when the rotation is not 0.
 *
 * Jacobians are ∂vec(T)/∂(parameters), 12 rows (the 12 entries of T) by 6 or 12 columns, exact (chain rule of
 * the closed forms; the log's derivative as the inverse of the exp Jacobian on the tangent space). A pose
 * gradient g_T (12, ∂loss/∂T entries) maps to the twist gradient Jᵀ·g_T (nerf_se3_vjp).
 * Pure functions: reentrant and thread-safe.
 */
#ifndef SCICAP_RECON_NERF_SE3_H
#define SCICAP_RECON_NERF_SE3_H

#define NERF_SE3_TAYLOR_THETA 0.1

void nerf_se3_identity(double T[12]);
void nerf_se3_mul(const double A[12], const double B[12], double AB[12]);
void nerf_se3_inv(const double T[12], double Ti[12]);
/* exp of a twist; J (nullable) = ∂vec(T)/∂ξ, 12×6 row-major. */
void nerf_se3_exp(const double xi[6], double T[12], double J[72]);
/* log of a pose (R must be a rotation to ~1e-12; the result has θ <= π). */
void nerf_se3_log(const double T[12], double xi[6]);
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
