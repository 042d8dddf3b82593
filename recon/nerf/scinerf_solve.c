/* recon/nerf/scinerf_solve.c — the SCINeRF-style solver: MLP fields behind the shared trainer (see
 * scinerf_solve.h, trainer.h). */
#include "recon/nerf/scinerf_solve.h"

#include <errno.h>
#include <stddef.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define GROUP 8 /* rays are batched in groups of 8 × 8 (a batch shape: the pixels are scattered) */

void sci_scinerf_params_default(sci_scinerf_params *p)
{
    *p = (sci_scinerf_params){.iters = 2400, /* the balanced preset's */
                              .rays_per_step = 1024,
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
                              .sh_degree = 1, /* view-independent colour (docs/nerf-methods.md, the recipe) */
                              .lr = 1e-2,
                              .lr_final = 1e-3,
                              .recipe = {.spacing = NERF_SPACING_LINEAR, .distortion_weight = 0.01},
                              .pose_mode = NERF_POSES_KNOWN,
                              /* SCINeRF's 1e-3 → 1e-4 serves 200k steps; in 1000 it cannot follow the corridor's
                               * motion (fast, from the identity: 17.45 dB; 3e-2 → 3e-3: 20.25 dB at step 750) */
                              .pose_lr = 3e-2,
                              .pose_lr_final = 3e-3,
                              .metrics_every = 50,
                              .seed = 1};
}

int sci_scinerf_params_preset(sci_scinerf_params *p, const char *name)
{
    /* all three on the hash-encoded field: SCINeRF's own 8 × 256 frequency network runs at ≈ 0.05 Mpoints/s on the
     * two cores (docs/nerf-methods.md), minutes per hundred steps; set pos_enc etc. to use it. Placed on the
     * photographic scenes' ceilings by io/ceiling.h's rule (tests/unit/test_nerf_presets), at evaluated steps of the
     * photo_llff ceiling (plateau 31.62 dB, bench/results/nerf_ceiling_photo_llff.md): fast within 1 dB (30.89 at
     * 1500; 30.59 at 1200), balanced within 0.3 dB (31.33 at 2400), best within 0.1 dB (31.56 at 3600). The
     * presets differ in steps only. At 0.24 s a step of 1024 rays (2 threads; fast on photo_llff 362 s) fast takes
     * 6 min, balanced 10, best 14.5; a fine network (32 importance samples) cost 1.44 s a step on the corridor for no
     * gain */
    static const struct {
        const char *name;
        int iters;
    } t[] = {
        {"fast", 1500},
        {"balanced", 2400},
        {"best", 3600},
    };
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (strcmp(name, t[i].name) == 0) {
            p->iters = t[i].iters, p->rays_per_step = 1024, p->samples = 32, p->fine_samples = 0;
            p->pos_enc = NERF_MLP_POS_HASH, p->log2_table = 19, p->finest_res = 512;
            p->depth = 2, p->width = 64, p->skip = -1, p->feature_dim = 15, p->color_hidden = 64;
            p->dir_enc = NERF_MLP_DIR_SH, p->sh_degree = 1, p->lr = 1e-2, p->lr_final = 1e-3;
            return 0;
        }
    return -EINVAL;
}

/* SCINeRF's network (docs/conventions.md §7): frequency encoding 10/4, 8 × 256 with the skip at 4, ReLU density,
 * 256 features, colour 128, coarse 64 + fine 64 samples, Adam 5e-4. */
void sci_scinerf_params_paper(sci_scinerf_params *p)
{
    p->samples = 64, p->fine_samples = 64, p->pos_enc = NERF_MLP_POS_FREQ, p->pos_freqs = 10;
    p->depth = 8, p->width = 256, p->skip = 4, p->feature_dim = 256, p->color_hidden = 128;
    p->dir_enc = NERF_MLP_DIR_FREQ, p->lr = 5e-4, p->lr_final = 5e-5;
    p->pose_lr = 1e-3, p->pose_lr_final = 1e-4; /* the paper's, for its 200k steps */
}

/* The model part of the trainer's configuration (nerf_solve.c fills the shared part): scattered rays batched in
 * groups, Adam constants of the encoding (Instant-NGP's for the hash grid, NeRF's for the frequency one), no TV. */
static void sn_config(const void *params, nerf_train_config *c)
{
    const sci_scinerf_params *p = params;
    c->group_w = c->group_h = GROUP;
    c->groups_per_step = p->rays_per_step / (GROUP * GROUP);
    c->patch_sampling = 0;
    c->fine_samples = p->fine_samples;
    c->adam_beta2 = p->pos_enc == NERF_MLP_POS_HASH ? 0.99 : 0.999;
    c->adam_eps = p->pos_enc == NERF_MLP_POS_HASH ? 1e-15 : 1e-8;
    c->tv_weight = 0;
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

static int sn_check(const void *params, sci_error *err)
{
    const sci_scinerf_params *p = params;
    if (p->rays_per_step < GROUP * GROUP || p->rays_per_step % (GROUP * GROUP) || p->rays_per_step > 262144)
        return sci_error_set(err, -EINVAL, "scinerf: rays-per-step must be a multiple of 64 in [64, 262144] (got %d)",
                             p->rays_per_step);
    if (p->pos_enc == NERF_MLP_POS_HASH && (p->log2_table < 10 || p->log2_table > 24 || !(p->finest_res >= 16) ||
                                            !(p->finest_res <= 1e6)))
        return sci_error_set(err, -EINVAL, "scinerf: hash table 2^%d / finest resolution %g out of range",
                             p->log2_table, p->finest_res);
    nerf_mlp_config mc = mlp_config(p);
    nerf_mlp *net;
    int rc = nerf_mlp_new(&net, &mc, err);
    if (rc < 0)
        return sci_error_prefix(err, "scinerf: ");
    nerf_mlp_free(net);
    return 0;
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

/* The coarse network, and the fine one when there are importance samples. */
static int sn_build(const void *params, const sci_problem *problem, const nerf_train_config *tc, int threads,
                    void **state, nerf_model models[2], int *n_models, sci_error *err)
{
    const sci_scinerf_params *p = params;
    nerf_mlp_config mc = mlp_config(p);
    memcpy(mc.aabb_min, tc->box_lo, sizeof mc.aabb_min);
    memcpy(mc.aabb_max, tc->box_hi, sizeof mc.aabb_max);
    const int groups = tc->groups_per_step * problem->mask->n, R = GROUP * GROUP;
    mlp_model *m = calloc(2, sizeof *m);
    if (!(*state = m))
        return sci_error_set(err, -ENOMEM, "scinerf: out of memory");
    *n_models = p->fine_samples > 0 ? 2 : 1;
    for (int k = 0; k < *n_models; k++) {
        const long pts = (long)groups * R * (p->samples + (k ? p->fine_samples : 0));
        if (pts > (1L << 26))
            return sci_error_set(err, -EINVAL, "scinerf: %ld points per call is too many (rays-per-step × frames × "
                                 "samples must stay below 2^26)", pts);
        m[k].R = R;
        int rc;
        if ((rc = nerf_mlp_new(&m[k].net, &mc, err)) < 0 ||
            (rc = nerf_mlp_ws_new(&m[k].ws, m[k].net, (int)pts, threads, err)) < 0)
            return sci_error_prefix(err, "scinerf: ");
        models[k] = (nerf_model){.ops = &mlp_ops,
                                 .self = &m[k],
                                 .n_params = nerf_mlp_param_count(m[k].net),
                                 .n_hash = nerf_mlp_hash_param_count(m[k].net),
                                 .max_groups = groups};
    }
    return 0;
}

static void sn_free(void *state)
{
    mlp_model *m = state;
    for (int k = 0; m && k < 2; k++) {
        nerf_mlp_ws_free(m[k].ws);
        nerf_mlp_free(m[k].net);
    }
    free(m);
}

static const nerf_solve_method sn_method = {.name = "scinerf",
                                            .params_size = sizeof(sci_scinerf_params),
                                            .shared_offset = offsetof(sci_scinerf_params, shared),
                                            .check = sn_check,
                                            .config = sn_config,
                                            .build = sn_build,
                                            .free_models = sn_free};

int sci_scinerf_params_check(const sci_scinerf_params *p, sci_error *err)
{
    return nerf_solve_check(&sn_method, p, err);
}

int sci_scinerf_solve(const sci_problem *problem, const sci_scinerf_params *params, sci_result *result,
                      sci_progress_fn progress, void *user)
{
    return nerf_solve_run(&sn_method, problem, params, result, progress, user, NULL);
}

int sci_scinerf_solve_ex(const sci_problem *problem, const sci_scinerf_params *params, sci_result *result,
                         sci_progress_fn progress, void *user, double (*poses_out)[12])
{
    return nerf_solve_run(&sn_method, problem, params, result, progress, user, poses_out);
}

/* --- the method's row in the solver table (recon/solver.h) ------------------------------------------------ */

static const char *const pos_enc_names[] = {"freq", "hash", NULL};
static const char *const dir_enc_names[] = {"freq", "sh", NULL};
#define SN(k, t, f, lo, hi, help) {k, t, offsetof(sci_scinerf_params, f), lo, hi, NULL, 0, help}
#define SN_ENUM(k, f, names, help) {k, SOLVER_FIELD_ENUM, offsetof(sci_scinerf_params, f), 0, 0, names, 0, help}
static const solver_field sn_fields[] = {
    SN("rays_per_step", SOLVER_FIELD_INT, rays_per_step, 64, 262144, "random pixels per step (a multiple of 64)"),
    {"rays", SOLVER_FIELD_INT, offsetof(sci_scinerf_params, rays_per_step), 64, 262144, NULL, SOLVER_FIELD_ALIAS,
     "rays_per_step (the bench's name)"},
    SN("fine_samples", SOLVER_FIELD_INT, fine_samples, 0, 1024, "importance samples of a fine network (0: none)"),
    SN_ENUM("pos_enc", pos_enc, pos_enc_names, "position encoding: freq (SCINeRF) or hash"),
    SN("pos_freqs", SOLVER_FIELD_INT, pos_freqs, 1, 32, "frequency encoding octaves"),
    SN("log2_table", SOLVER_FIELD_INT, log2_table, 10, 24, "hash table entries per level, log2"),
    SN("finest_res", SOLVER_FIELD_DOUBLE, finest_res, 16, 1e6, "finest hash-grid resolution"),
    SN("depth", SOLVER_FIELD_INT, depth, 1, 64, "trunk layers"),
    SN("width", SOLVER_FIELD_INT, width, 1, 4096, "trunk width"),
    SN("skip", SOLVER_FIELD_INT, skip, -1, 64, "skip connection layer (-1: none)"),
    SN("feature_dim", SOLVER_FIELD_INT, feature_dim, 1, 4096, "features before the colour head"),
    SN("color_hidden", SOLVER_FIELD_INT, color_hidden, 0, 4096, "colour head hidden width (0: one layer)"),
    SN_ENUM("dir_enc", dir_enc, dir_enc_names, "direction encoding: freq (SCINeRF) or sh"),
    SN("sh_degree", SOLVER_FIELD_INT, sh_degree, 1, 4, "SH degree of the directions"),
};

static void sn_defaults(void *s) { sci_scinerf_params_default(s); }

static void sn_preset(void *s, solver_preset p) { sci_scinerf_params_preset(s, solver_preset_name(p)); }

static int sn_solver_check(const void *s, sci_error *err) { return sci_scinerf_params_check(s, err); }

static int sn_run(const sci_problem *p, const void *s, const solver_io *io, sci_result *r)
{
    return nerf_solve_run_io(&sn_method, p, s, io, r);
}

/* The bench grid on the fast preset: fewer steps (100, 300, 700), and samples per ray at 300 steps. */
static const char *const sn_bench_quick[] = {"{\"preset\":\"fast\",\"iters\":10}", NULL};
static const char *const sn_bench_full[] = {
    "{\"preset\":\"fast\"}",
    "{\"preset\":\"fast\",\"iters\":100}",
    "{\"preset\":\"fast\",\"iters\":300}",
    "{\"preset\":\"fast\",\"iters\":700}",
    "{\"preset\":\"fast\",\"iters\":300,\"samples\":16}",
    NULL,
};

const solver_ops sci_scinerf_solver = {
    .name = "scinerf",
    .summary = "SCINeRF-style MLP radiance field trained on the snapshot (needs a camera; minutes)",
    .caps = SOLVER_NEEDS_CAMERA | SOLVER_CHECKPOINTS | SOLVER_POSES,
    .settings_size = sizeof(sci_scinerf_params),
    .fields = {{sn_fields, sizeof sn_fields / sizeof sn_fields[0], 0},
               {nerf_solve_fields, NERF_SOLVE_FIELD_COUNT, offsetof(sci_scinerf_params, shared)}},
    .defaults = sn_defaults,
    .preset = sn_preset,
    .check = sn_solver_check,
    .run = sn_run,
    .bench_quick = sn_bench_quick,
    .bench_full = sn_bench_full,
};
