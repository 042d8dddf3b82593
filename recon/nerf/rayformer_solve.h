/* recon/nerf/rayformer_solve.h — `scicap recon --method rayformer`: train a RayFormer radiance field (rayformer.h)
 * on one SCI snapshot of a static scene seen by a moving camera, then render the N frames (the RayFormer paper).
 *
 * The training loop is the shared NeRF trainer (trainer.h): B patch locations per step (overlapping windows: any
 * top-left pixel), each rendered from all N poses (N·B network patches), loss
 *     (1/P)·Σ_p (Y_p − Σ_i M_i,p·C_i,p)² + λ·mean TV(C over the rendered patches),
 * C the grey value = mean of the network's three colour channels (the problem is monochrome); Adam on the network
 * (hash table lazy), lr decayed exponentially from lr to lr_final. Poses: known (problem->camera, fixed), or
 * optimised jointly (start/end on SE(3), or per frame; poses.h). At the end the N frames are rendered window-wise
 * (non-overlapping patches) at sample midpoints into result->frames.
 *
 * The paper's ablation, each step switched on its own (sci_rayformer_params_ablation gives the ladder):
 *   patch_sampling  0: every "patch" is patch² scattered random pixels (the random-ray baseline)
 *   inter_ray       0: the inter-ray attention path passes V through (attention.h); 1: with the defaults it
 *                   is behind a learned gate per head that starts closed (inter_gate) and carries a city-block
 *                   bias (inter_slope) — both this project's, not the paper's
 *   intra_ray       0: the intra-ray path passes V through
 *   tv_weight       0: no TV term (TV needs patch sampling: it is ignored without it)
 * Presets (sci_rayformer_params_preset): "fast", "balanced", "best" — cost and accuracy in bench/results/.
 *
 * Trace: every step gets loss and the residual ‖Y − Ŷ‖ over the trained pixels relative to the RMS of the whole
 * snapshot; every metrics_every steps (and at the last) the full N frames are rendered for PSNR/SSIM; that
 * intermediate render is excluded from wall time like the tracer's own metrics; the final render counts.
 * Checkpoints and resume: trainer.h (blobs; the caller stores them).
 * Contract as gaptv.h: validates, fills result->frames and trace, returns 0, SCI_ECANCELED (frames = the model
 * rendered at that point), SCI_EDIVERGED (no frames), or an error with its message in result->error. Needs
 * problem->camera. Blocks; OpenMP; deterministic for a given seed and thread count.
 */
#ifndef SCICAP_RECON_NERF_RAYFORMER_SOLVE_H
#define SCICAP_RECON_NERF_RAYFORMER_SOLVE_H

#include "recon/nerf/nerf_solve.h"
#include "recon/nerf/poses.h"
#include "recon/nerf/trainer.h"
#include "recon/problem.h"

typedef struct sci_rayformer_params {
    int patch;                   /* patch side: 2, 4, 8 or 16 (paper: 8) */
    int patches_per_step;        /* B, patch locations per step, each rendered from all N poses */
    int blocks;                  /* I²R transformer blocks, 1 … 8 (0: 2, the default network) */
    int log2_table;              /* hash table entries per level, log2 (10 … 24) */
    double finest_res;           /* finest hash-grid resolution (the coarsest is 16) */
    int sh_degree;               /* direction encoding degree 1 … 4 (4: the paper's 16 SH outputs) */
    double net_lr_scale;         /* the transformer learns at lr × this, the hash table at lr (0: 1) */
    int heads_full_lr;           /* 1: only the transformer blocks are scaled, the final LN and the density and colour
                                    heads learn at lr; 0: the heads are scaled too */
    double adam_eps;             /* Adam's ε for every parameter, 1e-30 … 1 (1e-15, instant-ngp's: a parameter's step
                                    is lr-sized however small its gradient; adam.h) */
    double tv_weight;            /* λ of the TV term (0: off) */
    double tv_eps;               /* Charbonnier ε of the TV term (0: plain |d|) */
    int patch_sampling;          /* 1: patches; 0: scattered random rays in groups of patch² (ablation baseline) */
    int inter_ray, intra_ray;    /* 1: the attention path; 0: pass-through (ablation) */
    double intra_slope;          /* intra-ray distance bias, 0 … 100: head h adds −(slope/2^h)·|i − j| to the logit
                                    of sample i for sample j (attention.h; 0: the paper's position-free attention) */
    double inter_slope;          /* inter-ray distance bias, 0 … 100: head h adds −(slope/2^h)·(|Δx| + |Δy|), the
                                    pixel offset between rays i and j in their window (attention.h; 0: none) */
    int zero_gates;              /* 1: each block's output projections start at zero (the block starts as the
                                    identity, ReZero/LayerScale-style); 0: Kaiming-uniform */
    int final_norm;              /* 1: layer norm before the density head (pre-norm transformers); 0: the head reads
                                    the features as they are, as SCINeRF's MLP reads the hash features */
    int head_hidden;             /* 0: density and geometry from one FC layer (the paper); > 0: a ReLU layer first */
    int render_tilings;          /* inference: 1 = one tiling of windows, 4 = the mean of four offset by half a
                                    window (trainer.h); only inter-ray attention makes them differ */
    int inter_gate;              /* 1: the inter-ray path's output is v + g·(attention − v), g learned per head from 0
                                    (the path starts as the + patch rung's pass-through; block.h); 0: the attention */
    int patch_stride;            /* pixels between neighbouring rays of a window, 1 … 8, in training and at
                                    inference (1: adjacent, the paper's patches; d > 1: dilated windows spanning
                                    (patch − 1)·d + 1 pixels a side, patch_sampler.h) */
    int patch_stride_max;        /* training: > patch_stride draws each window's stride from patch_stride … this, at
                                    most 8 (GRAF's random patch scale, nerf_windows_pick); 0: every window
                                    patch_stride. Inference keeps patch_stride */
    int patch_stride_start;      /* training: > patch_stride starts every window at this stride, at most 8, and
                                    narrows it to patch_stride over the run (coarse-to-fine, nerf_stride_at); 0:
                                    off. Not with patch_stride_max */
    int stratify;                /* 1: a training step's windows (scattered rays without patch sampling) one per cell of
                                    a grid over the image; 0: each uniform (trainer.h) */
    int window_jitter;           /* with inter-ray attention: 1 = in training the rays of a window share their depth
                                    jitter, so sample s of each ray lies at one depth, as at inference (trainer.h);
                                    0 = each ray its own */
    /* iters, samples (L per ray, paper 32), lr, lr_final, recipe, pose_*, metrics_every, ssim_every, seed, threads,
     * checkpoint_*, resume*: the settings every NeRF method shares (recon/nerf/nerf_solve.h) */
    union {
        nerf_solve_shared shared;
        struct {
            NERF_SOLVE_SHARED_FIELDS
        };
    };
} sci_rayformer_params;

/* The defaults: the "balanced" preset. */
void sci_rayformer_params_default(sci_rayformer_params *p);
/* Overwrite the cost/accuracy fields (iters, patch, patches_per_step, samples, hash table, lr) with a preset:
 * "fast" (a 128×128×8 scene in a few minutes on 2 cores), "balanced", "best". -EINVAL for an unknown name. */
int sci_rayformer_params_preset(sci_rayformer_params *p, const char *name);
/* The paper's ablation ladder (Table 2), step 0 … 4: baseline (random rays, no attention, no TV), + patch
 * sampling, + inter-ray attention, + intra-ray attention, + TV (= the full method). Sets patch_sampling,
 * inter_ray, intra_ray and tv_weight (to tv_weight_full at step 4, 0 before); -EINVAL outside 0 … 4. */
int sci_rayformer_params_ablation(sci_rayformer_params *p, int step, double tv_weight_full);
extern const char *const sci_rayformer_ablation_names[5]; /* "baseline", "+patch", "+inter", "+intra", "+tv" */
/* -EINVAL with a message naming the parameter and its value. */
int sci_rayformer_params_check(const sci_rayformer_params *p, sci_error *err);

int sci_rayformer_solve(const sci_problem *problem, const sci_rayformer_params *params, sci_result *result,
                        sci_progress_fn progress, void *user);
/* The same, also writing the final N camera-to-world poses (optimised or given) to poses_out when it is not NULL
 * (on success and on cancel). */
int sci_rayformer_solve_ex(const sci_problem *problem, const sci_rayformer_params *params, sci_result *result,
                           sci_progress_fn progress, void *user, double (*poses_out)[12]);

/* The method's row in the solver table (recon/solver.h): settings sci_rayformer_params, presets as above, the
 * ablation ladder as the "ablation" key (baseline, patch, inter, intra, tv). */
extern const solver_ops sci_rayformer_solver;

#endif
