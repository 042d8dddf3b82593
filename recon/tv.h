/* recon/tv.h — the anisotropic TV denoiser of the MATLAB reference (PnP-SCI / DeSCI TV_denoising.m;
 * docs/conventions.md §3).
 *
 * Per frame, a Chambolle-type dual projection with α = 5 and duals that start at zero on every call:
 *     repeat n times:  u = f − ½(D_hᵀ z_h + D_vᵀ z_v)
 *                      z_h ← clip(z_h + D_h u / α, w/2),  z_v ← clip(z_v + D_v u / α, w/2)
 * returning the u of the last pass, which was computed before the last dual update: n passes use n − 1 dual
 * updates and n = 1 returns f. The last, unused dual update is skipped (same output, less work).
 *
 * Plan/execute: a sci_tv holds one dual workspace per thread for frames of w×h; sci_tv_denoise is then
 * allocation-free. Frames are independent and run in parallel (OpenMP over frames), so the result does not
 * depend on thread count. One sci_tv must not be used by two callers at once.
 */
#ifndef SCICAP_RECON_TV_H
#define SCICAP_RECON_TV_H

#include "base/cube.h"
#include "base/error.h"

typedef struct sci_tv sci_tv;

/* A plan for frames of w×h. -EINVAL for sizes < 1, -ENOMEM. */
int sci_tv_new(sci_tv **out, int w, int h, sci_error *err);
void sci_tv_free(sci_tv *tv);

/* Denoise every frame of x in place with weight `weight` (on the data's scale; 0.07 for /255 data) and `iters`
 * passes (>= 1). x must be w×h×n with the plan's w and h. */
void sci_tv_denoise(sci_tv *tv, sci_cube *x, float weight, int iters);

/* The same, calling pre(frame, k, ctx) on each frame just before denoising it, in the same thread: solvers fuse
 * their per-frame data step with the denoiser this way, so each frame is touched while it is in cache. */
void sci_tv_denoise_with(sci_tv *tv, sci_cube *x, float weight, int iters,
                         void (*pre)(float *frame, int k, void *ctx), void *ctx);

/* The same on one frame: u = TV(f), with caller-provided scratch of sci_tv_frame_work_floats(w, h) floats
 * (overwritten). f and u may alias. */
void sci_tv_denoise_frame(const float *f, float *u, int w, int h, float weight, int iters, float *work);
size_t sci_tv_frame_work_floats(int w, int h);

#endif
