/* recon/nerf/trainer.h — the training loop shared by the NeRF-family SCI solvers (rayformer_solve.h,
 * scinerf_solve.h): ray sampling, volume rendering, the SCI measurement loss, Adam, pose optimisation,
 * the trace, checkpoints and the final window-wise render. The radiance field itself is a model behind callbacks.
 *
 * One training step:
 *   1. pick B pixel groups of R = gw·gh rays: overlapping windows (patch sampling: any top-left pixel) or R
 *      scattered random pixels per group (random-ray sampling; the groups are then only a batch shape);
 *   2. camera-frame rays with L stratified (jittered) depths in [near, far]; each group is seen from all N poses
 *      → N·B model groups (the same pixels in every frame, as SCI needs: Y = Σᵢ Mᵢ ⊙ Cᵢ);
 *   3. model forward → σ, rgb → volume rendering (render.h) → grey = mean of the three channels;
 *      optional second (fine) pass: Lf importance samples from the coarse weights (inverse CDF, no gradient
 *      through the sampling), the fine model on the Lc + Lf sorted depths (SCINeRF);
 *   4. loss = (1/P)·Σ_p (Y_p − Σᵢ M_i,p·C_i,p)² (+ the same for the coarse pass when there is a fine one)
 *      + λ·TV(C over the rendered windows)/(N·B·R) — TV only with patch sampling (scattered rays have no
 *      neighbours);
 *   5. backward through rendering and the model(s) → Adam (hash table lazy), lr decayed exponentially from lr
 *      to lr_final; optimised poses: per-point position/direction gradients → ∂loss/∂Tᵢ → twists (poses.h) →
 *      pose Adam with its own warm-up and decay.
 * Inference renders every frame window-wise (non-overlapping gw×gh windows; the last row and column shifted
 * inside the image; with render_tilings 4 the mean of four tilings) at sample midpoints (deterministic importance
 * samples).
 * With ema_steps H > 0 the last 4H steps also keep an exponential moving average of the weights (decay 1 − 1/H,
 * started as a copy; one pass over the weights a step); the renders from then on — the trace's and the final
 * frames — use the average, training never does (instant-ngp reimplementations keep one, JNeRF at decay 0.95).
 *
 * Gauge (pose optimisation): a scene and camera poses fitted together from one snapshot are defined only up to
 * a rigid motion (and scale) of everything; `pose_hold_first` pins pose 1 (its twist gets no update), which fixes
 * the rigid part. Compare poses with nerf_poses_relative_error, which is blind to the gauge.
 *
 * Checkpoints (the trainer's whole state: iteration, parameters, Adam moments and step counts, pose twists and
 * their Adam, the sampling RNG, elapsed time) are byte blobs: recon/ writes no files. checkpoint_fn gets one
 * every checkpoint_every steps and when the run is canceled; `resume` starts from one. A resumed run continues
 * the same step sequence: with the same parameters and thread count it ends bitwise equal to an uninterrupted
 * run. The blob is validated (magic, version, method, sizes, checksum, finite values) before use. A checkpoint of
 * a run with known poses may also start a run that optimises them (the scene first, then the poses): the poses
 * then start as configured.
 * Layout (little-endian, native float/double): header {magic "SCINERF\0", u32 version, u32 flags,
 * char method[NERF_CKPT_METHOD_MAX], i32 w, h, n, iter, u64 n_params[2], u64 n_pose_params, u64 rng[4], f64 wall_s, cpu_s,
 * f32 box[6]},
 * then for each model: params (f32), Adam m, s (f32), steps (u32), with flags bit 0 (a moving average of the
 * weights has begun, ema_steps) its average (f32); pose twists, pose Adam m, v, grad (f64),
 * pose step (i64); then a u64 FNV-1a checksum of everything before it.
 *
 * Errors: 0, SCI_ECANCELED (frames = the model rendered at that point), SCI_EDIVERGED (no frames),
 * -EINVAL / SCI_EFORMAT (bad checkpoint) / -ENOMEM with the message in result->error.
 * Blocks; OpenMP inside the models and the rendering; deterministic for a given seed and thread count.
 */
#ifndef SCICAP_RECON_NERF_TRAINER_H
#define SCICAP_RECON_NERF_TRAINER_H

#include <stddef.h>
#include <stdint.h>

#include "recon/nerf/patch_sampler.h"
#include "recon/nerf/poses.h"
#include "recon/problem.h"

/* Bytes of the method name in a checkpoint header, the NUL included: part of the file format, so it stays 16 even
 * though names may be longer elsewhere (SCI_METHOD_NAME_MAX); solver_list_check refuses a checkpointing method
 * whose name does not fit. */
#define NERF_CKPT_METHOD_MAX 16

/* A radiance field as the trainer sees it. A call evaluates n_groups groups of R rays × L samples each: point
 * (g·R + r)·L + s, pos (n_groups·R·L × 3, world), dir (n_groups·R × 3, unit, world, borrowed until the backward)
 * → sigma (n_groups·R·L), rgb (×3). The backward follows the last forward: d_sigma, d_rgb → grad (n_params,
 * overwritten), d_pos, d_dir (each NULL to skip). Return 0 or a negative code. */
typedef struct nerf_model_ops {
    void (*init)(void *self, float *params, uint64_t seed);
    int (*forward)(void *self, const float *params, int n_groups, int L, const float *pos, const float *dir,
                   float *sigma, float *rgb);
    int (*backward)(void *self, const float *params, const float *d_sigma, const float *d_rgb, float *grad,
                    float *d_pos, float *d_dir);
    /* Optional (NULL: none): told the step about to run (1 … iters) and the coarse-to-fine length c2f_steps of
     * the config, before that step's forward; the final render follows a call with it = iters. */
    void (*progress)(void *self, int it, int iters, int c2f_steps);
} nerf_model_ops;

typedef struct nerf_model {
    const nerf_model_ops *ops;
    void *self;       /* borrowed: the solver owns the network and its workspace */
    size_t n_params;  /* floats */
    size_t n_hash;    /* the first n_hash parameters are a hash table (lazy Adam) */
    size_t n_scaled;  /* parameters [n_hash, n_scaled) learn at lr × net_lr_scale, the rest at lr; 0: every
                         parameter after the table is scaled */
    int max_groups;   /* largest n_groups per call (at least N·B) */
} nerf_model;

/* Called with a checkpoint blob (borrowed for the call) after step `iter`. Nonzero return: the run stops with
 * that code (e.g. a failed write), message in result->error. */
typedef int (*nerf_checkpoint_fn)(const void *blob, size_t bytes, int iter, void *user);

typedef struct nerf_train_config {
    const char *method;           /* "rayformer", "scinerf": messages and checkpoints */
    int iters;                    /* training steps */
    int group_w, group_h;         /* rays per group: the window (patch sampling) or the batch shape */
    int group_stride;             /* patch sampling: pixels between neighbouring rays of a window, in training and
                                     at inference (patch_sampler.h; 0 or 1: adjacent) */
    int group_stride_max;         /* patch sampling, training: > group_stride draws each window's stride from
                                     group_stride … this (nerf_windows_pick); 0 or less: every window group_stride */
    int group_stride_start;       /* patch sampling, training: > group_stride starts every window at this stride and
                                     narrows it to group_stride over the run (coarse-to-fine, nerf_stride_at); 0 or
                                     less: off. Not with group_stride_max */
    int groups_per_step;          /* B, each seen from all N poses */
    int patch_sampling;           /* 1: overlapping windows; 0: scattered random pixels */
    int stratify;                 /* 1: a step's windows (or pixels) one per cell of a grid over the image
                                     (nerf_strata_pick); 0: each uniform on its own */
    int samples;                  /* L (coarse) stratified samples per ray */
    int window_jitter;            /* patch sampling: 1 = the rays of a window share their depth jitter (sample s of
                                     every ray at one depth, as at inference: the points inter-ray attention
                                     mixes); 0 = each ray its own */
    int fine_samples;             /* importance samples of the fine pass (needs a fine model), 0: none */
    double lr, lr_final;          /* network Adam, exponential decay over the run */
    double net_lr_scale;          /* the model's scaled range (nerf_model.n_scaled) learns at lr × this (0: 1) */
    double adam_beta2, adam_eps;  /* network Adam β2, ε (β1 = 0.9) */
    double tv_weight, tv_eps;     /* λ and the Charbonnier ε of the TV term (patch sampling only) */
    nerf_spacing spacing;         /* how the coarse samples divide [near, far] (patch_sampler.h) */
    double distortion_weight;     /* λ_dist of the distortion loss on the coarse weights (loss.h), 0: off */
    int c2f_steps;                /* coarse-to-fine: the model's fine levels fade in over this many steps (0: all
                                     on from the start; models without a progress callback ignore it) */
    double depth_tv_weight;       /* λ of a TV term on the rendered depth (normalised to [0, 1] over near … far)
                                     within each window (RegNeRF's depth smoothness; patch sampling only), 0: off */
    int prior_steps;              /* GAP-TV warm start: for the first prior_steps steps the rendered frames are
                                     also pulled toward GAP-TV's reconstruction, with a weight falling linearly
                                     from prior_weight to 0 (0: off) */
    double prior_weight;
    int ema_steps;                /* H > 0: render with an exponential moving average of the weights (decay
                                     1 − 1/H) kept over the last 4H steps; 0: off */
    nerf_poses_mode pose_mode;    /* KNOWN: problem->camera poses; LINEAR / PER_FRAME: optimised */
    int pose_init_identity;       /* start from the identity (SCINeRF) rather than the camera's poses */
    double pose_perturb_rot_rad;  /* U(±a) added to each rotation component of the initial twists */
    double pose_perturb_trans;    /* U(±a) on each translation component, scene units */
    int pose_hold_first;          /* pin pose 1 (gauge) */
    double pose_lr, pose_lr_final;/* pose Adam, exponential decay */
    int pose_delay;               /* poses stay put for this many steps (the scene forms first), 0: none */
    int pose_warmup;              /* then the pose lr ramps linearly from 0 over this many steps (0: none) */
    int render_tilings;           /* inference: 1 (or 0) = one tiling of non-overlapping windows; 4 = each pixel the
                                     mean of that tiling and the three offset by half a window (models that mix the
                                     rays of a window: a pixel's value depends on the window it sits in, and
                                     training saw it at every position in one); 4× the render's cost */
    int metrics_every;            /* full render for PSNR every k steps (0: only at the end) */
    int ssim_every;               /* SSIM on those renders every k steps (0: only at the end) */
    uint64_t seed;
    int checkpoint_every;         /* 0: only at cancel (if checkpoint_fn) */
    nerf_checkpoint_fn checkpoint_fn;
    void *checkpoint_user;
    const void *resume;           /* borrowed checkpoint blob to start from, or NULL */
    size_t resume_bytes;
    float box_lo[3], box_hi[3];   /* the scene box the models were built with (nerf_train_scene_box); kept in
                                     checkpoints */
} nerf_train_config;

/* The convergence recipe both NeRF solvers share (docs/nerf-methods.md, "The recipe"): where the samples go, the
 * losses against fog, the GAP-TV warm start and the density at initialisation. Copied into nerf_train_config
 * (the first four) and into the model's config (density_bias). */
typedef struct nerf_recipe {
    nerf_spacing spacing;      /* sample spacing along rays */
    double distortion_weight;  /* λ_dist, 0: off */
    double depth_tv_weight;    /* depth smoothness within windows (patch sampling only), 0: off */
    int c2f_steps;             /* coarse-to-fine hash levels over this many steps, 0: off */
    int prior_steps;           /* GAP-TV warm start length, 0: off */
    double prior_weight;       /* its starting weight */
    double density_bias;       /* added before the density activation: ln σ at initialisation (trunc_exp) */
    int ema_steps;             /* evaluate a moving average of the weights over about this many steps, 0: off */
} nerf_recipe;

/* -EINVAL naming the field and its value. */
int nerf_train_config_check(const nerf_train_config *c, sci_error *err);

/* The box every sample may fall in: the frustums between near and far of the initial poses, padded (more when
 * poses are optimised). Poses as the trainer will start them (identity + perturbation, or the camera's). With
 * c->resume, the box stored in the checkpoint (SCI_EFORMAT if the blob is not a valid checkpoint). */
int nerf_train_scene_box(const sci_problem *pb, const nerf_train_config *c, float lo[3], float hi[3],
                         sci_error *err);

/* What both solvers do before building their models: the problem validated (sci_problem_validate), a camera with
 * one pose per frame required (-EINVAL), and c->box_lo/box_hi set by nerf_train_scene_box. Errors name c->method. */
int nerf_train_prepare(const sci_problem *pb, nerf_train_config *c, sci_error *err);

/* Train `coarse` (and `fine`, or NULL) on the problem and render the frames into result (solver contract of
 * problem.h). The models' n_params, n_hash and max_groups must fit the config (max_groups >= N·B; the fine model
 * is called with L = samples + fine_samples). poses_out (N × 12, or NULL) gets the final poses on success and
 * cancel. */
int nerf_train_run(const sci_problem *pb, const nerf_train_config *c, const nerf_model *coarse,
                   const nerf_model *fine, sci_result *result, sci_progress_fn progress, void *user,
                   double (*poses_out)[12]);

/* Checkpoint facts without resuming: the step it was taken after and the method. 0, or SCI_EFORMAT naming what is
 * wrong (magic, version, truncated, checksum). */
int nerf_checkpoint_peek(const void *blob, size_t bytes, int *iter, char method[NERF_CKPT_METHOD_MAX],
                         sci_error *err);

#endif
