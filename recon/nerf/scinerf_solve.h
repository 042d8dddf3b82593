/* recon/nerf/scinerf_solve.h — `scicap recon --method scinerf`: a SCINeRF-style reconstruction (an MLP radiance field,
 * mlp.h) of the N frames of a static scene seen by a camera moving during the exposure, from one SCI snapshot.
 *
 * As SCINeRF (docs/conventions.md §7): random ray sampling (each step: `rays_per_step` pixels drawn anywhere in
 * the image, the same pixels rendered from all N poses), stratified samples, optional coarse + fine importance
 * sampling with two networks and the loss summed over both, loss ‖Y − Σᵢ Mᵢ ⊙ Cᵢ‖² on the sampled pixels, Adam
 * with an exponentially decayed learning rate, poses known or optimised jointly (start/end on SE(3), or per frame),
 * from the camera's poses or from the identity with a small perturbation. The network: frequency encoding and
 * a deep ReLU trunk (SCINeRF's 8 × 256), or a hash encoding with a narrow trunk (the Instant-NGP variant, much
 * cheaper on a CPU). The shared trainer (trainer.h) runs the loop, the trace, checkpoints and the final render
 * (in 8 × 8 windows; the windows are only a batch shape here).
 *
 * Contract as rayformer_solve.h: validates, fills result->frames and the trace, returns 0, SCI_ECANCELED,
 * SCI_EDIVERGED, or an error with its message in result->error. Needs problem->camera. Blocks; OpenMP;
 * deterministic for a given seed and thread count.
 */
#ifndef SCICAP_RECON_NERF_SCINERF_SOLVE_H
#define SCICAP_RECON_NERF_SCINERF_SOLVE_H

#include "recon/nerf/mlp.h"
#include "recon/nerf/nerf_solve.h"
#include "recon/nerf/poses.h"
#include "recon/nerf/trainer.h"
#include "recon/problem.h"

typedef struct sci_scinerf_params {
    int rays_per_step;           /* random pixels per step (a multiple of 64), each rendered from all N poses */
    int fine_samples;            /* importance samples of the fine network (SCINeRF 64; 0: one network) */
    nerf_mlp_pos_enc pos_enc;    /* NERF_MLP_POS_FREQ (SCINeRF) or NERF_MLP_POS_HASH */
    int pos_freqs;               /* frequency encoding: octaves (SCINeRF 10) */
    int log2_table;              /* hash encoding: entries per level, log2 */
    double finest_res;           /* hash encoding: finest resolution */
    int depth, width, skip;      /* trunk (SCINeRF 8, 256, 4; skip −1: none) */
    int feature_dim;             /* features before the colour head (SCINeRF 256) */
    int color_hidden;            /* colour head hidden width (SCINeRF 128; 0: one layer) */
    nerf_mlp_dir_enc dir_enc;    /* NERF_MLP_DIR_FREQ (SCINeRF, 4 octaves) or NERF_MLP_DIR_SH */
    int sh_degree;               /* SH directions: 1 … 4 (1: a constant, i.e. view-independent colour) */
    /* iters, samples (coarse stratified samples per ray, SCINeRF 64), lr, lr_final, recipe, pose_* (pose_mode
     * KNOWN, LINEAR — SCINeRF's default — or PER_FRAME), metrics_every, ssim_every, seed, threads, checkpoint_*,
     * resume*: the settings every NeRF method shares (recon/nerf/nerf_solve.h) */
    union {
        nerf_solve_shared shared;
        struct {
            NERF_SOLVE_SHARED_FIELDS
        };
    };
} sci_scinerf_params;

/* The defaults: the "balanced" preset (hash encoding, 2 × 64 trunk, no fine network). */
void sci_scinerf_params_default(sci_scinerf_params *p);
/* "fast", "balanced", "best" on the hash-encoded field (best adds 32 importance samples with a fine network):
 * overwrites the network and cost fields; bench/results/nerf_recon.md measures them. -EINVAL for an unknown name. */
int sci_scinerf_params_preset(sci_scinerf_params *p, const char *name);
/* SCINeRF's own network and sampling (frequency encoding, 8 × 256, coarse 64 + fine 64, lr 5e-4, pose lr 1e-3):
 * overwrites the network fields, keeps iters and rays. About 0.05 Mpoints/s forward + backward on 2 cores: slow. */
void sci_scinerf_params_paper(sci_scinerf_params *p);
/* -EINVAL with a message naming the parameter and its value. */
int sci_scinerf_params_check(const sci_scinerf_params *p, sci_error *err);

int sci_scinerf_solve(const sci_problem *problem, const sci_scinerf_params *params, sci_result *result,
                      sci_progress_fn progress, void *user);
/* The same, also writing the final N poses to poses_out when it is not NULL (on success and on cancel). */
int sci_scinerf_solve_ex(const sci_problem *problem, const sci_scinerf_params *params, sci_result *result,
                         sci_progress_fn progress, void *user, double (*poses_out)[12]);

/* The method's row in the solver table (recon/solver.h): settings sci_scinerf_params, presets as above. */
extern const solver_ops sci_scinerf_solver;

#endif
