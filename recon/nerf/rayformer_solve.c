/* recon/nerf/rayformer_solve.c — the RayFormer solver: the network behind the shared trainer (see
 * rayformer_solve.h, trainer.h). */
#include "recon/nerf/rayformer_solve.h"

#include <errno.h>
#include <stddef.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "recon/nerf/rayformer.h"

/* The ablation ladder's steps, written once: the labels ("+patch", as reports print them) and, without the '+', the
 * names the "ablation" key takes (rf_fields below). */
static const char step_patch[] = "+patch", step_inter[] = "+inter", step_intra[] = "+intra", step_tv[] = "+tv";
const char *const sci_rayformer_ablation_names[5] = {"baseline", step_patch, step_inter, step_intra, step_tv};

void sci_rayformer_params_default(sci_rayformer_params *p)
{
    /* the recipe (docs/nerf-methods.md, "The recipe"): view-independent colour, a 2^19 table, one
     * I²R block that starts as the identity with its attention learning at 0.1× while the heads learn at the
     * table's rate, no layer norm before the density head, 32 samples over the scene's depth range (16 trailed
     * SCINeRF at equal time on the corridor and the tabletop, docs/nerf-methods.md), the
     * distortion loss at 0.03 (0.01 at 16 samples; at 32 the balanced preset's corridor ends 0.11 dB higher with
     * 0.03 and its surfaces form, largest ray weight 0.58 → 0.87; 0.1 costs 0.27 dB), windows of 2 × 2 (128 a
     * step: the same 512 rays as 8 of 8 × 8, spread over 16× the image; fast preset on corridor 21.44 dB against
     * 21.09 with 32 of 4 × 4 and 20.54 with 8 of 8 × 8); finest hash resolution 512 (1024 at balanced: corridor +0.13
     * dB, orbit +0.02, noisy −0.12, tabletop −0.24: no gain on the average); intra-ray attention with a distance bias
     * of slope 2 per sample (position-free, it cost 1.1 dB on the corridor's fast preset: samples of every depth
     * mixed; slope 1 reached as far in depth at 16 samples as 2 does at 32, and 2 gained 0.15 dB on the fast
     * preset's three-scene mean over 1), inter-ray attention with a city-block bias of slope 1 inside the window
     * (+ inter-ray rung +0.02 / +0.02 / +0.015 dB on corridor / orbit / noisy; docs/nerf-methods.md, "The ablation ladder"),
     * behind a learned gate per head that starts closed (ungated, the + inter-ray step lost 0.03 dB on the three-seed
     * mean, gated it is +0.003; docs/nerf-methods.md, "The recipe").
     * Measured, not the default: four render tilings (+0.01 … +0.04 dB for 4× the render); a window's rays sharing
     * their depth jitter (noisy +0.21 dB, corridor and orbit −0.14 … −0.31; docs/nerf-methods.md, "The recipe");
     * windows with a stride (patch_stride 2 / 3: the + patch rung on photo_llff +0.18 / +0.15 dB, the full method
     * −0.09 / −0.03, the orbit's −0.06 at 2; fast preset, docs/benchmarks.md); each window's stride drawn from
     * 1 … 4 (patch_stride_max 4, two seeds: the + patch rung −0.05 dB on the photo scenes' mean, + intra −0.04, the
     * full method −0.07 against adjacent windows); a moving average of the weights (ema_steps 50, shared with
     * SCINeRF: + 0.05 dB for the full method on the photo scenes' mean, the + patch step unchanged); Adam's ε at
     * 1e-8 (adam_eps; photo_llff, two seeds: baseline + 0.06 dB, + patch + 0.13, the full method − 0.10); windows
     * narrowing from stride 3 to 1 over the run (patch_stride_start 3, seed 1: the + patch step's mean − 0.11 dB
     * against − 0.14, the full method − 0.28 on the orbit) */
    *p = (sci_rayformer_params){.iters = 3400, /* the balanced preset's */
                                .patch = 2,
                                .patch_stride = 1,
                                .patch_stride_max = 0,
                                .patch_stride_start = 0,
                                .patches_per_step = 128,
                                .samples = 32,
                                .blocks = 1,
                                .log2_table = 19,
                                .finest_res = 512,
                                .sh_degree = 1,
                                .zero_gates = 1,
                                .final_norm = 0,
                                .head_hidden = 0,
                                .render_tilings = 1,
                                .window_jitter = 0,
                                /* a step's windows one per cell of a grid over the image: fast preset, one seed,
                                 * llff / orbit / noisy 30.52 / 27.06 / 28.20 dB against the uniform windows'
                                 * 30.27 / 26.58 / 28.35 (docs/nerf-methods.md, "The recipe") */
                                .stratify = 1,
                                .inter_gate = 1,
                                .heads_full_lr = 1,
                                .recipe = {.spacing = NERF_SPACING_LINEAR, .distortion_weight = 0.03},
                                /* decayed to 3e-3, not 1e-3: at 32 samples the field still gains from a large step
                                 * late in a short run (corridor, 1000 steps: 23.11 dB with a 10k-step schedule's rate
                                 * against 22.96 decayed to 1e-3) */
                                .lr = 1e-2,
                                .lr_final = 3e-3,
                                /* the attention blocks at the hash table's 1e-2 collapsed on two scenes of three
                                 * (noisy, +inter: 15.3 dB; at 0.1× the same run reaches 24.9 dB by step 1050) */
                                .net_lr_scale = 0.1,
                                /* instant-ngp's: a hash entry's step does not shrink with its gradient */
                                .adam_eps = 1e-15,
                                .tv_weight = 0.01,
                                .tv_eps = 0,
                                .patch_sampling = 1,
                                .inter_ray = 1,
                                .intra_ray = 1,
                                .intra_slope = 2,
                                .inter_slope = 1,
                                .pose_mode = NERF_POSES_KNOWN,
                                .pose_init_identity = 0,
                                .pose_perturb_rot_rad = 0,
                                .pose_perturb_trans = 0,
                                /* SCINeRF's 1e-3 → 1e-4 is for 200k steps: in 1500 the decayed rate moves a twist
                                 * by ≈ 0.6 at most, the corridor's whole motion (fast, from the identity: 18.02 dB;
                                 * 3e-2 → 3e-3: 21.14 dB, pose error 0.0036 rad; 1e-1 → 1e-2: 18.39 at step 750) */
                                .pose_lr = 3e-2,
                                .pose_lr_final = 3e-3,
                                .pose_warmup = 0,
                                .pose_hold_first = 0,
                                .metrics_every = 50,
                                .ssim_every = 0,
                                .seed = 1,
                                .threads = 0};
}

int sci_rayformer_params_preset(sci_rayformer_params *p, const char *name)
{
    /* placed on the photographic scenes' ceilings by io/ceiling.h's rule (tests/unit/test_nerf_presets): photo_llff
     * decides, its plateau 32.31 dB (bench/results/nerf_ceiling_photo_llff.md). Fast: the least steps within 1 dB;
     * the long run has 31.21 dB at step 1500 and 31.38 at 1800, and a run of its own 1600 steps ends at 31.37.
     * Balanced within 0.3 dB: 32.00 at 3300, 32.09 at 3600, its own 3400 steps 32.11. Best within 0.1 dB: 32.21
     * at 4500. The presets differ in steps only, so the ceiling, a long run of fast's settings, is the curve they sit
     * on. At 0.16–0.17 s a step (128×128×8, 2 threads, AMD EPYC host) fast takes 4.3–4.7 min, balanced about 9.5,
     * best about 12.5 (fast on photo_llff / orbit / noisy 261 / 280 / 259 s, docs/benchmarks.md) */
    static const struct {
        const char *name;
        int iters;
    } t[] = {
        {"fast", 1600},
        {"balanced", 3400},
        {"best", 4500},
    };
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (strcmp(name, t[i].name) == 0) {
            p->iters = t[i].iters, p->patches_per_step = 128, p->log2_table = 19, p->finest_res = 512;
            p->patch = 2, p->samples = 32, p->lr = 1e-2, p->lr_final = 3e-3;
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

/* The model part of the trainer's configuration (nerf_solve.c fills the shared part). */
static void rf_config(const void *params, nerf_train_config *c)
{
    const sci_rayformer_params *p = params;
    c->group_w = c->group_h = p->patch;
    c->group_stride = p->patch_stride;
    c->group_stride_max = p->patch_stride_max;
    c->group_stride_start = p->patch_stride_start;
    c->groups_per_step = p->patches_per_step;
    c->patch_sampling = p->patch_sampling;
    c->stratify = p->stratify;
    c->fine_samples = 0;
    c->net_lr_scale = p->net_lr_scale;
    c->adam_beta2 = 0.99;
    c->adam_eps = p->adam_eps;
    c->tv_weight = p->tv_weight;
    c->tv_eps = p->tv_eps;
    /* without inter-ray attention every tiling renders the same image: one, at a quarter of the cost */
    c->render_tilings = p->inter_ray ? p->render_tilings : 1;
    /* only inter-ray attention compares the rays of a window sample by sample */
    c->window_jitter = p->inter_ray && p->window_jitter;
}

static int rf_check(const void *params, sci_error *err)
{
    const sci_rayformer_params *p = params;
    if (p->patch != 2 && p->patch != 4 && p->patch != 8 && p->patch != 16)
        return sci_error_set(err, -EINVAL, "rayformer: patch must be 2, 4, 8 or 16 (got %d)", p->patch);
    if (p->patch_stride < 1 || p->patch_stride > 8)
        return sci_error_set(err, -EINVAL, "rayformer: patch-stride must be in [1, 8] (got %d)", p->patch_stride);
    if (p->patch_stride_max != 0 && (p->patch_stride_max < p->patch_stride || p->patch_stride_max > 8))
        return sci_error_set(err, -EINVAL, "rayformer: patch-stride-max must be 0 or in [patch-stride %d, 8] (got %d)",
                             p->patch_stride, p->patch_stride_max);
    if (p->patch_stride_start != 0 && (p->patch_stride_start < p->patch_stride || p->patch_stride_start > 8))
        return sci_error_set(err, -EINVAL, "rayformer: patch-stride-start must be 0 or in [patch-stride %d, 8] (got "
                             "%d)", p->patch_stride, p->patch_stride_start);
    if (p->patch_stride_start > p->patch_stride && p->patch_stride_max > p->patch_stride)
        return sci_error_set(err, -EINVAL, "rayformer: patch-stride-start and patch-stride-max exclude each other");
    if (p->log2_table < 10 || p->log2_table > 24)
        return sci_error_set(err, -EINVAL, "rayformer: log2-table must be in [10, 24] (got %d)", p->log2_table);
    if (!(p->finest_res >= 16) || !(p->finest_res <= 1e6))
        return sci_error_set(err, -EINVAL, "rayformer: finest-res must be in [16, 1e6] (got %g)", p->finest_res);
    if (p->sh_degree < 1 || p->sh_degree > 4)
        return sci_error_set(err, -EINVAL, "rayformer: sh-degree must be in [1, 4] (got %d)", p->sh_degree);
    if (p->blocks < 0 || p->blocks > 8)
        return sci_error_set(err, -EINVAL, "rayformer: blocks must be in [1, 8] (got %d)", p->blocks);
    if ((p->inter_ray != 0 && p->inter_ray != 1) || (p->intra_ray != 0 && p->intra_ray != 1) ||
        (p->patch_sampling != 0 && p->patch_sampling != 1))
        return sci_error_set(err, -EINVAL, "rayformer: patch-sampling, inter-ray and intra-ray are 0 or 1");
    if (!(p->intra_slope >= 0 && p->intra_slope <= 100))
        return sci_error_set(err, -EINVAL, "rayformer: intra-slope must be in [0, 100] (got %g)", p->intra_slope);
    if (!(p->inter_slope >= 0 && p->inter_slope <= 100))
        return sci_error_set(err, -EINVAL, "rayformer: inter-slope must be in [0, 100] (got %g)", p->inter_slope);
    if (!(p->adam_eps >= 1e-30 && p->adam_eps <= 1))
        return sci_error_set(err, -EINVAL, "rayformer: adam-eps must be in [1e-30, 1] (got %g)", p->adam_eps);
    return 0;
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

static int rf_build(const void *params, const sci_problem *problem, const nerf_train_config *tc, int threads,
                    void **state, nerf_model models[2], int *n_models, sci_error *err)
{
    const sci_rayformer_params *p = params;
    nerf_rayformer_config cfg = nerf_rayformer_config_default();
    cfg.grid.log2_table = p->log2_table;
    cfg.grid.finest_res = p->finest_res;
    cfg.patch_w = cfg.patch_h = p->patch;
    cfg.samples = p->samples;
    if (p->blocks > 0)
        cfg.n_blocks = p->blocks;
    cfg.sh_degree = p->sh_degree;
    cfg.inter_ray = p->inter_ray;
    cfg.intra_ray = p->intra_ray;
    cfg.intra_slope = (float)p->intra_slope;
    cfg.inter_slope = (float)p->inter_slope;
    cfg.zero_gates = p->zero_gates;
    cfg.inter_gate = p->inter_gate;
    cfg.final_norm = p->final_norm;
    cfg.head_hidden = p->head_hidden;
    cfg.density_bias = (float)p->recipe.density_bias;
    memcpy(cfg.aabb_min, tc->box_lo, sizeof cfg.aabb_min);
    memcpy(cfg.aabb_max, tc->box_hi, sizeof cfg.aabb_max);
    rf_model *m = calloc(1, sizeof *m);
    if (!(*state = m))
        return sci_error_set(err, -ENOMEM, "rayformer: out of memory");
    const int groups = p->patches_per_step * problem->mask->n;
    int rc;
    if ((rc = nerf_rayformer_new(&m->net, &cfg, err)) < 0 ||
        (rc = nerf_rayformer_ws_new(&m->ws, m->net, groups, threads, err)) < 0)
        return rc;
    models[0] = (nerf_model){.ops = &rf_ops,
                             .self = m,
                             .n_params = nerf_rayformer_param_count(m->net),
                             .n_hash = nerf_rayformer_hash_param_count(m->net),
                             .n_scaled = p->heads_full_lr ? nerf_rayformer_layout_of(m->net).lnf_g : 0,
                             .max_groups = groups};
    *n_models = 1;
    return 0;
}

static void rf_free(void *state)
{
    rf_model *m = state;
    if (!m)
        return;
    nerf_rayformer_ws_free(m->ws);
    nerf_rayformer_free(m->net);
    free(m);
}

static const nerf_solve_method rf_method = {.name = "rayformer",
                                            .params_size = sizeof(sci_rayformer_params),
                                            .shared_offset = offsetof(sci_rayformer_params, shared),
                                            .check = rf_check,
                                            .config = rf_config,
                                            .build = rf_build,
                                            .free_models = rf_free};

int sci_rayformer_params_check(const sci_rayformer_params *p, sci_error *err)
{
    return nerf_solve_check(&rf_method, p, err);
}

int sci_rayformer_solve(const sci_problem *problem, const sci_rayformer_params *params, sci_result *result,
                        sci_progress_fn progress, void *user)
{
    return nerf_solve_run(&rf_method, problem, params, result, progress, user, NULL);
}

int sci_rayformer_solve_ex(const sci_problem *problem, const sci_rayformer_params *params, sci_result *result,
                           sci_progress_fn progress, void *user, double (*poses_out)[12])
{
    return nerf_solve_run(&rf_method, problem, params, result, progress, user, poses_out);
}

/* --- the method's row in the solver table (recon/solver.h) ------------------------------------------------ */

static const char *const ablation_steps[] = {"baseline", step_patch + 1, step_inter + 1, step_intra + 1, step_tv + 1,
                                             NULL};
#define RF(k, t, f, lo, hi, help) {k, t, offsetof(sci_rayformer_params, f), lo, hi, NULL, 0, help}
static const solver_field rf_fields[] = {
    RF("patch", SOLVER_FIELD_INT, patch, 2, 16, "patch side: 2, 4, 8 or 16"),
    RF("patch_stride", SOLVER_FIELD_INT, patch_stride, 1, 8, "pixels between a window's neighbouring rays (1: next)"),
    RF("patch_stride_max", SOLVER_FIELD_INT, patch_stride_max, 0, 8,
       "training: each window's stride drawn from patch_stride … this (0: all patch_stride)"),
    RF("patch_stride_start", SOLVER_FIELD_INT, patch_stride_start, 0, 8,
       "training: windows start at this stride and narrow to patch_stride over the run (0: off)"),
    RF("patches_per_step", SOLVER_FIELD_INT, patches_per_step, 1, 65536, "patch locations per step"),
    RF("blocks", SOLVER_FIELD_INT, blocks, 0, 8, "I²R transformer blocks (0: 2)"),
    RF("log2_table", SOLVER_FIELD_INT, log2_table, 10, 24, "hash table entries per level, log2"),
    {"table", SOLVER_FIELD_INT, offsetof(sci_rayformer_params, log2_table), 10, 24, NULL, SOLVER_FIELD_ALIAS,
     "log2_table (the bench's name)"},
    RF("finest_res", SOLVER_FIELD_DOUBLE, finest_res, 16, 1e6, "finest hash-grid resolution"),
    RF("sh_degree", SOLVER_FIELD_INT, sh_degree, 1, 4, "view-direction encoding degree"),
    RF("net_lr_scale", SOLVER_FIELD_DOUBLE, net_lr_scale, 0, 1e3, "the transformer learns at lr × this (0: 1)"),
    RF("heads_full_lr", SOLVER_FIELD_BOOL, heads_full_lr, 0, 1, "the heads learn at lr"),
    RF("adam_eps", SOLVER_FIELD_DOUBLE, adam_eps, 1e-30, 1, "Adam's ε, every parameter (1e-15: steps ignore scale)"),
    RF("tv_weight", SOLVER_FIELD_DOUBLE, tv_weight, 0, 1e6, "TV weight over the rendered patches"),
    RF("tv_eps", SOLVER_FIELD_DOUBLE, tv_eps, 0, 1e6, "Charbonnier ε of the TV term"),
    RF("patch_sampling", SOLVER_FIELD_BOOL, patch_sampling, 0, 1, "patches (1) or scattered rays (0)"),
    RF("inter_ray", SOLVER_FIELD_BOOL, inter_ray, 0, 1, "inter-ray attention"),
    RF("intra_ray", SOLVER_FIELD_BOOL, intra_ray, 0, 1, "intra-ray attention"),
    RF("intra_slope", SOLVER_FIELD_DOUBLE, intra_slope, 0, 100,
       "intra-ray distance bias: head h's logits − slope/2^h·|i − j| (0: none)"),
    RF("inter_slope", SOLVER_FIELD_DOUBLE, inter_slope, 0, 100,
       "inter-ray distance bias: head h's logits − slope/2^h·(|Δx| + |Δy|) in the window (0: none)"),
    RF("zero_gates", SOLVER_FIELD_BOOL, zero_gates, 0, 1, "blocks start as the identity"),
    RF("final_norm", SOLVER_FIELD_BOOL, final_norm, 0, 1, "layer norm before the density head"),
    RF("inter_gate", SOLVER_FIELD_BOOL, inter_gate, 0, 1,
       "inter-ray attention behind a learned gate per head that starts closed (its pass-through)"),
    RF("window_jitter", SOLVER_FIELD_BOOL, window_jitter, 0, 1,
       "a window's rays share their depth jitter in training (with inter-ray attention)"),
    RF("stratify", SOLVER_FIELD_BOOL, stratify, 0, 1,
       "training windows (or rays) one per cell of a grid over the image, not each uniform"),
    RF("render_tilings", SOLVER_FIELD_INT, render_tilings, 1, 4, "inference tilings of windows: 1, or 4 (the mean)"),
    RF("head_hidden", SOLVER_FIELD_INT, head_hidden, 0, 4096, "hidden ReLU layer of the density head (0: one FC)"),
    {"ablation", SOLVER_FIELD_ACTION, 0, 0, 0, ablation_steps, 0,
     "the paper's ladder: sets patch_sampling, inter_ray, intra_ray, tv_weight (tv: the full method)"},
};

static void rf_defaults(void *s) { sci_rayformer_params_default(s); }

static void rf_preset(void *s, solver_preset p) { sci_rayformer_params_preset(s, solver_preset_name(p)); }

static int rf_action(void *s, const char *key, int value, sci_error *err)
{
    sci_rayformer_params *p = s;
    if (strcmp(key, "ablation") != 0)
        return sci_error_set(err, -EINVAL, "rayformer: no action %s", key);
    /* the full method's TV weight is the one set so far (the default or the preset's) */
    return sci_rayformer_params_ablation(p, value, p->tv_weight);
}

/* A settings object that names "patch" without "patches_per_step" keeps the rays per step (patches × patch²): the
 * bench's patch-size points, recorded so in bench/results.csv. */
static void rf_rules(void *s, const void *before, const json_t *obj)
{
    sci_rayformer_params *p = s;
    const sci_rayformer_params *b = before;
    if (json_object_get(obj, "patch") && !json_object_get(obj, "patches_per_step")) {
        const int rays = b->patches_per_step * b->patch * b->patch;
        p->patches_per_step = rays / (p->patch * p->patch) > 0 ? rays / (p->patch * p->patch) : 1;
    }
}

static int rf_solver_check(const void *s, sci_error *err) { return sci_rayformer_params_check(s, err); }

static int rf_run(const sci_problem *p, const void *s, const solver_io *io, sci_result *r)
{
    return nerf_solve_run_io(&rf_method, p, s, io, r);
}

/* The bench grid on the fast preset: fewer steps (100, 300, 900), and at 300 steps one other knob at a time (samples
 * per ray, the patch size at the same rays per step, the hash table: levels × features is the transformer width, so
 * the table is rayformer's hash knob). */
static const char *const rf_bench_quick[] = {"{\"preset\":\"fast\",\"iters\":10}", NULL};
static const char *const rf_bench_full[] = {
    "{\"preset\":\"fast\"}",
    "{\"preset\":\"fast\",\"iters\":100}",
    "{\"preset\":\"fast\",\"iters\":300}",
    "{\"preset\":\"fast\",\"iters\":900}",
    "{\"preset\":\"fast\",\"iters\":300,\"samples\":16}",
    "{\"preset\":\"fast\",\"iters\":300,\"patch\":4}",
    "{\"preset\":\"fast\",\"iters\":300,\"table\":14}",
    NULL,
};

const solver_ops sci_rayformer_solver = {
    .name = "rayformer",
    .summary = "RayFormer radiance field trained on the snapshot (needs a camera; minutes to hours)",
    .caps = SOLVER_NEEDS_CAMERA | SOLVER_CHECKPOINTS | SOLVER_POSES,
    .settings_size = sizeof(sci_rayformer_params),
    .fields = {{rf_fields, sizeof rf_fields / sizeof rf_fields[0], 0},
               {nerf_solve_fields, NERF_SOLVE_FIELD_COUNT, offsetof(sci_rayformer_params, shared)}},
    .defaults = rf_defaults,
    .preset = rf_preset,
    .action = rf_action,
    .from_json_rules = rf_rules,
    .check = rf_solver_check,
    .run = rf_run,
    .bench_quick = rf_bench_quick,
    .bench_full = rf_bench_full,
};
