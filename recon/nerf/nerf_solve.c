/* recon/nerf/nerf_solve.c — the NeRF solver shell shared by every NeRF method (see nerf_solve.h). */
#include "recon/nerf/nerf_solve.h"

#include <errno.h>
#include <omp.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const pose_mode_names[] = {"known", "linear", "per-frame", NULL};
static const char *const spacing_names[] = {"linear", "disparity", "log", NULL};

#define SH(k, t, f, lo, hi, help) {k, t, offsetof(nerf_solve_shared, f), lo, hi, NULL, 0, help}
#define SH_ENUM(k, f, names, help) {k, SOLVER_FIELD_ENUM, offsetof(nerf_solve_shared, f), 0, 0, names, 0, help}
const solver_field nerf_solve_fields[] = {
    SH("iters", SOLVER_FIELD_INT, iters, 1, 1e7, "training steps"),
    SH("samples", SOLVER_FIELD_INT, samples, 2, 1024, "(coarse) samples per ray"),
    SH("lr", SOLVER_FIELD_DOUBLE, lr, 0, 10, "network learning rate at the start"),
    SH("lr_final", SOLVER_FIELD_DOUBLE, lr_final, 0, 10, "network learning rate at the end"),
    SH_ENUM("spacing", recipe.spacing, spacing_names, "how the coarse samples divide [near, far]"),
    SH("distortion_weight", SOLVER_FIELD_DOUBLE, recipe.distortion_weight, 0, 1e6, "distortion loss weight"),
    SH("depth_tv_weight", SOLVER_FIELD_DOUBLE, recipe.depth_tv_weight, 0, 1e6, "depth TV weight within windows"),
    SH("c2f_steps", SOLVER_FIELD_INT, recipe.c2f_steps, 0, 1e7, "coarse-to-fine hash levels over this many steps"),
    SH("prior_steps", SOLVER_FIELD_INT, recipe.prior_steps, 0, 1e7, "GAP-TV warm start length"),
    SH("prior_weight", SOLVER_FIELD_DOUBLE, recipe.prior_weight, 0, 1e6, "GAP-TV warm start weight"),
    SH("ema_steps", SOLVER_FIELD_INT, recipe.ema_steps, 0, 1e6, "evaluate a moving average of the weights (steps)"),
    SH("density_bias", SOLVER_FIELD_DOUBLE, recipe.density_bias, -1e3, 1e3, "added before the density activation"),
    SH_ENUM("pose_mode", pose_mode, pose_mode_names, "camera poses: known, or optimised (linear, per-frame)"),
    SH("pose_init_identity", SOLVER_FIELD_BOOL, pose_init_identity, 0, 1, "optimised poses start at the identity"),
    SH("pose_perturb_rot_rad", SOLVER_FIELD_DOUBLE, pose_perturb_rot_rad, 0, 10, "initial twist rotation noise"),
    SH("pose_perturb_trans", SOLVER_FIELD_DOUBLE, pose_perturb_trans, 0, 1e6, "initial twist translation noise"),
    SH("pose_lr", SOLVER_FIELD_DOUBLE, pose_lr, 0, 10, "pose learning rate at the start"),
    SH("pose_lr_final", SOLVER_FIELD_DOUBLE, pose_lr_final, 0, 10, "pose learning rate at the end"),
    SH("pose_delay", SOLVER_FIELD_INT, pose_delay, 0, 1e7, "steps before the poses move"),
    SH("pose_warmup", SOLVER_FIELD_INT, pose_warmup, 0, 1e7, "pose learning-rate ramp"),
    SH("pose_hold_first", SOLVER_FIELD_BOOL, pose_hold_first, 0, 1, "pose 1 stays put (gauge)"),
    SH("metrics_every", SOLVER_FIELD_INT, metrics_every, 0, 1e9, "full render for PSNR every k steps"),
    SH("ssim_every", SOLVER_FIELD_INT, ssim_every, 0, 1e9, "SSIM every k steps"),
    SH("seed", SOLVER_FIELD_SEED, seed, 0, 9007199254740992.0, "RNG seed"),
    SH("threads", SOLVER_FIELD_INT, threads, 0, 1024, "OpenMP threads (0: all)"),
};
_Static_assert(sizeof nerf_solve_fields / sizeof nerf_solve_fields[0] == NERF_SOLVE_FIELD_COUNT,
               "NERF_SOLVE_FIELD_COUNT is the length of nerf_solve_fields");

static const nerf_solve_shared *shared_of(const nerf_solve_method *m, const void *params)
{
    return (const nerf_solve_shared *)((const char *)params + m->shared_offset);
}

void nerf_solve_config(const nerf_solve_method *m, const void *params, nerf_train_config *c)
{
    const nerf_solve_shared *s = shared_of(m, params);
    *c = (nerf_train_config){.method = m->name,
                             .iters = s->iters,
                             .samples = s->samples,
                             .lr = s->lr,
                             .lr_final = s->lr_final,
                             .spacing = s->recipe.spacing,
                             .distortion_weight = s->recipe.distortion_weight,
                             .depth_tv_weight = s->recipe.depth_tv_weight,
                             .c2f_steps = s->recipe.c2f_steps,
                             .prior_steps = s->recipe.prior_steps,
                             .prior_weight = s->recipe.prior_weight,
                             .ema_steps = s->recipe.ema_steps,
                             .pose_mode = s->pose_mode,
                             .pose_init_identity = s->pose_init_identity,
                             .pose_perturb_rot_rad = s->pose_perturb_rot_rad,
                             .pose_perturb_trans = s->pose_perturb_trans,
                             .pose_hold_first = s->pose_hold_first,
                             .pose_lr = s->pose_lr,
                             .pose_lr_final = s->pose_lr_final,
                             .pose_delay = s->pose_delay,
                             .pose_warmup = s->pose_warmup,
                             .metrics_every = s->metrics_every,
                             .ssim_every = s->ssim_every,
                             .seed = s->seed,
                             .checkpoint_every = s->checkpoint_every,
                             .checkpoint_fn = s->checkpoint_fn,
                             .checkpoint_user = s->checkpoint_user,
                             .resume = s->resume,
                             .resume_bytes = s->resume_bytes};
    m->config(params, c);
}

int nerf_solve_check(const nerf_solve_method *m, const void *params, sci_error *err)
{
    const nerf_solve_shared *s = shared_of(m, params);
    int rc = m->check(params, err);
    if (rc < 0)
        return rc;
    if (s->threads < 0 || s->threads > 1024)
        return sci_error_set(err, -EINVAL, "%s: threads must be in [0, 1024] (got %d)", m->name, s->threads);
    nerf_train_config c;
    nerf_solve_config(m, params, &c);
    return nerf_train_config_check(&c, err);
}

int nerf_solve_run(const nerf_solve_method *m, const sci_problem *problem, const void *params, sci_result *result,
                   sci_progress_fn progress, void *user, double (*poses_out)[12])
{
    snprintf(result->method, sizeof result->method, "%s", m->name);
    sci_error *err = &result->error;
    int rc = nerf_solve_check(m, params, err);
    if (rc < 0)
        return rc;
    nerf_train_config tc;
    nerf_solve_config(m, params, &tc);
    if ((rc = nerf_train_prepare(problem, &tc, err)) < 0)
        return rc;
    const int outer = omp_get_max_threads();
    const int threads = shared_of(m, params)->threads > 0 ? shared_of(m, params)->threads : outer;
    /* the models take the count explicitly; the trainer's own loops and Adam follow this thread's OpenMP default,
     * which is set for the run so that `threads` bounds all of it (threads=1 used 2 cores in Adam before) */
    omp_set_num_threads(threads);
    void *state = NULL;
    nerf_model models[2];
    int n_models = 1;
    if ((rc = m->build(params, problem, &tc, threads, &state, models, &n_models, err)) == 0)
        rc = nerf_train_run(problem, &tc, &models[0], n_models == 2 ? &models[1] : NULL, result, progress, user,
                            poses_out);
    m->free_models(state);
    omp_set_num_threads(outer);
    return rc;
}

int nerf_solve_run_io(const nerf_solve_method *m, const sci_problem *problem, const void *params,
                      const solver_io *io, sci_result *result)
{
    void *q = malloc(m->params_size);
    if (!q)
        return sci_error_set(&result->error, -ENOMEM, "%s: out of memory", m->name);
    memcpy(q, params, m->params_size);
    nerf_solve_shared *s = (nerf_solve_shared *)((char *)q + m->shared_offset);
    if (io->checkpoint_fn) {
        s->checkpoint_fn = io->checkpoint_fn;
        s->checkpoint_user = io->checkpoint_user;
        s->checkpoint_every = io->checkpoint_every;
    }
    if (io->resume) {
        s->resume = io->resume;
        s->resume_bytes = io->resume_bytes;
    }
    int rc = nerf_solve_run(m, problem, q, result, io->progress, io->user, io->poses_out);
    free(q);
    return rc;
}

int nerf_solve_preset_index(const char *name, solver_preset *p)
{
    for (int i = 0; i < SOLVER_PRESET_COUNT; i++)
        if (name && strcmp(name, solver_preset_names[i]) == 0) {
            *p = (solver_preset)i;
            return 0;
        }
    return -EINVAL;
}
