/* base/se3.h — rigid motions (SE(3)) in double: exp, log, composition, inverse and the geodesic between two poses.
 * The one implementation the simulator (sim/pose.h, camera paths) and the NeRF solvers (recon/nerf/se3.h, pose
 * optimisation) share, so a path the simulator draws and a path a solver fits are the same curve.
 *
 * A pose is a row-major 3×4 [R | t] (double[12], element (r, c) at 4r + c), camera-to-world in the NeRF
 * convention of recon/problem.h. A twist ξ = [ω (3), u (3)]: rotation vector first (axis × angle, radians; SCINeRF
 * order), then the translational part u (scene units); θ = ‖ω‖, W = [ω]×.
 *   exp: R = I + A·W + B·W², t = V·u, V = I + B·W + C·W²,  A = sinθ/θ, B = (1 − cosθ)/θ², C = (θ − sinθ)/θ³.
 *   log: R → unit quaternion (Shepperd: the largest of the trace and the diagonal as pivot, ties to the trace, then
 *        to the earlier diagonal entry; no acos) → ω = 2·atan2(n, w)/n · v with w >= 0, so θ ∈ [0, π] and θ near π
 *        stays exact (at θ = π exactly the sign of ω is the pivot's); u = V⁻¹ t, V⁻¹ = I − ½W + D·W²,
 *        D = (1 − (θ/2)cot(θ/2))/θ².
 * A, B, C, D and the derivative coefficients switch to their Taylor series below θ = SCI_SE3_TAYLOR_THETA, where
 * the closed forms cancel (closed forms above), so θ = 0, 1e-12, 1e-6 … π are all finite and accurate. Only the
 * selected branch is evaluated.
 *
 * Pure functions: reentrant and thread-safe; outputs may alias inputs (results go through a local first).
 */
#ifndef SCICAP_BASE_SE3_H
#define SCICAP_BASE_SE3_H

#define SCI_SE3_TAYLOR_THETA 0.1

void sci_se3_identity(double T[12]);
/* AB = A·B. */
void sci_se3_mul(const double A[12], const double B[12], double AB[12]);
/* Ti = T⁻¹ = [Rᵀ | −Rᵀt]. */
void sci_se3_inv(const double T[12], double Ti[12]);
/* T = exp(ξ); J (nullable) = ∂vec(T)/∂ξ, 12×6 row-major, exact. */
void sci_se3_exp(const double xi[6], double T[12], double J[72]);
/* ξ = log(T); R must be a rotation (orthonormal, det +1) to ~1e-12. θ ∈ [0, π]. */
void sci_se3_log(const double T[12], double xi[6]);
/* The rotation matrix (row-major 3×3) of rotation vector w (radians): the R of sci_se3_exp. */
void sci_se3_rot_exp(const double w[3], double R[9]);
/* The geodesic T(τ) = T0·exp(τ·log(T0⁻¹·T1)). τ = 0 and τ = 1 return copies of T0 and T1 bit for bit (a camera path
 * must hit its end poses exactly); other τ, also outside [0, 1], interpolate or extrapolate along it. */
void sci_se3_geodesic(const double T0[12], const double T1[12], double tau, double T[12]);

#endif
