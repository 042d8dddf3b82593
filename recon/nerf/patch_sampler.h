/* recon/nerf/patch_sampler.h — rays of pixel patches (RayFormer's patch-level sampling) or of scattered pixels.
 *
 * A patch is pw × ph pixels whose top-left pixel is (x0, y0); ray r = y·pw + x sees pixel (x0 + d·x, y0 + d·y),
 * d >= 1 the window's stride (1: adjacent pixels; d > 1 spreads the same rays over ((pw − 1)·d + 1)² pixels, as
 * GRAF's dilated patches do, for more of the image a step at the same rays). A
 * "scattered" patch has the same shape but its rays are arbitrary pixels (the random-ray baseline: the network still
 * sees pw·ph rays at a time). Samples along a ray lie at depths t_s = near + (s + u_s)·(far − near)/L along −z in the
 * camera frame (linear spacing; nerf_spacing for the others), u_s = 0.5 at inference and U(0, 1) (stratified
 * jitter) in training; δ_s = (far − near)/L·‖d‖
 * with d = ((px + 0.5 − cx)/fx, −(py + 0.5 − cy)/fy, −1) the pixel's camera-frame direction (problem.h).
 *
 * The camera-frame arrays do not depend on the pose, so one fill serves all N poses of a snapshot; the world-frame
 * positions and unit directions come from nerf_patch_to_world. Reentrant: no state but the caller's jitter stream,
 * which nerf_rays_camera advances.
 */
#ifndef SCICAP_RECON_NERF_PATCH_SAMPLER_H
#define SCICAP_RECON_NERF_PATCH_SAMPLER_H

#include "base/rng.h"
#include "recon/problem.h"

/* How the L bins of a ray divide [near, far]: equal steps in depth t (NeRF), in disparity 1/t (forward-facing
 * scenes: bins follow the pixel footprint's parallax), or in log t (geometric). The last two need near > 0
 * (otherwise linear). */
typedef enum nerf_spacing { NERF_SPACING_LINEAR = 0, NERF_SPACING_DISPARITY = 1, NERF_SPACING_LOG = 2 } nerf_spacing;
/* Depth at fraction s ∈ [0, 1] of the way from near to far under a spacing. */
double nerf_depth_at(nerf_spacing sp, double near, double far, double s);
/* Camera-frame rays of n_rays pixels (px[r], py[r]) with L samples: pcam n_rays×L×3 (points), dcam n_rays×3 (unit
 * directions), delta n_rays×L (the bin's length × ‖d‖). Bin s spans fractions [s/L, (s+1)/L] of the spacing;
 * the sample sits at (s + u)/L, u = 0.5 with jitter NULL, else U(0, 1). share >= 1: consecutive runs of `share`
 * rays use the same L draws (sample s at one depth across the run, as at inference: what inter-ray attention
 * compares); 1 (or less): each ray its own. The stream advances by L draws per run. */
void nerf_rays_camera(const sci_camera *cam, int n_rays, const int *px, const int *py, int L, double near,
                      double far, nerf_spacing spacing, sci_rng *jitter, int share, float *pcam, float *dcam,
                      float *delta);
/* Camera-frame points at given depths along −z: t (n_rays×L, non-decreasing along each ray, in [near, far]) →
 * pcam (n_rays×L×3), dcam (n_rays×3) and delta (n_rays×L): δ_s = (t_{s+1} − t_s)·‖d‖, the last (far − t_{L−1})·‖d‖,
 * clamped at 0. The depth of a point of nerf_rays_camera is −pcam_z. */
void nerf_rays_camera_depths(const sci_camera *cam, int n_rays, const int *px, const int *py, int L, const float *t,
                             double far, float *pcam, float *dcam, float *delta);
/* Pixels of a patch: px, py (pw·ph each) for the patch at (x0, y0) with stride d >= 1. */
void nerf_patch_pixels(int x0, int y0, int pw, int ph, int d, int *px, int *py);
/* B training windows of pw × ph rays on a w × h image: window b's pixels to px, py [b·pw·ph, (b + 1)·pw·ph). Each
 * window's stride is d0 or, with d1 > d0, drawn per window uniformly from d0 … d1 (GRAF's random patch scale: some
 * windows adjacent for what joins neighbours, some spread for coverage), placed centred in the span of a stride-d1
 * window so every stride reaches the image alike. The corners are stratified over the positions of the widest
 * window (nerf_strata_pick) or, stratify 0, uniform. Needs w, h >= the widest window's span, d0 >= 1. Draws from
 * rng: the corners (two uniforms or nerf_strata_pick's draws each), then one bounded draw a window when d1 > d0. */
void nerf_windows_pick(int B, int w, int h, int pw, int ph, int d0, int d1, int stratify, sci_rng *rng, int *px,
                       int *py);
/* The windows' stride at training step it of 1 … iters when they start at d_start and narrow to d_end
 * (coarse-to-fine: wide windows cover more of the image while the field takes its coarse shape, adjacent ones
 * give the attention and TV their neighbours at the end): d_start − (d_start − d_end)·(it − 1)/iters, rounded. With
 * k = d_start − d_end the run's first 1/(2k) is at d_start, its last 1/(2k) at d_end, 1/k at each stride between.
 * d_start <= d_end: d_end throughout. */
int nerf_stride_at(int d_end, int d_start, int it, int iters);
/* Pixels a patch of side p with stride d spans along one axis: (p − 1)·d + 1. */
static inline int nerf_patch_span(int p, int d) { return (p - 1) * d + 1; }
/* Window t of the inference tiling of a w × h image by pw × ph windows of stride d, shifted (ox, oy) pixels up and
 * left (0 <= ox < pw·d, 0 <= oy < ph·d): blocks of pw·d × ph·d pixels, nerf_tile_count(...) windows, each block
 * d² windows offset (0 … d − 1)² that interleave to cover it. Blocks are clamped inside the image, never single
 * windows, so every pixel belongs to at least one window (overlaps only where a clamped block meets its neighbour);
 * needs w >= pw·d and h >= ph·d. Writes the window's top-left pixel. */
int nerf_tile_count(int w, int h, int pw, int ph, int d, int ox, int oy);
void nerf_tile_window(int t, int w, int h, int pw, int ph, int d, int ox, int oy, int *x0, int *y0);
/* n positions (x[k], y[k]) in [0, span_x) × [0, span_y), stratified: the rectangle is cut into a gx × gy grid
 * (gx·gy ≥ n cells of about equal area and aspect), n cells evenly spaced in row-major order from a random start
 * are chosen, and each position is uniform in its cell, so every step's positions cover the whole rectangle while
 * each pixel stays equally likely. With fewer cells than n (a rectangle smaller than n pixels) cells repeat.
 * n, span_x, span_y >= 1. Draws from rng: one bounded draw for the start, then two uniforms a position. */
void nerf_strata_pick(int n, int span_x, int span_y, sci_rng *rng, int *x, int *y);
/* World frame under camera-to-world pose T: pos = R·pcam + t (n_rays·L points), dir = R·dcam (n_rays). */
void nerf_rays_to_world(const double T[12], int n_rays, int L, const float *pcam, const float *dcam, float *pos,
                        float *dir);
/* Axis-aligned box holding every sample of every pose (camera centres and the frustum corners at near and far),
 * grown by `pad` (fraction of each side). */
void nerf_rays_bounds(const sci_camera *cam, int w, int h, const double (*poses)[12], int n, double near, double far,
                      double pad, float lo[3], float hi[3]);

#endif
