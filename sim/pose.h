/* sim/pose.h — rigid camera poses (SE(3)) in double: exp, log, composition and the geodesic between two poses.
 *
 * A pose is a row-major 3×4 matrix [R | t] (12 doubles), camera-to-world in the NeRF convention of
 * recon/problem.h. A twist ξ = (ρ, ω) has ρ the translational part (scene units) and ω the rotation vector
 * (axis × angle, radians); exp(ξ) = [exp([ω]×) | V ρ] (docs/conventions.md §11).
 *
 * The arithmetic is base/se3.h's (the one SE(3) implementation, shared with the NeRF solvers' pose optimisation:
 * Taylor branches near 0, a quaternion log exact near π); these are the simulator's names for it, with the twist in
 * sim's order (ρ, ω). Pure functions; thread-safe.
 */
#ifndef SCICAP_SIM_POSE_H
#define SCICAP_SIM_POSE_H

/* T = exp(xi), xi = (rho[3], omega[3]). */
void sim_pose_exp(const double xi[6], double T[12]);
/* xi = log(T); R must be a rotation (orthonormal, det +1) to about 1e-9. Angle in [0, π]. */
void sim_pose_log(const double T[12], double xi[6]);
/* C = A·B. */
void sim_pose_mul(const double A[12], const double B[12], double C[12]);
/* Ti = T⁻¹ = [Rᵀ | −Rᵀt]. */
void sim_pose_inv(const double T[12], double Ti[12]);
/* The SE(3) geodesic T(τ) = T0·exp(τ·log(T0⁻¹·T1)). τ = 0 and τ = 1 return copies of T0 and T1 bit for bit (the
 * path must hit its end poses exactly, docs/conventions.md §12); other τ (also outside [0, 1]) interpolate or
 * extrapolate along the geodesic. */
void sim_pose_interp(const double T0[12], const double T1[12], double tau, double T[12]);
/* Rotation matrix (row-major 3×3) of rotation vector w (radians). */
void sim_rot_exp(const double w[3], double R[9]);
/* Camera-to-world pose of a camera at `eye` looking at `target` with `up` roughly up (NeRF axes: the camera's
 * −z points at the target, +y towards `up`). Returns -1 if eye == target or up is parallel to the view line. */
int sim_pose_look_at(const double eye[3], const double target[3], const double up[3], double T[12]);

#endif
