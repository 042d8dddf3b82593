/* recon/nerf/trainer.c — the NeRF-family training loop (see trainer.h). */
#include "recon/nerf/trainer.h"
#include "recon/nerf/trainer_run.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/rng.h"
#include "recon/nerf/adam.h"
#include "recon/nerf/loss.h"
#include "recon/nerf/patch_sampler.h"
#include "recon/nerf/render.h"
#include "recon/nerf/se3.h"
#include "recon/gaptv.h"
#include "recon/sci_ops.h"
#include "recon/tracer.h"

int nerf_train_config_check(const nerf_train_config *c, sci_error *err)
{
    const char *m = c->method ? c->method : "nerf";
    if (c->iters < 1 || c->iters > 10000000)
        return sci_error_set(err, -EINVAL, "%s: iters must be in [1, 1e7] (got %d)", m, c->iters);
    if (c->ema_steps < 0 || c->ema_steps > 1000000)
        return sci_error_set(err, -EINVAL, "%s: ema_steps must be in [0, 1e6] (got %d)", m, c->ema_steps);
    if (c->group_w < 1 || c->group_h < 1 || c->group_w * c->group_h > 4096)
        return sci_error_set(err, -EINVAL, "%s: ray group %dx%d out of range", m, c->group_w, c->group_h);
    if (c->group_stride < 0 || c->group_stride > 64)
        return sci_error_set(err, -EINVAL, "%s: window stride must be in [0, 64] (0: 1) (got %d)", m,
                             c->group_stride);
    if (c->group_stride_max < 0 || c->group_stride_max > 64)
        return sci_error_set(err, -EINVAL, "%s: largest window stride must be in [0, 64] (0: the stride) (got %d)",
                             m, c->group_stride_max);
    if (c->group_stride_start < 0 || c->group_stride_start > 64)
        return sci_error_set(err, -EINVAL, "%s: starting window stride must be in [0, 64] (0: off) (got %d)", m,
                             c->group_stride_start);
    const int d = c->group_stride > 1 ? c->group_stride : 1;
    if (c->group_stride_start > d && c->group_stride_max > d)
        return sci_error_set(err, -EINVAL, "%s: a starting window stride and strides drawn per window exclude each "
                             "other", m);
    if (c->groups_per_step < 1 || c->groups_per_step > 4096)
        return sci_error_set(err, -EINVAL, "%s: groups per step must be in [1, 4096] (got %d)", m,
                             c->groups_per_step);
    if (c->samples < 2 || c->samples > 1024 || c->fine_samples < 0 || c->fine_samples > 1024)
        return sci_error_set(err, -EINVAL, "%s: samples %d / fine samples %d out of range ([2, 1024], [0, 1024])",
                             m, c->samples, c->fine_samples);
    if (c->fine_samples > 0 && c->samples < 3)
        return sci_error_set(err, -EINVAL, "%s: importance sampling needs at least 3 coarse samples (got %d)", m,
                             c->samples);
    if (!(c->lr > 0) || !(c->lr < 10) || !(c->lr_final > 0) || !(c->lr_final < 10))
        return sci_error_set(err, -EINVAL, "%s: lr and lr-final must be in (0, 10) (got %g, %g)", m, c->lr,
                             c->lr_final);
    if (c->render_tilings != 0 && c->render_tilings != 1 && c->render_tilings != 4)
        return sci_error_set(err, -EINVAL, "%s: render tilings must be 1 or 4 (got %d)", m, c->render_tilings);
    if (!(c->net_lr_scale >= 0 && c->net_lr_scale <= 10))
        return sci_error_set(err, -EINVAL, "%s: net-lr-scale must be in [0, 10] (got %g)", m, c->net_lr_scale);
    if (!(c->adam_beta2 >= 0 && c->adam_beta2 < 1) || !(c->adam_eps > 0) || !isfinite(c->adam_eps))
        return sci_error_set(err, -EINVAL, "%s: Adam beta2 %g must be in [0, 1), eps %g > 0", m, c->adam_beta2,
                             c->adam_eps);
    if (!(c->tv_weight >= 0) || !isfinite(c->tv_weight) || !(c->tv_eps >= 0) || !isfinite(c->tv_eps))
        return sci_error_set(err, -EINVAL, "%s: tv-weight and tv-eps must be finite and >= 0 (got %g, %g)", m,
                             c->tv_weight, c->tv_eps);
    if (c->spacing != NERF_SPACING_LINEAR && c->spacing != NERF_SPACING_DISPARITY && c->spacing != NERF_SPACING_LOG)
        return sci_error_set(err, -EINVAL, "%s: unknown sample spacing %d", m, (int)c->spacing);
    if (!(c->distortion_weight >= 0) || !isfinite(c->distortion_weight))
        return sci_error_set(err, -EINVAL, "%s: distortion weight must be finite and >= 0 (got %g)", m,
                             c->distortion_weight);
    if (c->prior_steps < 0 || !(c->prior_weight >= 0) || !isfinite(c->prior_weight))
        return sci_error_set(err, -EINVAL, "%s: prior steps (%d) and weight (%g) must be >= 0", m, c->prior_steps,
                             c->prior_weight);
    if (!(c->depth_tv_weight >= 0) || !isfinite(c->depth_tv_weight))
        return sci_error_set(err, -EINVAL, "%s: depth TV weight must be finite and >= 0 (got %g)", m,
                             c->depth_tv_weight);
    if (c->c2f_steps < 0)
        return sci_error_set(err, -EINVAL, "%s: c2f steps must be >= 0 (got %d)", m, c->c2f_steps);
    if (c->pose_mode != NERF_POSES_KNOWN && c->pose_mode != NERF_POSES_LINEAR &&
        c->pose_mode != NERF_POSES_PER_FRAME)
        return sci_error_set(err, -EINVAL, "%s: unknown pose mode %d", m, (int)c->pose_mode);
    if (!(c->pose_lr >= 0) || !isfinite(c->pose_lr) || !(c->pose_lr_final >= 0) || !isfinite(c->pose_lr_final))
        return sci_error_set(err, -EINVAL, "%s: pose-lr %g / pose-lr-final %g must be finite and >= 0", m,
                             c->pose_lr, c->pose_lr_final);
    if (!(c->pose_perturb_rot_rad >= 0) || !(c->pose_perturb_rot_rad <= 1) || !(c->pose_perturb_trans >= 0) ||
        !isfinite(c->pose_perturb_trans))
        return sci_error_set(err, -EINVAL, "%s: pose perturbation out of range (rotation %g rad in [0, 1], %g)", m,
                             c->pose_perturb_rot_rad, c->pose_perturb_trans);
    if (c->pose_delay < 0 || c->pose_warmup < 0 || c->metrics_every < 0 || c->ssim_every < 0 || c->checkpoint_every < 0)
        return sci_error_set(err, -EINVAL, "%s: pose delay and warm-up, metrics and checkpoint intervals must be >= 0",
                             m);
    return 0;
}

/* The poses a run starts from. */
static int make_poses(const sci_problem *pb, const nerf_train_config *c, nerf_poses **out, sci_error *err)
{
    const sci_camera *cam = pb->camera;
    int rc = nerf_poses_new(out, c->pose_mode, cam->n, c->pose_init_identity ? NULL : (const double(*)[12])cam->pose,
                            c->pose_perturb_rot_rad, c->pose_perturb_trans, c->seed, err);
    if (rc == 0)
        nerf_poses_set_hold_first(*out, c->pose_hold_first);
    return rc;
}

int nerf_train_scene_box(const sci_problem *pb, const nerf_train_config *c, float lo[3], float hi[3],
                         sci_error *err)
{
    const sci_camera *cam = pb->camera;
    if (c->resume) /* the network's coordinates must mean what they meant when the checkpoint was taken */
        return nerf_trainer_ckpt_box(c->resume, c->resume_bytes, lo, hi, err);
    nerf_poses *p;
    int rc = make_poses(pb, c, &p, err);
    if (rc < 0)
        return rc;
    double(*cur)[12] = malloc((size_t)cam->n * sizeof *cur);
    if (!cur) {
        nerf_poses_free(p);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", c->method);
    }
    for (int j = 0; j < cam->n; j++)
        nerf_poses_get(p, j, cur[j]);
    nerf_rays_bounds(cam, pb->mask->w, pb->mask->h, (const double(*)[12])cur, cam->n, cam->near_m, cam->far_m,
                     c->pose_mode == NERF_POSES_KNOWN ? 0.02 : 0.15, lo, hi);
    free(cur);
    nerf_poses_free(p);
    return 0;
}

int nerf_train_prepare(const sci_problem *pb, nerf_train_config *c, sci_error *err)
{
    int rc = sci_problem_validate(pb, err);
    if (rc < 0)
        return rc;
    if (!pb->camera || pb->camera->n != pb->mask->n)
        return sci_error_set(err, -EINVAL, "%s: %s: needs a camera with one pose per frame", c->method, pb->name);
    return nerf_train_scene_box(pb, c, c->box_lo, c->box_hi, err);
}

/* ------------------------------------------------------------------ run state (trainer_run.h) */

static void pass_free(nerf_trainer_pass *p)
{
    nerf_adam_free(p->adam);
    void *b[] = {p->params, p->ema, p->grad,  p->t,       p->pcam,    p->delta, p->pos,   p->sigma, p->rgb,
                 p->color,  p->grey,  p->dC,      p->d_color, p->d_sigma, p->d_rgb, p->d_pos, p->d_dir,
                 p->d_sigma_dist, p->tn, p->depth, p->d_depth};
    for (size_t i = 0; i < sizeof b / sizeof b[0]; i++)
        free(b[i]);
}

static void run_free(nerf_trainer_run_state *r)
{
    for (int k = 0; k < 2; k++)
        pass_free(&r->ps[k]);
    nerf_poses_free(r->poses);
    sci_cube_free(r->prior);
    void *b[] = {r->px, r->py, r->dcam, r->dir, r->Y,      r->M,      r->T,
                 r->imp_cdf, r->imp_u, r->imp_tc, r->imp_tf, r->Xp};
    for (size_t i = 0; i < sizeof b / sizeof b[0]; i++)
        free(b[i]);
}

static int pass_init(nerf_trainer_run_state *r, nerf_trainer_pass *p, const nerf_model *m, int L, int per_group,
                     int pose_grads, sci_error *err)
{
    const nerf_train_config *c = r->c;
    p->m = m;
    p->L = L;
    p->per_group = per_group;
    nerf_adam_config acfg = {.beta1 = 0.9, .beta2 = c->adam_beta2, .eps = c->adam_eps, .weight_decay = 0};
    int rc = nerf_adam_new(&p->adam, m->n_params, &acfg, err);
    if (rc < 0)
        return rc;
    const size_t rays = (size_t)r->G * r->R, pts = rays * L;
    p->params = malloc(m->n_params * sizeof(float));
    p->grad = malloc(m->n_params * sizeof(float));
    p->ema = c->ema_steps > 0 ? malloc(m->n_params * sizeof(float)) : NULL;
    p->t = per_group ? malloc(pts * sizeof(float)) : NULL;
    p->pcam = malloc(pts * 3 * sizeof(float));
    p->delta = malloc(pts * sizeof(float));
    p->pos = malloc(pts * 3 * sizeof(float));
    p->sigma = malloc(pts * sizeof(float));
    p->rgb = malloc(pts * 3 * sizeof(float));
    p->color = malloc(rays * 3 * sizeof(float));
    p->grey = malloc(rays * sizeof(float));
    p->dC = malloc(rays * sizeof(float));
    p->d_color = malloc(rays * 3 * sizeof(float));
    p->d_sigma = malloc(pts * sizeof(float));
    p->d_rgb = malloc(pts * 3 * sizeof(float));
    p->d_pos = pose_grads ? malloc(pts * 3 * sizeof(float)) : NULL;
    p->d_dir = pose_grads ? malloc(rays * 3 * sizeof(float)) : NULL;
    const int dist = !per_group && c->distortion_weight > 0;
    p->d_sigma_dist = dist ? malloc(pts * sizeof(float)) : NULL;
    const int dtv = !per_group && c->depth_tv_weight > 0 && c->patch_sampling;
    p->tn = dtv ? malloc(pts * sizeof(float)) : NULL;
    p->depth = dtv ? malloc(rays * sizeof(float)) : NULL;
    p->d_depth = dtv ? malloc(rays * sizeof(float)) : NULL;
    if ((dist && !p->d_sigma_dist) || (dtv && (!p->tn || !p->depth || !p->d_depth)) || !p->params || !p->grad ||
        (c->ema_steps > 0 && !p->ema) ||
        (per_group && !p->t) || !p->pcam || !p->delta || !p->pos || !p->sigma || !p->rgb || !p->color || !p->grey ||
        !p->dC || !p->d_color || !p->d_sigma || !p->d_rgb || (pose_grads && (!p->d_pos || !p->d_dir)))
        return sci_error_set(err, -ENOMEM, "%s: out of memory for a batch of %d groups × %d rays × %d samples",
                             c->method, r->G, r->R, L);
    m->ops->init(m->self, p->params, c->seed + (per_group ? 0x9e3779b9u : 0));
    return 0;
}

static int run_init(nerf_trainer_run_state *r, const sci_problem *pb, const nerf_train_config *c,
                    const nerf_model *coarse, const nerf_model *fine, sci_error *err)
{
    r->pb = pb;
    r->c = c;
    r->w = pb->mask->w;
    r->h = pb->mask->h;
    r->n = pb->mask->n;
    r->R = c->group_w * c->group_h;
    r->B = c->groups_per_step;
    r->G = r->B * r->n;
    r->near = pb->camera->near_m;
    r->far = pb->camera->far_m;
    r->n_pass = fine ? 2 : 1;
    sci_rng_seed(&r->rng, c->seed, 0x6a7);
    double ysq = 0;
    const size_t fs = (size_t)r->w * r->h;
    for (size_t k = 0; k < fs; k++)
        ysq += (double)pb->meas->data[k] * pb->meas->data[k];
    /* the residual's scale: the snapshot's RMS, floored at 0.1 % of white so that a black snapshot does not make
     * every residual look divergent */
    r->y_rms = fmax(sqrt(ysq / (double)fs), 1e-3 * (pb->peak > 0 ? pb->peak : 1.0));
    int rc;
    if ((rc = make_poses(pb, c, &r->poses, err)) < 0)
        return rc;
    const int pose_grads = nerf_poses_param_count(r->poses) > 0;
    if ((rc = pass_init(r, &r->ps[0], coarse, c->samples, 0, pose_grads, err)) < 0)
        return rc;
    if (fine && (rc = pass_init(r, &r->ps[1], fine, c->samples + c->fine_samples, 1, pose_grads, err)) < 0)
        return rc;
    const size_t rays = (size_t)r->G * r->R;
    r->px = malloc(rays * sizeof(int));
    r->py = malloc(rays * sizeof(int));
    r->dcam = malloc(rays * 3 * sizeof(float));
    r->dir = malloc(rays * 3 * sizeof(float));
    r->Y = malloc((size_t)r->B * r->R * sizeof(float));
    r->M = malloc(rays * sizeof(float));
    r->T = malloc((size_t)r->n * sizeof *r->T);
    r->imp_cdf = malloc((size_t)c->samples * sizeof(double));
    r->imp_u = malloc((size_t)(c->fine_samples + 1) * sizeof(double));
    r->imp_tc = malloc((size_t)c->samples * sizeof(float));
    r->imp_tf = malloc((size_t)(c->fine_samples + 1) * sizeof(float));
    if (!r->px || !r->py || !r->dcam || !r->dir || !r->Y || !r->M || !r->T || !r->imp_cdf || !r->imp_u ||
        !r->imp_tc || !r->imp_tf)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", c->method);
    if (c->prior_steps > 0 && c->prior_weight > 0) {
        /* the warm start's target: GAP-TV with its benchmark defaults (a fraction of a second) */
        sci_gaptv_params gp;
        sci_gaptv_params_default(&gp);
        gp.metrics_every = gp.ssim_every = 0;
        sci_result gr = {0};
        rc = sci_gaptv_solve(pb, &gp, &gr, NULL, NULL);
        if (rc < 0) {
            sci_error_set(err, rc, "%s: GAP-TV warm start: %s", c->method, gr.error.msg);
            sci_result_free_contents(&gr);
            return rc;
        }
        r->prior = gr.frames;
        gr.frames = NULL;
        sci_result_free_contents(&gr);
        if (!(r->Xp = malloc(rays * sizeof(float))))
            return sci_error_set(err, -ENOMEM, "%s: out of memory", c->method);
    }
    return 0;
}

/* ------------------------------------------------------------------ passes */

static inline size_t cam_slot(const nerf_trainer_pass *p, int n_loc, int i, int b)
{
    return p->per_group ? (size_t)i * n_loc + b : (size_t)b;
}

/* World transform, model forward and rendering of n_loc locations seen from n_pose poses (group q = i·n_loc + b);
 * the camera-frame samples are in p->pcam / p->delta, the directions in r->dcam. */
static int pass_forward(nerf_trainer_run_state *r, nerf_trainer_pass *p, int n_loc, int n_pose, const double (*T)[12])
{
    const int R = r->R, L = p->L;
    const size_t gp = (size_t)R * L;
    for (int i = 0; i < n_pose; i++)
        for (int b = 0; b < n_loc; b++) {
            size_t q = (size_t)i * n_loc + b, s = cam_slot(p, n_loc, i, b);
            nerf_rays_to_world(T[i], R, L, p->pcam + s * gp * 3, r->dcam + (size_t)b * R * 3, p->pos + q * gp * 3,
                               r->dir + q * R * 3);
        }
    const int ng = n_loc * n_pose;
    int rc = p->m->ops->forward(p->m->self, p->params, ng, L, p->pos, r->dir, p->sigma, p->rgb);
    if (rc < 0)
        return rc;
    if (p->tn) { /* the coarse pass's camera-frame samples are per location */
        const double inv = 1.0 / (r->far - r->near);
        for (size_t k = 0; k < (size_t)n_loc * gp; k++)
            p->tn[k] = (float)((-p->pcam[3 * k + 2] - r->near) * inv);
    }
#pragma omp parallel for schedule(static)
    for (int q = 0; q < ng; q++) {
        int b = q % n_loc, i = q / n_loc;
        nerf_render_rays rr = {.n_rays = R,
                               .L = L,
                               .sigma = p->sigma + (size_t)q * gp,
                               .rgb = p->rgb + (size_t)q * gp * 3,
                               .delta = p->delta + cam_slot(p, n_loc, i, b) * gp,
                               .t = p->tn ? p->tn + cam_slot(p, n_loc, i, b) * gp : NULL,
                               .t_stop = NERF_RENDER_T_STOP};
        nerf_render_forward(&rr, p->color + (size_t)q * R * 3, p->tn ? p->depth + (size_t)q * R : NULL, NULL, NULL);
    }
    const size_t nr = (size_t)ng * R;
    for (size_t k = 0; k < nr; k++)
        p->grey[k] = (p->color[3 * k] + p->color[3 * k + 1] + p->color[3 * k + 2]) * (1.0f / 3);
    return 0;
}

/* Importance samples for the fine pass from the coarse pass's weights: per group q and ray, the coarse depths
 * (midpoint bins) and Lf draws by inverse CDF (stratified u, jittered when rng is given), merged and sorted with
 * the coarse depths into fine->t; then the fine camera-frame samples. Locations' pixels are r->px/py. */
static void importance(nerf_trainer_run_state *r, int n_loc, int n_pose, sci_rng *rng)
{
    nerf_trainer_pass *pc = &r->ps[0], *pf = &r->ps[1];
    const int R = r->R, Lc = pc->L, Lf = r->c->fine_samples, L = pf->L;
    const int ng = n_loc * n_pose;
    double *cdf = r->imp_cdf, *u = r->imp_u;
    float *tc = r->imp_tc, *tf = r->imp_tf;
    for (int q = 0; q < ng; q++) {
        int b = q % n_loc;
        for (int k = 0; k < R; k++) {
            size_t ray = (size_t)q * R + k, cr = (size_t)b * R + k;
            const float *sg = pc->sigma + ray * Lc, *dl = pc->delta + cr * Lc;
            float *t = pf->t + ray * L;
            for (int s = 0; s < Lc; s++)
                tc[s] = -pc->pcam[(cr * Lc + s) * 3 + 2]; /* depth along −z */
            /* weights w_s = T_s α_s; bins between coarse midpoints carry the interior weights (nerf-pytorch) */
            double logT = 0, tot = 0;
            cdf[0] = 0;
            for (int s = 0; s < Lc; s++) {
                double tau = (double)sg[s] * dl[s], a = -expm1(-tau), wgt = exp(logT) * a;
                logT -= tau;
                if (s >= 1 && s <= Lc - 2) {
                    tot += wgt + 1e-5;
                    cdf[s] = tot; /* cdf over edges 1 … Lc−2 */
                }
            }
            int nf = 0;
            if (Lf > 0 && Lc >= 3) {
                for (int j = 0; j < Lf; j++)
                    u[j] = (j + (rng ? sci_rng_uniform(rng) : 0.5)) / Lf * tot;
                /* edges e_s = (tc[s−1] + tc[s])/2 for s = 1 … Lc−1; segment s (1 … Lc−2) spans [e_s, e_{s+1}]
                 * with mass cdf[s] − cdf[s−1] (cdf[0] = 0) */
                int s = 1;
                for (int j = 0; j < Lf; j++) {
                    while (s < Lc - 2 && cdf[s] < u[j])
                        s++;
                    double lo = s > 1 ? cdf[s - 1] : 0, hi = cdf[s], f = hi > lo ? (u[j] - lo) / (hi - lo) : 0.5;
                    f = f < 0 ? 0 : f > 1 ? 1 : f;
                    double e0 = 0.5 * (tc[s - 1] + tc[s]), e1 = 0.5 * (tc[s] + tc[s + 1]);
                    tf[nf++] = (float)(e0 + f * (e1 - e0));
                }
            }
            /* merge (both sorted) */
            int a = 0, c2 = 0, o = 0;
            while (a < Lc || c2 < nf)
                t[o++] = (c2 >= nf || (a < Lc && tc[a] <= tf[c2])) ? tc[a++] : tf[c2++];
            while (o < L) /* only if the sampling was skipped */
                t[o] = t[o - 1], o++;
        }
    }
    for (int q = 0; q < ng; q++) {
        int b = q % n_loc;
        nerf_rays_camera_depths(r->pb->camera, R, r->px + (size_t)b * R, r->py + (size_t)b * R, L,
                                pf->t + (size_t)q * R * L, r->far, pf->pcam + (size_t)q * R * L * 3,
                                r->dcam /* rewritten with the same values */ + (size_t)b * R * 3,
                                pf->delta + (size_t)q * R * L);
    }
}

/* Measurement loss of a pass over the step's B locations × N poses (+ TV, the GAP-TV prior and the distortion
 * loss when asked; prior_w is the prior's weight at this step): fills p->dC (and p->d_sigma_dist), returns the
 * loss; *data = Σ r². */
static double pass_loss(nerf_trainer_run_state *r, nerf_trainer_pass *p, int with_tv, double prior_w, double *data)
{
    const nerf_train_config *c = r->c;
    const int N = r->n, ng = r->G;
    const size_t P = (size_t)r->B * r->R, nr = (size_t)ng * r->R;
    memset(p->dC, 0, nr * sizeof(float));
    *data = nerf_loss_measurement((int)P, N, 1, r->Y, r->M, p->grey, p->dC);
    const float inv_p = (float)(1.0 / (double)P);
    for (size_t k = 0; k < nr; k++)
        p->dC[k] *= inv_p;
    double loss = *data / (double)P;
    if (with_tv && c->tv_weight > 0 && c->patch_sampling)
        loss += nerf_loss_tv(ng, c->group_w, c->group_h, 1, p->grey, c->tv_eps, c->tv_weight / (double)nr, p->dC);
    if (p->tn) {
        memset(p->d_depth, 0, nr * sizeof(float));
        if (with_tv)
            loss += nerf_loss_tv(ng, c->group_w, c->group_h, 1, p->depth, 1e-3, c->depth_tv_weight / (double)nr,
                                 p->d_depth);
    }
    if (prior_w > 0 && r->Xp) {
        /* (β/(N·P))·Σ (C − X_gap)²: every frame pulled toward GAP-TV's at the same pixel */
        double sq = 0.0;
        const double k = prior_w / (double)nr;
        for (size_t q = 0; q < nr; q++) {
            double d = (double)p->grey[q] - r->Xp[q];
            sq += d * d;
            p->dC[q] += (float)(2.0 * k * d);
        }
        loss += k * sq;
    }
    if (p->d_sigma_dist) {
        const size_t pts = nr * (size_t)p->L;
        memset(p->d_sigma_dist, 0, pts * sizeof(float));
        double ld = 0.0;
#pragma omp parallel for schedule(static) reduction(+ : ld)
        for (int q = 0; q < ng; q++) {
            const int b = q % r->B, i = q / r->B;
            const size_t gp = (size_t)r->R * p->L;
            ld += nerf_loss_distortion(r->R, p->L, p->sigma + (size_t)q * gp, p->delta + cam_slot(p, r->B, i, b) * gp,
                                       c->distortion_weight / (double)nr, p->d_sigma_dist + (size_t)q * gp);
        }
        loss += ld;
    }
    return loss;
}

static int pass_backward(nerf_trainer_run_state *r, nerf_trainer_pass *p, int pose_grads)
{
    const int R = r->R, L = p->L, ng = r->G;
    const size_t gp = (size_t)R * L, nr = (size_t)ng * R;
    for (size_t k = 0; k < nr; k++)
        p->d_color[3 * k] = p->d_color[3 * k + 1] = p->d_color[3 * k + 2] = p->dC[k] * (1.0f / 3);
#pragma omp parallel for schedule(static)
    for (int q = 0; q < ng; q++) {
        int b = q % r->B, i = q / r->B;
        nerf_render_rays rr = {.n_rays = R,
                               .L = L,
                               .sigma = p->sigma + (size_t)q * gp,
                               .rgb = p->rgb + (size_t)q * gp * 3,
                               .delta = p->delta + cam_slot(p, r->B, i, b) * gp,
                               .t = p->tn ? p->tn + cam_slot(p, r->B, i, b) * gp : NULL,
                               .t_stop = NERF_RENDER_T_STOP};
        nerf_render_backward(&rr, p->d_color + (size_t)q * R * 3, p->tn ? p->d_depth + (size_t)q * R : NULL, NULL,
                             p->d_sigma + (size_t)q * gp,
                             p->d_rgb + (size_t)q * gp * 3, NULL);
        if (p->d_sigma_dist)
            for (size_t k = (size_t)q * gp; k < (size_t)(q + 1) * gp; k++)
                p->d_sigma[k] += p->d_sigma_dist[k];
    }
    int rc = p->m->ops->backward(p->m->self, p->params, p->d_sigma, p->d_rgb, p->grad, pose_grads ? p->d_pos : NULL,
                                 pose_grads ? p->d_dir : NULL);
    if (rc < 0)
        return rc;
    if (pose_grads)
        for (int i = 0; i < r->n; i++) {
            double g_T[12] = {0};
            for (int b = 0; b < r->B; b++) {
                size_t q = (size_t)i * r->B + b, s = cam_slot(p, r->B, i, b);
                nerf_se3_grad_from_points(R * L, p->pcam + s * gp * 3, p->d_pos + q * gp * 3, 0, g_T);
                nerf_se3_grad_from_points(R, r->dcam + (size_t)b * R * 3, p->d_dir + q * R * 3, 1, g_T);
            }
            nerf_poses_add_grad(r->poses, i, g_T);
        }
    return 0;
}

static double lr_at(double lr0, double lr1, int it, int iters)
{
    return lr0 * pow(lr1 / lr0, (double)(it - 1) / fmax(1, iters - 1));
}

/* The window's stride (patch sampling; scattered rays have none). */
static int stride_of(const nerf_train_config *c)
{
    return c->patch_sampling && c->group_stride > 1 ? c->group_stride : 1;
}

/* The widest stride a training window takes in the run (the image must hold it). */
static int widest_stride(const nerf_train_config *c)
{
    const int d = stride_of(c), wide = c->group_stride_max > c->group_stride_start ? c->group_stride_max
                                                                                     : c->group_stride_start;
    return c->patch_sampling && wide > d ? wide : d;
}

/* This step's pixels (step it of 1 … iters): B windows of R rays (patch sampling) or B·R scattered pixels, each
 * uniform or stratified. */
static void sample_pixels(nerf_trainer_run_state *r, int it)
{
    const nerf_train_config *c = r->c;
    const int R = r->R, B = r->B, w = r->w;
    if (c->patch_sampling) {
        const int d = nerf_stride_at(stride_of(c), c->group_stride_start, it, c->iters);
        nerf_windows_pick(B, w, r->h, c->group_w, c->group_h, d, c->group_stride_max, c->stratify, &r->rng, r->px,
                          r->py);
        return;
    }
    if (c->stratify) {
        nerf_strata_pick(B * R, w, r->h, &r->rng, r->px, r->py);
        return;
    }
    for (int k = 0; k < B * R; k++) {
        r->px[k] = (int)sci_rng_below(&r->rng, (uint64_t)w);
        r->py[k] = (int)sci_rng_below(&r->rng, (uint64_t)r->h);
    }
}

static int train_step(nerf_trainer_run_state *r, int it, double *loss_out, double *residual)
{
    const nerf_train_config *c = r->c;
    const int R = r->R, B = r->B, N = r->n, w = r->w;
    const size_t P = (size_t)B * R, fs = (size_t)w * r->h;
    sample_pixels(r, it);
    nerf_trainer_pass *pc = &r->ps[0], *pf = &r->ps[1], *last = &r->ps[r->n_pass - 1];
    nerf_rays_camera(r->pb->camera, (int)P, r->px, r->py, pc->L, r->near, r->far, c->spacing, &r->rng,
                     c->window_jitter && c->patch_sampling ? R : 1, pc->pcam, r->dcam, pc->delta);
    const double prior_w = r->Xp && it <= c->prior_steps ? c->prior_weight * (1.0 - (double)(it - 1) / c->prior_steps)
                                                         : 0.0;
    for (size_t k = 0; k < P; k++) {
        size_t pix = (size_t)r->py[k] * w + r->px[k];
        r->Y[k] = r->pb->meas->data[pix];
        for (int i = 0; i < N; i++) {
            r->M[(size_t)i * P + k] = r->pb->mask->data[(size_t)i * fs + pix];
            if (prior_w > 0)
                r->Xp[(size_t)i * P + k] = r->prior->data[(size_t)i * fs + pix];
        }
    }
    for (int i = 0; i < N; i++)
        nerf_poses_get(r->poses, i, r->T[i]);
    for (int k = 0; k < r->n_pass; k++)
        if (r->ps[k].m->ops->progress)
            r->ps[k].m->ops->progress(r->ps[k].m->self, it, c->iters, c->c2f_steps);
    int rc = pass_forward(r, pc, B, N, (const double(*)[12])r->T);
    if (rc == 0 && r->n_pass == 2) {
        importance(r, B, N, &r->rng);
        rc = pass_forward(r, pf, B, N, (const double(*)[12])r->T);
    }
    if (rc < 0)
        return rc;
    double data, loss = pass_loss(r, last, 1, prior_w, &data);
    if (r->n_pass == 2) {
        double dc;
        loss += pass_loss(r, pc, 0, prior_w, &dc);
    }
    *loss_out = loss;
    *residual = sqrt(data / (double)P) / r->y_rms;
    const int pose_grads = nerf_poses_param_count(r->poses) > 0;
    const double lr = lr_at(c->lr, c->lr_final, it, c->iters);
    for (int k = 0; k < r->n_pass; k++) {
        nerf_trainer_pass *p = &r->ps[k];
        if ((rc = pass_backward(r, p, pose_grads)) < 0)
            return rc;
        const size_t scaled_end = p->m->n_scaled > p->m->n_hash ? p->m->n_scaled : p->m->n_params;
        nerf_adam_step(p->adam, p->params, p->grad, 0, p->m->n_hash, lr, 1, 0);
        nerf_adam_step(p->adam, p->params, p->grad, p->m->n_hash, scaled_end,
                       lr * (c->net_lr_scale > 0 ? c->net_lr_scale : 1), 0, 0);
        if (scaled_end < p->m->n_params)
            nerf_adam_step(p->adam, p->params, p->grad, scaled_end, p->m->n_params, lr, 0, 0);
    }
    if (pose_grads) {
        double plr = c->pose_lr > 0 ? lr_at(c->pose_lr, c->pose_lr_final > 0 ? c->pose_lr_final : c->pose_lr, it,
                                            c->iters)
                                    : 0;
        if (it <= c->pose_delay)
            plr = 0;
        else if (c->pose_warmup > 0 && it - c->pose_delay < c->pose_warmup)
            plr *= (double)(it - c->pose_delay) / c->pose_warmup;
        nerf_poses_step(r->poses, plr);
    }
    return 0;
}

/* Largest sample weight of each ray that hits something (opacity ≥ 0.5): adds to *sum, counts in *cnt. */
static void max_weights(const nerf_trainer_pass *p, int n_rays, double *sum, long *cnt)
{
    const int L = p->L;
    for (int k = 0; k < n_rays; k++) {
        const float *sg = p->sigma + (size_t)k * L, *dl = p->delta + (size_t)k * L; /* one pose: ray k's slot */
        double logT = 0.0, wmax = 0.0;
        for (int s = 0; s < L; s++) {
            double tau = (double)sg[s] * dl[s], wgt = exp(logT) * -expm1(-tau);
            wmax = fmax(wmax, wgt);
            logT -= tau;
        }
        if (-expm1(logT) >= 0.5) {
            *sum += wmax;
            (*cnt)++;
        }
    }
}

/* Render one tiling of the frame seen from pose T, offset (ox, oy) pixels up and left (windows clamped inside the
 * image), into frame (w×h, every pixel written once: a later window overwrites an earlier one where clamping makes
 * them meet). */
static int render_tiling(nerf_trainer_run_state *r, const double T[1][12], int ox, int oy, float *frame, double *wsum,
                         long *wcnt)
{
    const nerf_train_config *c = r->c;
    const int pw = c->group_w, ph = c->group_h, R = r->R, d = stride_of(c);
    const int tiles = nerf_tile_count(r->w, r->h, pw, ph, d, ox, oy), chunk = r->G;
    nerf_trainer_pass *pc = &r->ps[0], *last = &r->ps[r->n_pass - 1];
    for (int t0 = 0; t0 < tiles; t0 += chunk) {
        int cnt = tiles - t0 < chunk ? tiles - t0 : chunk;
        for (int b = 0; b < cnt; b++) {
            int x0, y0;
            nerf_tile_window(t0 + b, r->w, r->h, pw, ph, d, ox, oy, &x0, &y0);
            nerf_patch_pixels(x0, y0, pw, ph, d, r->px + (size_t)b * R, r->py + (size_t)b * R);
        }
        nerf_rays_camera(r->pb->camera, cnt * R, r->px, r->py, pc->L, r->near, r->far, c->spacing, NULL, 1, pc->pcam,
                         r->dcam, pc->delta);
        int rc = pass_forward(r, pc, cnt, 1, T);
        if (rc == 0 && r->n_pass == 2) {
            importance(r, cnt, 1, NULL);
            rc = pass_forward(r, &r->ps[1], cnt, 1, T);
        }
        if (rc < 0)
            return rc;
        if (wsum)
            max_weights(last, cnt * R, wsum, wcnt);
        for (int k = 0; k < cnt * R; k++)
            frame[(size_t)r->py[k] * r->w + r->px[k]] = last->grey[k];
    }
    return 0;
}

/* Render all N frames window-wise into x (w×h×N); *max_weight (or NULL) gets the mean largest ray weight over the
 * rays that hit something (NaN if none do), over every tiling rendered. With render_tilings 4, each pixel is the
 * mean of the tiling and the three offset by half a window across, down and both (in that order). */
static int render_all(nerf_trainer_run_state *r, sci_cube *x, double *max_weight)
{
    double wsum = 0.0;
    long wcnt = 0;
    const nerf_train_config *c = r->c;
    const int K = c->render_tilings == 4 ? 4 : 1, d = stride_of(c);
    const size_t npix = (size_t)r->w * r->h;
    float *tmp = K > 1 ? malloc(npix * sizeof *tmp) : NULL;
    if (K > 1 && !tmp)
        return -ENOMEM;
    int rc = 0;
    for (int i = 0; i < r->n && rc == 0; i++) {
        double T[1][12];
        nerf_poses_get(r->poses, i, T[0]);
        float *frame = sci_cube_frame(x, i);
        double *ws = max_weight ? &wsum : NULL;
        rc = render_tiling(r, (const double(*)[12])T, 0, 0, frame, ws, &wcnt);
        for (int k = 1; k < K && rc == 0; k++) {
            rc = render_tiling(r, (const double(*)[12])T, k & 1 ? c->group_w * d / 2 : 0,
                               k & 2 ? c->group_h * d / 2 : 0, tmp, ws, &wcnt);
            for (size_t p = 0; p < npix && rc == 0; p++)
                frame[p] += tmp[p];
        }
        if (K > 1)
            for (size_t p = 0; p < npix; p++)
                frame[p] *= 1.0f / (float)K;
    }
    free(tmp);
    if (rc < 0)
        return rc;
    if (max_weight)
        *max_weight = wcnt > 0 ? wsum / (double)wcnt : NAN;
    return 0;
}

static int emit_checkpoint(nerf_trainer_run_state *r, const sci_tracer *tr, int iter, sci_error *err)
{
    const nerf_train_config *c = r->c;
    if (!c->checkpoint_fn)
        return 0;
    int64_t now = sci_clock_mono_ns(), cpu = sci_clock_cpu_ns();
    double wall_s = (double)(now - tr->t0_ns - tr->skip_ns) * 1e-9;
    double cpu_s = (double)(cpu - tr->cpu0_ns - tr->skip_cpu_ns) * 1e-9;
    unsigned char *blob;
    size_t n;
    int rc = nerf_trainer_ckpt_save(r, iter, wall_s, cpu_s, &blob, &n);
    if (rc < 0)
        return sci_error_set(err, rc, "%s: checkpoint at step %d: out of memory", c->method, iter);
    rc = c->checkpoint_fn(blob, n, iter, c->checkpoint_user);
    free(blob);
    if (rc != 0)
        return sci_error_set(err, rc < 0 ? rc : -EIO, "%s: checkpoint at step %d was not stored (%s)", c->method,
                             iter, sci_strerror(rc < 0 ? rc : -EIO));
    return 0;
}

/* ------------------------------------------------------------------ the weights' moving average */

/* Fold step `it`'s weights into the average once it is within the last 4H steps (H = ema_steps): the first such
 * step starts it as a copy (so does the first after resuming from a checkpoint taken without one). Before then
 * there is none (a checkpoint's average from a run whose window began earlier is dropped). */
static void ema_update(nerf_trainer_run_state *r, int it)
{
    const nerf_train_config *c = r->c;
    if (c->ema_steps <= 0 || it <= c->iters - 4 * c->ema_steps) {
        r->ema_live = 0;
        return;
    }
    const float a = 1.0f / (float)c->ema_steps;
    for (int k = 0; k < r->n_pass; k++) {
        nerf_trainer_pass *p = &r->ps[k];
        const long n = (long)p->m->n_params;
        float *e = p->ema;
        const float *w = p->params;
        if (!r->ema_live) {
            memcpy(e, w, (size_t)n * sizeof *e);
            continue;
        }
#pragma omp parallel for schedule(static)
        for (long j = 0; j < n; j++)
            e[j] += a * (w[j] - e[j]);
    }
    r->ema_live = 1;
}

/* Exchange each pass's weights with their average once it has begun: a render between two swaps sees it. */
static void ema_swap(nerf_trainer_run_state *r)
{
    for (int k = 0; k < r->n_pass && r->ema_live; k++) {
        float *t = r->ps[k].params;
        r->ps[k].params = r->ps[k].ema;
        r->ps[k].ema = t;
    }
}

/* ------------------------------------------------------------------ the loop */

/* render_all with the weights' average once it runs (trace points and the final frames show it). */
static int render_frames(nerf_trainer_run_state *r, sci_cube *x, double *max_weight)
{
    ema_swap(r);
    int rc = render_all(r, x, max_weight);
    ema_swap(r);
    return rc;
}

/* The frames of a trace point or of the last step into x, with their measurement residual and mean largest ray
 * weight; the render counts as method time only at the last step, the residual never (a diagnostic). */
static int render_point(nerf_trainer_run_state *r, sci_tracer *tr, sci_cube *x, int last, double *meas_res,
                        double *wmax)
{
    int64_t t0 = sci_clock_mono_ns(), c0 = sci_clock_cpu_ns();
    int rc = render_frames(r, x, wmax);
    if (rc < 0)
        return rc;
    if (!last) {
        tr->skip_ns += sci_clock_mono_ns() - t0;
        tr->skip_cpu_ns += sci_clock_cpu_ns() - c0;
    }
    int64_t t1 = sci_clock_mono_ns(), c1 = sci_clock_cpu_ns();
    *meas_res = sci_op_residual(r->pb->mask, x, r->pb->meas);
    tr->skip_ns += sci_clock_mono_ns() - t1;
    tr->skip_cpu_ns += sci_clock_cpu_ns() - c1;
    return 0;
}

int nerf_train_run(const sci_problem *pb, const nerf_train_config *c, const nerf_model *coarse,
                   const nerf_model *fine, sci_result *result, sci_progress_fn progress, void *user,
                   double (*poses_out)[12])
{
    sci_error *err = &result->error;
    int rc = nerf_train_config_check(c, err);
    if (rc == 0)
        rc = sci_problem_validate(pb, err);
    if (rc < 0)
        return rc;
    const sci_camera *cam = pb->camera;
    if (!cam || cam->n != pb->mask->n)
        return sci_error_set(err, -EINVAL, "%s: %s: needs a camera with one pose per frame", c->method, pb->name);
    const int d = stride_of(c), dmax = widest_stride(c);
    if (pb->mask->w < c->group_w * d || pb->mask->h < c->group_h * d)
        return sci_error_set(err, SCI_ESHAPE, "%s: %s: image %dx%d is smaller than the %dx%d window (stride %d: its "
                             "tiling needs %dx%d)", c->method, pb->name, pb->mask->w, pb->mask->h, c->group_w,
                             c->group_h, d, c->group_w * d, c->group_h * d);
    if (pb->mask->w < nerf_patch_span(c->group_w, dmax) || pb->mask->h < nerf_patch_span(c->group_h, dmax))
        return sci_error_set(err, SCI_ESHAPE, "%s: %s: image %dx%d is smaller than a %dx%d window of stride %d",
                             c->method, pb->name, pb->mask->w, pb->mask->h, c->group_w, c->group_h, dmax);
    if (!(cam->far_m > cam->near_m) || !(cam->near_m >= 0))
        return sci_error_set(err, -EINVAL, "%s: %s: camera near/far %g/%g", c->method, pb->name, cam->near_m,
                             cam->far_m);
    if ((c->fine_samples > 0) != (fine != NULL))
        return sci_error_set(err, -EINVAL, "%s: fine samples (%d) need a fine model and the reverse", c->method,
                             c->fine_samples);
    const int G = c->groups_per_step * pb->mask->n;
    if (coarse->max_groups < G || (fine && fine->max_groups < G))
        return sci_error_set(err, -EINVAL, "%s: model takes %d groups per call, the step needs %d", c->method,
                             coarse->max_groups, G);

    nerf_trainer_run_state r = {0};
    sci_cube *x = NULL;
    int start = 0;
    if ((rc = run_init(&r, pb, c, coarse, fine, err)) < 0 ||
        (rc = sci_cube_new(&x, pb->mask->w, pb->mask->h, pb->mask->n, err)) < 0)
        goto out;
    if (c->resume && (rc = start = nerf_trainer_ckpt_load(&r, c->resume, c->resume_bytes, err)) < 0)
        goto out;
    rc = 0;
    if (start >= c->iters) {
        rc = sci_error_set(err, -EINVAL, "%s: checkpoint is at step %d, nothing left of %d steps", c->method, start,
                           c->iters);
        goto out;
    }

    sci_tracer tr;
    sci_tracer_start(&tr, pb, result, progress, user, c->iters, c->metrics_every, c->ssim_every);
    tr.t0_ns -= r.wall0_ns; /* a resumed run's trace continues the clock of the one it resumes */
    tr.cpu0_ns -= r.cpu0_ns;
    int rendered = 0, it = start;
    for (it = start + 1; it <= c->iters; it++) {
        double loss, res;
        if ((rc = train_step(&r, it, &loss, &res)) < 0) {
            sci_error_set(err, rc, "%s: step %d failed (%s)", c->method, it, sci_strerror(rc));
            goto out;
        }
        ema_update(&r, it);
        int last = it == c->iters;
        int metrics = pb->truth && c->metrics_every > 0 && it % c->metrics_every == 0;
        rendered = last || metrics;
        double meas_res = NAN, wmax = NAN;
        if (rendered && (rc = render_point(&r, &tr, x, last, &meas_res, &wmax)) < 0) {
            sci_error_set(err, rc, "%s: render failed (%s)", c->method, sci_strerror(rc));
            goto out;
        }
        if ((rc = sci_tracer_record_ex(&tr, it, rendered ? x : NULL, res, loss, meas_res, wmax)) != 0)
            break;
        if (c->checkpoint_every > 0 && (it % c->checkpoint_every == 0 || last)) {
            int64_t t0 = sci_clock_mono_ns(), c0 = sci_clock_cpu_ns();
            rc = emit_checkpoint(&r, &tr, it, err);
            tr.skip_ns += sci_clock_mono_ns() - t0;
            tr.skip_cpu_ns += sci_clock_cpu_ns() - c0;
            if (rc < 0)
                goto out;
        }
    }
    if (rc == SCI_ECANCELED) {
        sci_error saved = *err;
        int rc2 = emit_checkpoint(&r, &tr, it, err);
        if (rc2 < 0) {
            rc = rc2;
            goto out;
        }
        *err = saved;
        if (!rendered) {
            int rc3 = render_frames(&r, x, NULL);
            if (rc3 < 0) {
                rc = sci_error_set(err, rc3, "%s: render failed (%s)", c->method, sci_strerror(rc3));
                goto out;
            }
        }
    }
    if (poses_out && rc != SCI_EDIVERGED)
        for (int j = 0; j < r.n; j++)
            nerf_poses_get(r.poses, j, poses_out[j]);
    if (rc != SCI_EDIVERGED) {
        result->frames = x;
        x = NULL;
    }
out:
    sci_cube_free(x);
    run_free(&r);
    return rc;
}
