#include "recon/nerf/rayformer_solve.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/rng.h"
#include "recon/nerf/adam.h"
#include "recon/nerf/loss.h"
#include "recon/nerf/patch_sampler.h"
#include "recon/nerf/rayformer.h"
#include "recon/nerf/render.h"
#include "recon/nerf/se3.h"
#include "recon/tracer.h"

void sci_rayformer_params_default(sci_rayformer_params *p)
{
    *p = (sci_rayformer_params){.iters = 300,
                                .patch = 8,
                                .patches_per_step = 2,
                                .samples = 32,
                                .log2_table = 16,
                                .finest_res = 512,
                                .sh_degree = 4,
                                .lr = 1e-2,
                                .lr_final = 1e-3,
                                .tv_weight = 0.01,
                                .tv_eps = 0,
                                .patch_sampling = 1,
                                .pose_mode = NERF_POSES_KNOWN,
                                .pose_init_identity = 0,
                                .pose_perturb_rot_rad = 0,
                                .pose_perturb_trans = 0,
                                .pose_lr = 1e-3,
                                .metrics_every = 50,
                                .ssim_every = 0,
                                .seed = 1,
                                .threads = 0};
}

int sci_rayformer_params_check(const sci_rayformer_params *p, sci_error *err)
{
    if (p->iters < 1 || p->iters > 10000000)
        return sci_error_set(err, -EINVAL, "rayformer: iters must be in [1, 1e7] (got %d)", p->iters);
    if (p->patch != 2 && p->patch != 4 && p->patch != 8 && p->patch != 16)
        return sci_error_set(err, -EINVAL, "rayformer: patch must be 2, 4, 8 or 16 (got %d)", p->patch);
    if (p->patches_per_step < 1 || p->patches_per_step > 4096)
        return sci_error_set(err, -EINVAL, "rayformer: patches-per-step must be in [1, 4096] (got %d)",
                             p->patches_per_step);
    if (p->samples < 2 || p->samples > 1024)
        return sci_error_set(err, -EINVAL, "rayformer: samples must be in [2, 1024] (got %d)", p->samples);
    if (p->log2_table < 10 || p->log2_table > 24)
        return sci_error_set(err, -EINVAL, "rayformer: log2-table must be in [10, 24] (got %d)", p->log2_table);
    if (!(p->finest_res >= 16) || !(p->finest_res <= 1e6))
        return sci_error_set(err, -EINVAL, "rayformer: finest-res must be in [16, 1e6] (got %g)", p->finest_res);
    if (p->sh_degree < 1 || p->sh_degree > 4)
        return sci_error_set(err, -EINVAL, "rayformer: sh-degree must be in [1, 4] (got %d)", p->sh_degree);
    if (!(p->lr > 0) || !(p->lr < 10) || !(p->lr_final > 0) || !(p->lr_final < 10))
        return sci_error_set(err, -EINVAL, "rayformer: lr and lr-final must be in (0, 10) (got %g, %g)", p->lr,
                             p->lr_final);
    if (!(p->tv_weight >= 0) || !isfinite(p->tv_weight) || !(p->tv_eps >= 0) || !isfinite(p->tv_eps))
        return sci_error_set(err, -EINVAL, "rayformer: tv-weight and tv-eps must be >= 0 (got %g, %g)",
                             p->tv_weight, p->tv_eps);
    if (p->pose_mode != NERF_POSES_KNOWN && p->pose_mode != NERF_POSES_LINEAR &&
        p->pose_mode != NERF_POSES_PER_FRAME)
        return sci_error_set(err, -EINVAL, "rayformer: unknown pose mode %d", (int)p->pose_mode);
    if (!(p->pose_lr >= 0) || !isfinite(p->pose_lr) || !(p->pose_perturb_rot_rad >= 0) ||
        !(p->pose_perturb_rot_rad <= 1) || !(p->pose_perturb_trans >= 0) || !isfinite(p->pose_perturb_trans))
        return sci_error_set(err, -EINVAL, "rayformer: pose-lr, pose perturbation out of range (%g, %g, %g)",
                             p->pose_lr, p->pose_perturb_rot_rad, p->pose_perturb_trans);
    if (p->metrics_every < 0 || p->ssim_every < 0)
        return sci_error_set(err, -EINVAL, "rayformer: metrics intervals must be >= 0");
    if (p->threads < 0 || p->threads > 1024)
        return sci_error_set(err, -EINVAL, "rayformer: threads must be in [0, 1024] (got %d)", p->threads);
    return 0;
}

/* Everything one run holds: the network and its optimiser, the poses, and per-step buffers sized for max_patches
 * network patches (B patch locations × N poses; the renderer uses the same batch). */
typedef struct rf_run {
    const sci_problem *pb;
    const sci_rayformer_params *prm;
    int w, h, n, pw, ph, R, L, B, max_patches;
    double near, far;
    nerf_rayformer *net;
    nerf_rayformer_ws *ws;
    nerf_adam *adam;
    nerf_poses *poses;
    float *params, *grad;
    size_t n_params, n_hash;
    /* camera-frame rays of the B locations */
    int *px, *py;
    float *pcam, *dcam, *delta1;
    /* network batch */
    float *pos, *dir, *delta, *sigma, *rgb, *color, *grey;
    float *d_color, *d_sigma, *d_rgb, *d_pos, *d_dir, *dC;
    float *Y, *M;
    sci_rng rng;
} rf_run;

static void rf_run_free(rf_run *r)
{
    nerf_rayformer_ws_free(r->ws);
    nerf_rayformer_free(r->net);
    nerf_adam_free(r->adam);
    nerf_poses_free(r->poses);
    void *bufs[] = {r->params, r->grad,  r->px,      r->py,      r->pcam,  r->dcam,  r->delta1, r->pos,
                    r->dir,    r->delta, r->sigma,   r->rgb,     r->color, r->grey,  r->d_color, r->d_sigma,
                    r->d_rgb,  r->d_pos, r->d_dir,   r->dC,      r->Y,     r->M};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        free(bufs[i]);
}

static int rf_run_init(rf_run *r, const sci_problem *pb, const sci_rayformer_params *prm, sci_error *err)
{
    const sci_camera *cam = pb->camera;
    r->pb = pb;
    r->prm = prm;
    r->w = pb->mask->w;
    r->h = pb->mask->h;
    r->n = pb->mask->n;
    r->pw = r->ph = prm->patch;
    r->R = r->pw * r->ph;
    r->L = prm->samples;
    r->B = prm->patches_per_step;
    r->max_patches = r->B * r->n;
    r->near = cam->near_m;
    r->far = cam->far_m;
    sci_rng_seed(&r->rng, prm->seed, 0x6a7);

    int rc;
    if ((rc = nerf_poses_new(&r->poses, prm->pose_mode, r->n,
                             prm->pose_init_identity ? NULL : (const double(*)[12])cam->pose,
                             prm->pose_perturb_rot_rad, prm->pose_perturb_trans, prm->seed, err)) < 0)
        return rc;
    /* The box: every pose the run may see, padded for pose updates. */
    double(*cur)[12] = malloc((size_t)r->n * sizeof *cur);
    if (!cur)
        return sci_error_set(err, -ENOMEM, "rayformer: out of memory");
    for (int j = 0; j < r->n; j++)
        nerf_poses_get(r->poses, j, cur[j]);
    nerf_rayformer_config cfg = nerf_rayformer_config_default();
    cfg.grid.log2_table = prm->log2_table;
    cfg.grid.finest_res = prm->finest_res;
    cfg.patch_w = r->pw;
    cfg.patch_h = r->ph;
    cfg.samples = r->L;
    cfg.sh_degree = prm->sh_degree;
    nerf_rays_bounds(cam, r->w, r->h, (const double(*)[12])cur, r->n, r->near, r->far,
                     prm->pose_mode == NERF_POSES_KNOWN ? 0.02 : 0.15, cfg.aabb_min, cfg.aabb_max);
    free(cur);
    if ((rc = nerf_rayformer_new(&r->net, &cfg, err)) < 0)
        return rc;
    int threads = prm->threads > 0 ? prm->threads : omp_get_max_threads();
    if ((rc = nerf_rayformer_ws_new(&r->ws, r->net, r->max_patches, threads, err)) < 0)
        return rc;
    r->n_params = nerf_rayformer_param_count(r->net);
    r->n_hash = nerf_rayformer_hash_param_count(r->net);
    nerf_adam_config acfg = {.beta1 = 0.9, .beta2 = 0.99, .eps = 1e-15, .weight_decay = 0};
    if ((rc = nerf_adam_new(&r->adam, r->n_params, &acfg, err)) < 0)
        return rc;

    const size_t rays = (size_t)r->max_patches * r->R, pts = rays * r->L, loc_rays = (size_t)r->B * r->R;
    r->params = malloc(r->n_params * sizeof(float));
    r->grad = malloc(r->n_params * sizeof(float));
    r->px = malloc(rays * sizeof(int)); /* the renderer lays out a whole chunk of tiles */
    r->py = malloc(rays * sizeof(int));
    r->pcam = malloc(loc_rays * r->L * 3 * sizeof(float));
    r->dcam = malloc(loc_rays * 3 * sizeof(float));
    r->delta1 = malloc(loc_rays * r->L * sizeof(float));
    r->pos = malloc(pts * 3 * sizeof(float));
    r->dir = malloc(rays * 3 * sizeof(float));
    r->delta = malloc(pts * sizeof(float));
    r->sigma = malloc(pts * sizeof(float));
    r->rgb = malloc(pts * 3 * sizeof(float));
    r->color = malloc(rays * 3 * sizeof(float));
    r->grey = malloc(rays * sizeof(float));
    r->d_color = malloc(rays * 3 * sizeof(float));
    r->d_sigma = malloc(pts * sizeof(float));
    r->d_rgb = malloc(pts * 3 * sizeof(float));
    r->d_pos = malloc(pts * 3 * sizeof(float));
    r->d_dir = malloc(rays * 3 * sizeof(float));
    r->dC = malloc(rays * sizeof(float));
    r->Y = malloc(loc_rays * sizeof(float));
    r->M = malloc(rays * sizeof(float));
    if (!r->params || !r->grad || !r->px || !r->py || !r->pcam || !r->dcam || !r->delta1 || !r->pos || !r->dir ||
        !r->delta || !r->sigma || !r->rgb || !r->color || !r->grey || !r->d_color || !r->d_sigma || !r->d_rgb ||
        !r->d_pos || !r->d_dir || !r->dC || !r->Y || !r->M)
        return sci_error_set(err, -ENOMEM, "rayformer: out of memory for a batch of %d patches", r->max_patches);
    nerf_rayformer_init(r->net, r->params, prm->seed);
    return 0;
}

/* Network + volume rendering of n_loc ray groups (camera frame in pcam/dcam/delta1, R rays each) seen from the
 * poses poses[0 … n_pose): network patch q = i·n_loc + b. Writes grey (n_pose·n_loc·R). */
static int rf_forward(rf_run *r, int n_loc, int n_pose, const double (*poses)[12])
{
    const int R = r->R, L = r->L;
    const size_t loc_pts = (size_t)R * L;
    for (int i = 0; i < n_pose; i++)
        for (int b = 0; b < n_loc; b++) {
            size_t q = (size_t)i * n_loc + b;
            nerf_rays_to_world(poses[i], R, L, r->pcam + b * loc_pts * 3, r->dcam + (size_t)b * R * 3,
                               r->pos + q * loc_pts * 3, r->dir + q * R * 3);
            memcpy(r->delta + q * loc_pts, r->delta1 + b * loc_pts, loc_pts * sizeof(float));
        }
    const int np = n_loc * n_pose;
    int rc = nerf_rayformer_forward(r->net, r->params, r->ws, np, r->pos, r->dir, r->sigma, r->rgb);
    if (rc < 0)
        return rc;
    const int n_rays = np * R;
#pragma omp parallel for schedule(static)
    for (int q = 0; q < np; q++) {
        nerf_render_rays rr = {.n_rays = R,
                               .L = L,
                               .sigma = r->sigma + (size_t)q * loc_pts,
                               .rgb = r->rgb + (size_t)q * loc_pts * 3,
                               .delta = r->delta + (size_t)q * loc_pts,
                               .t_stop = NERF_RENDER_T_STOP};
        nerf_render_forward(&rr, r->color + (size_t)q * R * 3, NULL, NULL, NULL);
    }
    for (int k = 0; k < n_rays; k++)
        r->grey[k] = (r->color[3 * k] + r->color[3 * k + 1] + r->color[3 * k + 2]) * (1.0f / 3);
    return 0;
}

/* Render all N frames window-wise into x (w×h×N). */
static int rf_render_all(rf_run *r, sci_cube *x)
{
    const int pw = r->pw, ph = r->ph, R = r->R;
    const int nx = (r->w + pw - 1) / pw, ny = (r->h + ph - 1) / ph, tiles = nx * ny;
    const int chunk = r->max_patches;
    for (int i = 0; i < r->n; i++) {
        double T[1][12];
        nerf_poses_get(r->poses, i, T[0]);
        for (int t0 = 0; t0 < tiles; t0 += chunk) {
            int cnt = tiles - t0 < chunk ? tiles - t0 : chunk;
            for (int b = 0; b < cnt; b++) {
                int tx = (t0 + b) % nx, ty = (t0 + b) / nx;
                int x0 = tx * pw, y0 = ty * ph;
                if (x0 > r->w - pw)
                    x0 = r->w - pw;
                if (y0 > r->h - ph)
                    y0 = r->h - ph;
                nerf_patch_pixels(x0, y0, pw, ph, r->px + (size_t)b * R, r->py + (size_t)b * R);
            }
            /* The ray buffers hold B locations; a render chunk may hold more patches (N·B): fill in pieces. */
            for (int b0 = 0; b0 < cnt; b0 += r->B) {
                int m = cnt - b0 < r->B ? cnt - b0 : r->B;
                nerf_rays_camera(r->pb->camera, m * R, r->px + (size_t)b0 * R, r->py + (size_t)b0 * R, r->L, r->near,
                                 r->far, NULL, r->pcam, r->dcam, r->delta1);
                int rc = rf_forward(r, m, 1, (const double(*)[12])T);
                if (rc < 0)
                    return rc;
                float *frame = sci_cube_frame(x, i);
                for (int k = 0; k < m * R; k++)
                    frame[(size_t)r->py[b0 * R + k] * r->w + r->px[b0 * R + k]] = r->grey[k];
            }
        }
    }
    return 0;
}

/* One training step: returns the loss; *residual = ‖Y − Ŷ‖/‖Y‖ over the trained pixels. */
static int rf_step(rf_run *r, int it, double *loss_out, double *residual)
{
    const sci_rayformer_params *prm = r->prm;
    const int R = r->R, L = r->L, B = r->B, N = r->n, w = r->w;
    const size_t P = (size_t)B * R, fs = (size_t)w * r->h;
    for (int b = 0; b < B; b++) {
        int *px = r->px + (size_t)b * R, *py = r->py + (size_t)b * R;
        if (prm->patch_sampling) {
            int x0 = (int)sci_rng_below(&r->rng, (uint64_t)(w - r->pw + 1));
            int y0 = (int)sci_rng_below(&r->rng, (uint64_t)(r->h - r->ph + 1));
            nerf_patch_pixels(x0, y0, r->pw, r->ph, px, py);
        } else {
            for (int k = 0; k < R; k++) {
                px[k] = (int)sci_rng_below(&r->rng, (uint64_t)w);
                py[k] = (int)sci_rng_below(&r->rng, (uint64_t)r->h);
            }
        }
    }
    nerf_rays_camera(r->pb->camera, (int)P, r->px, r->py, L, r->near, r->far, &r->rng, r->pcam, r->dcam, r->delta1);
    for (size_t k = 0; k < P; k++) {
        size_t pix = (size_t)r->py[k] * w + r->px[k];
        r->Y[k] = r->pb->meas->data[pix];
        for (int i = 0; i < N; i++)
            r->M[(size_t)i * P + k] = r->pb->mask->data[(size_t)i * fs + pix];
    }
    double(*T)[12] = malloc((size_t)N * sizeof *T);
    if (!T)
        return -ENOMEM;
    for (int i = 0; i < N; i++)
        nerf_poses_get(r->poses, i, T[i]);
    int rc = rf_forward(r, B, N, (const double(*)[12])T);
    free(T);
    if (rc < 0)
        return rc;

    const int np = B * N;
    const size_t n_rays = (size_t)np * R;
    memset(r->dC, 0, n_rays * sizeof(float));
    double data = nerf_loss_measurement((int)P, N, 1, r->Y, r->M, r->grey, r->dC);
    double ysq = 0;
    for (size_t k = 0; k < P; k++)
        ysq += (double)r->Y[k] * r->Y[k];
    *residual = sqrt(data / fmax(ysq, 1e-30));
    const float inv_p = (float)(1.0 / (double)P);
    for (size_t k = 0; k < n_rays; k++)
        r->dC[k] *= inv_p;
    double loss = data / (double)P;
    if (prm->tv_weight > 0 && prm->patch_sampling)
        loss += nerf_loss_tv(np, r->pw, r->ph, 1, r->grey, prm->tv_eps, prm->tv_weight / (double)n_rays, r->dC);
    *loss_out = loss;
    for (size_t k = 0; k < n_rays; k++)
        r->d_color[3 * k] = r->d_color[3 * k + 1] = r->d_color[3 * k + 2] = r->dC[k] * (1.0f / 3);

    const size_t loc_pts = (size_t)R * L;
#pragma omp parallel for schedule(static)
    for (int q = 0; q < np; q++) {
        nerf_render_rays rr = {.n_rays = R,
                               .L = L,
                               .sigma = r->sigma + (size_t)q * loc_pts,
                               .rgb = r->rgb + (size_t)q * loc_pts * 3,
                               .delta = r->delta + (size_t)q * loc_pts,
                               .t_stop = NERF_RENDER_T_STOP};
        nerf_render_backward(&rr, r->d_color + (size_t)q * R * 3, NULL, NULL, r->d_sigma + (size_t)q * loc_pts,
                             r->d_rgb + (size_t)q * loc_pts * 3, NULL);
    }
    const int opt_pose = nerf_poses_param_count(r->poses) > 0;
    rc = nerf_rayformer_backward(r->net, r->params, r->ws, r->d_sigma, r->d_rgb, r->grad,
                                 opt_pose ? r->d_pos : NULL, opt_pose ? r->d_dir : NULL);
    if (rc < 0)
        return rc;
    double lr = prm->lr * pow(prm->lr_final / prm->lr, (double)(it - 1) / fmax(1, prm->iters - 1));
    nerf_adam_step(r->adam, r->params, r->grad, 0, r->n_hash, lr, 1, 0);
    nerf_adam_step(r->adam, r->params, r->grad, r->n_hash, r->n_params, lr, 0, 0);
    if (opt_pose) {
        for (int i = 0; i < N; i++) {
            double g_T[12] = {0};
            for (int b = 0; b < B; b++) {
                size_t q = (size_t)i * B + b;
                nerf_se3_grad_from_points(R * L, r->pcam + b * loc_pts * 3, r->d_pos + q * loc_pts * 3, 0, g_T);
                nerf_se3_grad_from_points(R, r->dcam + (size_t)b * R * 3, r->d_dir + q * R * 3, 1, g_T);
            }
            nerf_poses_add_grad(r->poses, i, g_T);
        }
        double plr = prm->pose_lr * pow(0.1, (double)(it - 1) / fmax(1, prm->iters - 1));
        nerf_poses_step(r->poses, plr);
    }
    return 0;
}

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
    if (rc == 0)
        rc = sci_problem_validate(problem, err);
    if (rc < 0)
        return rc;
    const sci_camera *cam = problem->camera;
    if (!cam || cam->n != problem->mask->n)
        return sci_error_set(err, -EINVAL, "rayformer: %s: needs a camera with one pose per frame", problem->name);
    if (problem->mask->w < params->patch || problem->mask->h < params->patch)
        return sci_error_set(err, SCI_ESHAPE, "rayformer: %s: image %dx%d is smaller than the %d-pixel patch",
                             problem->name, problem->mask->w, problem->mask->h, params->patch);
    if (!(cam->far_m > cam->near_m) || !(cam->near_m >= 0))
        return sci_error_set(err, -EINVAL, "rayformer: %s: camera near/far %g/%g", problem->name, cam->near_m,
                             cam->far_m);

    rf_run run = {0};
    sci_cube *x = NULL;
    if ((rc = rf_run_init(&run, problem, params, err)) < 0 ||
        (rc = sci_cube_new(&x, problem->mask->w, problem->mask->h, problem->mask->n, err)) < 0)
        goto out;

    sci_tracer tr;
    sci_tracer_start(&tr, problem, result, progress, user, params->iters, params->metrics_every,
                     params->ssim_every);
    int rendered = 0;
    for (int it = 1; it <= params->iters; it++) {
        double loss, res;
        if ((rc = rf_step(&run, it, &loss, &res)) < 0) {
            sci_error_set(err, rc, "rayformer: step %d failed (%s)", it, sci_strerror(rc));
            goto out;
        }
        int last = it == params->iters;
        int metrics = problem->truth && params->metrics_every > 0 && it % params->metrics_every == 0;
        rendered = 0;
        if (last || metrics) {
            int64_t t0 = sci_clock_mono_ns(), c0 = sci_clock_cpu_ns();
            if ((rc = rf_render_all(&run, x)) < 0) {
                sci_error_set(err, rc, "rayformer: render failed (%s)", sci_strerror(rc));
                goto out;
            }
            rendered = 1;
            if (!last) { /* intermediate renders are trace metrics, not method time */
                tr.skip_ns += sci_clock_mono_ns() - t0;
                tr.skip_cpu_ns += sci_clock_cpu_ns() - c0;
            }
        }
        if ((rc = sci_tracer_record(&tr, it, rendered ? x : NULL, res, loss)) != 0)
            break;
    }
    if (rc == SCI_ECANCELED && !rendered) {
        int rc2 = rf_render_all(&run, x);
        if (rc2 < 0) {
            rc = sci_error_set(err, rc2, "rayformer: render failed (%s)", sci_strerror(rc2));
            goto out;
        }
    }
    if (poses_out && rc != SCI_EDIVERGED)
        for (int j = 0; j < run.n; j++)
            nerf_poses_get(run.poses, j, poses_out[j]);
    if (rc != SCI_EDIVERGED) {
        result->frames = x;
        x = NULL;
    }
out:
    sci_cube_free(x);
    rf_run_free(&run);
    return rc;
}
