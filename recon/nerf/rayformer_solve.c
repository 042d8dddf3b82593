/* recon/nerf/rayformer_solve.c — the RayFormer solver: the network behind the shared trainer (see
 * rayformer_solve.h, trainer.h). */
#include "recon/nerf/rayformer_solve.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "recon/nerf/rayformer.h"

const char *const sci_rayformer_ablation_names[5] = {"baseline", "+patch", "+inter", "+intra", "+tv"};

void sci_rayformer_params_default(sci_rayformer_params *p)
{
    /* the recipe of issue 15 (docs/nerf-methods.md, "The recipe"): view-independent colour, a 2^19 table, one
     * I²R block that starts as the identity with its attention learning at 0.1× while the heads learn at the
     * table's rate, 16 samples over the scene's depth range, the distortion loss */
    *p = (sci_rayformer_params){.iters = 3000,
                                .patch = 8,
                                .patches_per_step = 8,
                                .samples = 16,
                                .blocks = 1,
                                .log2_table = 19,
                                .finest_res = 512,
                                .sh_degree = 1,
                                .zero_gates = 1,
                                .heads_full_lr = 1,
                                .recipe = {.spacing = NERF_SPACING_LINEAR, .distortion_weight = 0.01},
                                .lr = 1e-2,
                                .lr_final = 1e-3,
                                /* the attention blocks at the hash table's 1e-2 collapsed on two scenes of three
                                 * (noisy, +inter: 15.3 dB; at 0.1× the same run reaches 24.9 dB by step 1050) */
                                .net_lr_scale = 0.1,
                                .tv_weight = 0.01,
                                .tv_eps = 0,
                                .patch_sampling = 1,
                                .inter_ray = 1,
                                .intra_ray = 1,
                                .pose_mode = NERF_POSES_KNOWN,
                                .pose_init_identity = 0,
                                .pose_perturb_rot_rad = 0,
                                .pose_perturb_trans = 0,
                                .pose_lr = 1e-3,
                                .pose_lr_final = 1e-4,
                                .pose_warmup = 0,
                                .pose_hold_first = 0,
                                .metrics_every = 50,
                                .ssim_every = 0,
                                .seed = 1,
                                .threads = 0};
}

int sci_rayformer_params_preset(sci_rayformer_params *p, const char *name)
{
    /* measured in bench/results/nerf_recon.md; "fast" is the issue's < 5 min for 128×128×8 on 2 cores */
    static const struct {
        const char *name;
        int iters, patches_per_step, log2_table;
        double finest_res;
    } t[] = {
        {"fast", 1500, 8, 19, 512},
        {"balanced", 3000, 8, 19, 512},
        {"best", 4000, 16, 19, 1024},
    };
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (strcmp(name, t[i].name) == 0) {
            p->iters = t[i].iters, p->patches_per_step = t[i].patches_per_step, p->log2_table = t[i].log2_table;
            p->finest_res = t[i].finest_res, p->patch = 8, p->samples = 16, p->lr = 1e-2, p->lr_final = 1e-3;
            return 0;
        }
    return -EINVAL;
}

int sci_rayformer_params_ablation(sci_rayformer_params *p, int step, double tv_weight_full)
{
    if (step < 0 || step > 4)
        return -EINVAL;
    p->patch_sampling = step >= 1;
    p->inter_ray = step >= 2;
    p->intra_ray = step >= 3;
    p->tv_weight = step >= 4 ? tv_weight_full : 0;
    return 0;
}

static void train_config(const sci_rayformer_params *p, nerf_train_config *c)
{
    *c = (nerf_train_config){.method = "rayformer",
                             .iters = p->iters,
                             .group_w = p->patch,
                             .group_h = p->patch,
                             .groups_per_step = p->patches_per_step,
                             .patch_sampling = p->patch_sampling,
                             .samples = p->samples,
                             .fine_samples = 0,
                             .lr = p->lr,
                             .lr_final = p->lr_final,
                             .net_lr_scale = p->net_lr_scale,
                             .adam_beta2 = 0.99,
                             .adam_eps = 1e-15,
                             .tv_weight = p->tv_weight,
                             .tv_eps = p->tv_eps,
                             .spacing = p->recipe.spacing,
                             .distortion_weight = p->recipe.distortion_weight,
                             .depth_tv_weight = p->recipe.depth_tv_weight,
                             .c2f_steps = p->recipe.c2f_steps,
                             .prior_steps = p->recipe.prior_steps,
                             .prior_weight = p->recipe.prior_weight,
                             .pose_mode = p->pose_mode,
                             .pose_init_identity = p->pose_init_identity,
                             .pose_perturb_rot_rad = p->pose_perturb_rot_rad,
                             .pose_perturb_trans = p->pose_perturb_trans,
                             .pose_hold_first = p->pose_hold_first,
                             .pose_lr = p->pose_lr,
                             .pose_lr_final = p->pose_lr_final,
                             .pose_delay = p->pose_delay,
                             .pose_warmup = p->pose_warmup,
                             .metrics_every = p->metrics_every,
                             .ssim_every = p->ssim_every,
                             .seed = p->seed,
                             .checkpoint_every = p->checkpoint_every,
                             .checkpoint_fn = p->checkpoint_fn,
                             .checkpoint_user = p->checkpoint_user,
                             .resume = p->resume,
                             .resume_bytes = p->resume_bytes};
}

int sci_rayformer_params_check(const sci_rayformer_params *p, sci_error *err)
{
    if (p->patch != 2 && p->patch != 4 && p->patch != 8 && p->patch != 16)
        return sci_error_set(err, -EINVAL, "rayformer: patch must be 2, 4, 8 or 16 (got %d)", p->patch);
    if (p->log2_table < 10 || p->log2_table > 24)
        return sci_error_set(err, -EINVAL, "rayformer: log2-table must be in [10, 24] (got %d)", p->log2_table);
    if (!(p->finest_res >= 16) || !(p->finest_res <= 1e6))
        return sci_error_set(err, -EINVAL, "rayformer: finest-res must be in [16, 1e6] (got %g)", p->finest_res);
    if (p->sh_degree < 1 || p->sh_degree > 4)
        return sci_error_set(err, -EINVAL, "rayformer: sh-degree must be in [1, 4] (got %d)", p->sh_degree);
    if (p->blocks < 0 || p->blocks > 8)
        return sci_error_set(err, -EINVAL, "rayformer: blocks must be in [1, 8] (got %d)", p->blocks);
    if (p->threads < 0 || p->threads > 1024)
        return sci_error_set(err, -EINVAL, "rayformer: threads must be in [0, 1024] (got %d)", p->threads);
    if ((p->inter_ray != 0 && p->inter_ray != 1) || (p->intra_ray != 0 && p->intra_ray != 1) ||
        (p->patch_sampling != 0 && p->patch_sampling != 1))
        return sci_error_set(err, -EINVAL, "rayformer: patch-sampling, inter-ray and intra-ray are 0 or 1");
    nerf_train_config c;
    train_config(p, &c);
    return nerf_train_config_check(&c, err);
}

/* The network and its workspace behind the trainer's callbacks. */
typedef struct rf_model {
    nerf_rayformer *net;
    nerf_rayformer_ws *ws;
} rf_model;

static void rf_init(void *self, float *params, uint64_t seed)
{
    rf_model *m = self;
    nerf_rayformer_init(m->net, params, seed);
}

static int rf_forward(void *self, const float *params, int n_groups, int L, const float *pos, const float *dir,
                      float *sigma, float *rgb)
{
    rf_model *m = self;
    if (L != nerf_rayformer_config_of(m->net)->samples)
        return -EINVAL;
    return nerf_rayformer_forward(m->net, params, m->ws, n_groups, pos, dir, sigma, rgb);
}

static int rf_backward(void *self, const float *params, const float *d_sigma, const float *d_rgb, float *grad,
                       float *d_pos, float *d_dir)
{
    rf_model *m = self;
    return nerf_rayformer_backward(m->net, params, m->ws, d_sigma, d_rgb, grad, d_pos, d_dir);
}

/* Coarse-to-fine: 4 levels at the start, every level from c2f_steps on (a linear ramp of BARF's alpha). */
static void rf_progress(void *self, int it, int iters, int c2f_steps)
{
    rf_model *m = self;
    const int levels = nerf_rayformer_config_of(m->net)->grid.n_levels;
    const double a0 = levels < 4 ? levels : 4;
    double alpha = c2f_steps > 0 && it < c2f_steps ? a0 + (levels - a0) * (double)it / c2f_steps : levels;
    (void)iters;
    nerf_rayformer_ws_set_levels(m->ws, alpha);
}

static const nerf_model_ops rf_ops = {
    .init = rf_init, .forward = rf_forward, .backward = rf_backward, .progress = rf_progress};

int sci_rayformer_solve(const sci_problem *problem, const sci_rayformer_params *params, sci_result *result,
                        sci_progress_fn progress, void *user)
{
    return sci_rayformer_solve_ex(problem, params, result, progress, user, NULL);
}

int sci_rayformer_solve_ex(const sci_problem *problem, const sci_rayformer_params *params, sci_result *result,
                           sci_progress_fn progress, void *user, double (*poses_out)[12])
{
    snprintf(result->method, sizeof result->method, "rayformer");
    sci_error *err = &result->error;
    int rc = sci_rayformer_params_check(params, err);
    if (rc < 0)
        return rc;
    nerf_train_config tc;
    train_config(params, &tc);
    if ((rc = nerf_train_prepare(problem, &tc, err)) < 0)
        return rc;
    nerf_rayformer_config cfg = nerf_rayformer_config_default();
    cfg.grid.log2_table = params->log2_table;
    cfg.grid.finest_res = params->finest_res;
    cfg.patch_w = cfg.patch_h = params->patch;
    cfg.samples = params->samples;
    if (params->blocks > 0)
        cfg.n_blocks = params->blocks;
    cfg.sh_degree = params->sh_degree;
    cfg.inter_ray = params->inter_ray;
    cfg.intra_ray = params->intra_ray;
    cfg.zero_gates = params->zero_gates;
    cfg.density_bias = (float)params->recipe.density_bias;
    memcpy(cfg.aabb_min, tc.box_lo, sizeof cfg.aabb_min);
    memcpy(cfg.aabb_max, tc.box_hi, sizeof cfg.aabb_max);
    rf_model m = {0};
    const int groups = params->patches_per_step * problem->mask->n;
    const int threads = params->threads > 0 ? params->threads : omp_get_max_threads();
    if ((rc = nerf_rayformer_new(&m.net, &cfg, err)) < 0 ||
        (rc = nerf_rayformer_ws_new(&m.ws, m.net, groups, threads, err)) < 0)
        goto out;
    nerf_model model = {.ops = &rf_ops,
                        .self = &m,
                        .n_params = nerf_rayformer_param_count(m.net),
                        .n_hash = nerf_rayformer_hash_param_count(m.net),
                        .n_scaled = params->heads_full_lr ? nerf_rayformer_layout_of(m.net).lnf_g : 0,
                        .max_groups = groups};
    rc = nerf_train_run(problem, &tc, &model, NULL, result, progress, user, poses_out);
out:
    nerf_rayformer_ws_free(m.ws);
    nerf_rayformer_free(m.net);
    return rc;
}
