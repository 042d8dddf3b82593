/* recon/nerf/scinerf_solve.c — the SCINeRF-style solver: MLP fields behind the shared trainer (see
 * scinerf_solve.h, trainer.h). */
#include "recon/nerf/scinerf_solve.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define GROUP 8 /* rays are batched in groups of 8 × 8 (a batch shape: the pixels are scattered) */

void sci_scinerf_params_default(sci_scinerf_params *p)
{
    *p = (sci_scinerf_params){.iters = 1500,
                              .rays_per_step = 2048,
                              .samples = 32,
                              .fine_samples = 0,
                              .pos_enc = NERF_MLP_POS_HASH,
                              .pos_freqs = 10,
                              .log2_table = 19,
                              .finest_res = 512,
                              .depth = 2,
                              .width = 64,
                              .skip = -1,
                              .feature_dim = 15,
                              .color_hidden = 64,
                              .dir_enc = NERF_MLP_DIR_SH,
                              .sh_degree = 1, /* view-independent colour (issue 15's recipe) */
                              .lr = 1e-2,
                              .lr_final = 1e-3,
                              .recipe = {.spacing = NERF_SPACING_LINEAR, .distortion_weight = 0.01},
                              .pose_mode = NERF_POSES_KNOWN,
                              .pose_lr = 1e-3,
                              .pose_lr_final = 1e-4,
                              .metrics_every = 50,
                              .seed = 1};
}

int sci_scinerf_params_preset(sci_scinerf_params *p, const char *name)
{
    /* all three on the hash-encoded field: SCINeRF's own 8 × 256 frequency network runs at ≈ 0.05 Mpoints/s on the
     * two cores (docs/nerf-blocks.md), minutes per hundred steps; set pos_enc etc. to use it */
    static const struct {
        const char *name;
        int iters, rays, fine;
    } t[] = {
        {"fast", 1000, 1024, 0},
        {"balanced", 1500, 2048, 0},
        {"best", 1000, 2048, 32},
    };
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (strcmp(name, t[i].name) == 0) {
            p->iters = t[i].iters, p->rays_per_step = t[i].rays, p->samples = 32, p->fine_samples = t[i].fine;
            p->pos_enc = NERF_MLP_POS_HASH, p->log2_table = 19, p->finest_res = 512;
            p->depth = 2, p->width = 64, p->skip = -1, p->feature_dim = 15, p->color_hidden = 64;
            p->dir_enc = NERF_MLP_DIR_SH, p->sh_degree = 1, p->lr = 1e-2, p->lr_final = 1e-3;
            return 0;
        }
    return -EINVAL;
}

/* SCINeRF's network (sci-reconstruction.md §7): frequency encoding 10/4, 8 × 256 with the skip at 4, ReLU density,
 * 256 features, colour 128, coarse 64 + fine 64 samples, Adam 5e-4. */
void sci_scinerf_params_paper(sci_scinerf_params *p)
{
    p->samples = 64, p->fine_samples = 64, p->pos_enc = NERF_MLP_POS_FREQ, p->pos_freqs = 10;
    p->depth = 8, p->width = 256, p->skip = 4, p->feature_dim = 256, p->color_hidden = 128;
    p->dir_enc = NERF_MLP_DIR_FREQ, p->lr = 5e-4, p->lr_final = 5e-5;
}

static void train_config(const sci_scinerf_params *p, nerf_train_config *c)
{
    *c = (nerf_train_config){.method = "scinerf",
                             .iters = p->iters,
                             .group_w = GROUP,
                             .group_h = GROUP,
                             .groups_per_step = p->rays_per_step / (GROUP * GROUP),
                             .patch_sampling = 0,
                             .samples = p->samples,
                             .fine_samples = p->fine_samples,
                             .lr = p->lr,
                             .lr_final = p->lr_final,
                             .adam_beta2 = p->pos_enc == NERF_MLP_POS_HASH ? 0.99 : 0.999,
                             .adam_eps = p->pos_enc == NERF_MLP_POS_HASH ? 1e-15 : 1e-8,
                             .tv_weight = 0,
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

static nerf_mlp_config mlp_config(const sci_scinerf_params *p)
{
    nerf_mlp_config c = p->pos_enc == NERF_MLP_POS_HASH ? nerf_mlp_config_hash() : nerf_mlp_config_scinerf();
    c.pos_enc = p->pos_enc;
    c.pos_freqs = p->pos_freqs;
    c.grid.log2_table = p->log2_table;
    c.grid.finest_res = p->finest_res;
    c.depth = p->depth;
    c.width = p->width;
    c.skip = p->skip;
    c.feature_dim = p->feature_dim;
    c.color_hidden = p->color_hidden;
    c.dir_enc = p->dir_enc;
    c.sh_degree = p->sh_degree;
    /* ReLU density (NeRF) with the frequency encoding, trunc_exp (Instant-NGP) with the hash grid */
    c.density_act = p->pos_enc == NERF_MLP_POS_HASH ? NERF_ACT_TRUNC_EXP : NERF_ACT_RELU;
    c.density_bias = (float)p->recipe.density_bias;
    return c;
}

int sci_scinerf_params_check(const sci_scinerf_params *p, sci_error *err)
{
    if (p->rays_per_step < GROUP * GROUP || p->rays_per_step % (GROUP * GROUP) || p->rays_per_step > 262144)
        return sci_error_set(err, -EINVAL, "scinerf: rays-per-step must be a multiple of 64 in [64, 262144] (got %d)",
                             p->rays_per_step);
    if (p->pos_enc == NERF_MLP_POS_HASH && (p->log2_table < 10 || p->log2_table > 24 || !(p->finest_res >= 16) ||
                                            !(p->finest_res <= 1e6)))
        return sci_error_set(err, -EINVAL, "scinerf: hash table 2^%d / finest resolution %g out of range",
                             p->log2_table, p->finest_res);
    if (p->threads < 0 || p->threads > 1024)
        return sci_error_set(err, -EINVAL, "scinerf: threads must be in [0, 1024] (got %d)", p->threads);
    nerf_mlp_config mc = mlp_config(p);
    nerf_mlp *net;
    int rc = nerf_mlp_new(&net, &mc, err);
    if (rc < 0)
        return sci_error_prefix(err, "scinerf: ");
    nerf_mlp_free(net);
    nerf_train_config c;
    train_config(p, &c);
    return nerf_train_config_check(&c, err);
}

typedef struct mlp_model {
    nerf_mlp *net;
    nerf_mlp_ws *ws;
    int R;
} mlp_model;

static void m_init(void *self, float *params, uint64_t seed)
{
    mlp_model *m = self;
    nerf_mlp_init(m->net, params, seed);
}

static int m_forward(void *self, const float *params, int n_groups, int L, const float *pos, const float *dir,
                     float *sigma, float *rgb)
{
    mlp_model *m = self;
    return nerf_mlp_forward(m->net, params, m->ws, n_groups * m->R * L, pos, dir, L, sigma, rgb);
}

static int m_backward(void *self, const float *params, const float *d_sigma, const float *d_rgb, float *grad,
                      float *d_pos, float *d_dir)
{
    mlp_model *m = self;
    return nerf_mlp_backward(m->net, params, m->ws, d_sigma, d_rgb, grad, d_pos, d_dir);
}

static const nerf_model_ops mlp_ops = {.init = m_init, .forward = m_forward, .backward = m_backward};

int sci_scinerf_solve(const sci_problem *problem, const sci_scinerf_params *params, sci_result *result,
                      sci_progress_fn progress, void *user)
{
    return sci_scinerf_solve_ex(problem, params, result, progress, user, NULL);
}

int sci_scinerf_solve_ex(const sci_problem *problem, const sci_scinerf_params *params, sci_result *result,
                         sci_progress_fn progress, void *user, double (*poses_out)[12])
{
    snprintf(result->method, sizeof result->method, "scinerf");
    sci_error *err = &result->error;
    int rc = sci_scinerf_params_check(params, err);
    if (rc < 0)
        return rc;
    nerf_train_config tc;
    train_config(params, &tc);
    if ((rc = nerf_train_prepare(problem, &tc, err)) < 0)
        return rc;
    nerf_mlp_config mc = mlp_config(params);
    memcpy(mc.aabb_min, tc.box_lo, sizeof mc.aabb_min);
    memcpy(mc.aabb_max, tc.box_hi, sizeof mc.aabb_max);
    const int groups = tc.groups_per_step * problem->mask->n, R = GROUP * GROUP;
    const int threads = params->threads > 0 ? params->threads : omp_get_max_threads();
    mlp_model m[2] = {{0}, {0}};
    const int n_models = params->fine_samples > 0 ? 2 : 1;
    nerf_model model[2];
    for (int k = 0; k < n_models; k++) {
        const long pts = (long)groups * R * (params->samples + (k ? params->fine_samples : 0));
        if (pts > (1L << 26)) {
            rc = sci_error_set(err, -EINVAL, "scinerf: %ld points per call is too many (rays-per-step × frames × "
                               "samples must stay below 2^26)", pts);
            goto out;
        }
        m[k].R = R;
        if ((rc = nerf_mlp_new(&m[k].net, &mc, err)) < 0 ||
            (rc = nerf_mlp_ws_new(&m[k].ws, m[k].net, (int)pts, threads, err)) < 0) {
            sci_error_prefix(err, "scinerf: ");
            goto out;
        }
        model[k] = (nerf_model){.ops = &mlp_ops,
                                .self = &m[k],
                                .n_params = nerf_mlp_param_count(m[k].net),
                                .n_hash = nerf_mlp_hash_param_count(m[k].net),
                                .max_groups = groups};
    }
    rc = nerf_train_run(problem, &tc, &model[0], n_models == 2 ? &model[1] : NULL, result, progress, user,
                        poses_out);
out:
    for (int k = 0; k < 2; k++) {
        nerf_mlp_ws_free(m[k].ws);
        nerf_mlp_free(m[k].net);
    }
    return rc;
}
