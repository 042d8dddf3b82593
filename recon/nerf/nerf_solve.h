/* recon/nerf/nerf_solve.h — the solver shell every NeRF-family method shares: the settings that are not about the
 * network (steps, samples, learning rate, the recipe, poses, trace, seed, threads, checkpoints), their mapping onto
 * the trainer's configuration, the checks, and the run (validate → scene box → build the model(s) → train →
 * free). A method (rayformer_solve.c, scinerf_solve.c) supplies only its network: a nerf_solve_method with the
 * model part of the configuration and the build/free of its model(s).
 *
 * The shared settings are spliced into each method's params struct as an anonymous union of the named struct and
 * the same fields unnamed, so callers keep writing p.seed while the shell reads &p.shared:
 *
 *     typedef struct sci_xxx_params {
 *         int width;                                          // the method's own knobs
 *         union { nerf_solve_shared shared; struct { NERF_SOLVE_SHARED_FIELDS }; };
 *     } sci_xxx_params;
 *
 * (Both members have the same fields in the same order, so reading one after writing the other is defined: C11
 * 6.5.2.3 common initial sequence.)
 *
 * Errors: 0 or a negative code with the message in err / result->error, naming the method. Blocks; OpenMP;
 * deterministic for a given seed and thread count.
 */
#ifndef SCICAP_RECON_NERF_NERF_SOLVE_H
#define SCICAP_RECON_NERF_NERF_SOLVE_H

#include "recon/nerf/poses.h"
#include "recon/nerf/trainer.h"
#include "recon/problem.h"
#include "recon/solver.h"

/* The field list of nerf_solve_shared; units and meanings in the struct below. */
#define NERF_SOLVE_SHARED_FIELDS                                                                                       \
    int iters;                                                                                                         \
    int samples;                                                                                                       \
    double lr, lr_final;                                                                                               \
    nerf_recipe recipe;                                                                                                \
    nerf_poses_mode pose_mode;                                                                                         \
    int pose_init_identity;                                                                                            \
    double pose_perturb_rot_rad;                                                                                       \
    double pose_perturb_trans;                                                                                         \
    double pose_lr, pose_lr_final;                                                                                     \
    int pose_delay, pose_warmup, pose_hold_first;                                                                      \
    int metrics_every, ssim_every;                                                                                     \
    unsigned long long seed;                                                                                           \
    int threads;                                                                                                       \
    int checkpoint_every;                                                                                              \
    nerf_checkpoint_fn checkpoint_fn;                                                                                  \
    void *checkpoint_user;                                                                                             \
    const void *resume;                                                                                                \
    size_t resume_bytes;

/* What every NeRF method's params hold besides the network:
 *   iters                 training steps, >= 1
 *   samples               L, (coarse) stratified samples per ray
 *   lr, lr_final          network Adam learning rate, decayed exponentially over the steps
 *   recipe                sampling, anti-fog losses, warm start, density init (trainer.h)
 *   pose_mode             KNOWN: problem->camera poses; LINEAR / PER_FRAME: optimised jointly
 *   pose_init_identity    optimised poses start from the identity (SCINeRF) instead of the camera's
 *   pose_perturb_rot_rad  U(±a) on each rotation component of the initial twists (radians)
 *   pose_perturb_trans    U(±a) on each translation component (scene units)
 *   pose_lr, pose_lr_final  pose Adam, decayed exponentially
 *   pose_delay            poses stay put for this many steps (the scene forms first)
 *   pose_warmup           then the pose lr ramps up from 0 over this many steps (0: none)
 *   pose_hold_first       gauge: pose 1 stays where it starts
 *   metrics_every         full render for PSNR every k steps (0: only at the end)
 *   ssim_every            SSIM on those renders every k steps (0: only at the end)
 *   seed                  the run's RNG seed
 *   threads               OpenMP threads for the network, 0: omp_get_max_threads()
 *   checkpoint_every      hand a checkpoint to checkpoint_fn every k steps and at the end (0: only on cancel)
 *   checkpoint_fn, checkpoint_user  NULL: no checkpoints
 *   resume, resume_bytes  borrowed checkpoint blob to continue from (same problem and network), or NULL */
typedef struct nerf_solve_shared {
    NERF_SOLVE_SHARED_FIELDS
} nerf_solve_shared;

/* The shared settings' keys for the solver table (recon/solver.h), offsets within nerf_solve_shared: a method's
 * row lists them as its second field group with base = offsetof(params, shared). */
#define NERF_SOLVE_FIELD_COUNT 25
extern const solver_field nerf_solve_fields[];

/* A NeRF method: its network behind the shell. */
typedef struct nerf_solve_method {
    const char *name;        /* "rayformer": result->method, messages, checkpoints */
    size_t params_size;      /* sizeof its params struct */
    size_t shared_offset;    /* offsetof(params, shared) */
    /* The method's own checks (network sizes, switches); -EINVAL naming the method and field. */
    int (*check)(const void *params, sci_error *err);
    /* The model part of the trainer's configuration (groups, sampling, optimiser constants, TV), after the shared
     * part was filled by nerf_solve_config. */
    void (*config)(const void *params, nerf_train_config *c);
    /* Build the model(s) for a run on `problem` with configuration tc (its scene box set) and `threads` threads:
     * models[0] (coarse) and, when *n_models is set to 2, models[1] (fine); *state is what free_models releases
     * (also after a failure). */
    int (*build)(const void *params, const sci_problem *problem, const nerf_train_config *tc, int threads,
                 void **state, nerf_model models[2], int *n_models, sci_error *err);
    void (*free_models)(void *state);
} nerf_solve_method;

/* The trainer's configuration of params: shared part, then the method's. */
void nerf_solve_config(const nerf_solve_method *m, const void *params, nerf_train_config *c);
/* Shared checks (threads), the method's, then the trainer's on the resulting configuration. */
int nerf_solve_check(const nerf_solve_method *m, const void *params, sci_error *err);
/* The run (solver contract of rayformer_solve.h); poses_out (N × 12, nullable) gets the final poses. */
int nerf_solve_run(const nerf_solve_method *m, const sci_problem *problem, const void *params, sci_result *result,
                   sci_progress_fn progress, void *user, double (*poses_out)[12]);
/* The same from the solver table: a copy of params with io's checkpoint hooks and resume blob (when io sets
 * them), io's progress and poses_out. */
int nerf_solve_run_io(const nerf_solve_method *m, const sci_problem *problem, const void *params,
                      const solver_io *io, sci_result *result);

/* The methods' common preset words: -EINVAL unless name is fast, balanced or best (index in *p). */
int nerf_solve_preset_index(const char *name, solver_preset *p);

#endif
