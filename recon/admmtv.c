#include "recon/admmtv.h"
#include "recon/gaptv.h"

#include <errno.h>
#include <stddef.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "recon/sci_ops.h"
#include "recon/tracer.h"
#include "recon/tv.h"

void sci_admmtv_params_default(sci_admmtv_params *p)
{
    *p = (sci_admmtv_params){.iters = 100, .lambda = 1.0, .gamma = 1e-3, .tv_weight = 0.07, .tv_iters = 5,
                             .metrics_every = 1, .ssim_every = 10};
}

int sci_admmtv_params_check(const sci_admmtv_params *p, sci_error *err)
{
    if (p->iters < 1 || p->iters > 10000000)
        return sci_error_set(err, -EINVAL, "admm-tv: iters must be in [1, 1e7] (got %d)", p->iters);
    if (!(p->lambda > 0) || !isfinite(p->lambda))
        return sci_error_set(err, -EINVAL, "admm-tv: lambda must be > 0 (got %g)", p->lambda);
    if (!(p->gamma >= 0) || !isfinite(p->gamma))
        return sci_error_set(err, -EINVAL, "admm-tv: gamma must be >= 0 (got %g)", p->gamma);
    if (!(p->tv_weight >= 0) || !isfinite(p->tv_weight))
        return sci_error_set(err, -EINVAL, "admm-tv: tv-weight must be >= 0 (got %g)", p->tv_weight);
    if (p->tv_iters < 1 || p->tv_iters > 100000)
        return sci_error_set(err, -EINVAL, "admm-tv: tv-iters must be in [1, 1e5] (got %d)", p->tv_iters);
    if (p->metrics_every < 0 || p->ssim_every < 0)
        return sci_error_set(err, -EINVAL, "admm-tv: metrics intervals must be >= 0");
    return 0;
}

typedef struct admm_step {
    const sci_cube *mask;
    const float *r; /* (y − ŷ) ⊘ (Φ + γ) */
    float lambda;
    size_t fs;
    float *v, *b; /* cubes' data */
} admm_step;

/* v_k = (θ_k + b_k) + λ M_k ⊙ r, then the frame handed to the denoiser becomes v_k − b_k. */
static void admm_data_step(float *theta, int k, void *ctx)
{
    const admm_step *s = ctx;
    size_t off = (size_t)k * s->fs;
    const float *m = s->mask->data + off;
    float *v = s->v + off, *b = s->b + off;
    for (size_t i = 0; i < s->fs; i++) {
        v[i] = (theta[i] + b[i]) + s->lambda * (m[i] * s->r[i]);
        theta[i] = v[i] - b[i];
    }
}

int sci_admmtv_solve(const sci_problem *problem, const sci_admmtv_params *params, sci_result *result,
                     sci_progress_fn progress, void *user)
{
    snprintf(result->method, sizeof result->method, "admm-tv");
    sci_error *err = &result->error;
    int rc = sci_admmtv_params_check(params, err);
    if (rc == 0)
        rc = sci_problem_validate(problem, err);
    if (rc < 0)
        return rc;
    const sci_cube *y = problem->meas, *mask = problem->mask;
    const int w = mask->w, h = mask->h, n = mask->n;
    const size_t fs = sci_cube_frame_size(mask), count = sci_cube_count(mask);

    sci_tracer tr;
    sci_tracer_start(&tr, problem, result, progress, user, params->iters, params->metrics_every,
                     params->ssim_every);
    sci_cube *theta = NULL, *b = NULL, *v = NULL, *tb = NULL, *yhat = NULL, *den = NULL, *r = NULL;
    sci_tv *tv = NULL;
    double *rowbuf = malloc(2 * (size_t)h * sizeof *rowbuf);
    if (!rowbuf || (rc = sci_cube_new(&theta, w, h, n, err)) < 0 || (rc = sci_cube_new(&b, w, h, n, err)) < 0 ||
        (rc = sci_cube_new(&v, w, h, n, err)) < 0 || (rc = sci_cube_new(&tb, w, h, n, err)) < 0 ||
        (rc = sci_cube_new(&yhat, w, h, 1, err)) < 0 || (rc = sci_cube_new(&den, w, h, 1, err)) < 0 ||
        (rc = sci_cube_new(&r, w, h, 1, err)) < 0 || (rc = sci_tv_new(&tv, w, h, err)) < 0) {
        if (!rowbuf)
            rc = sci_error_set(err, -ENOMEM, "admm-tv: out of memory");
        goto out;
    }
    /* Φ_sum with the zero guard, then + γ. */
    sci_op_phi_sum(mask, den);
    for (size_t i = 0; i < fs; i++)
        den->data[i] += (float)params->gamma;
    sci_op_adjoint(mask, y, theta);

    admm_step step = {.mask = mask, .r = r->data, .lambda = (float)params->lambda, .fs = fs, .v = v->data,
                      .b = b->data};
    for (int it = 1; it <= params->iters; it++) {
#pragma omp parallel for schedule(static) if (count >= SCI_PARALLEL_MIN)
        for (size_t i = 0; i < count; i++)
            tb->data[i] = theta->data[i] + b->data[i];
        sci_op_forward(mask, tb, yhat);
#pragma omp parallel for schedule(static) if (fs >= SCI_PARALLEL_MIN)
        for (size_t i = 0; i < fs; i++)
            r->data[i] = (y->data[i] - yhat->data[i]) / den->data[i];
        /* θ = TV(v − b): the data step writes v and leaves v − b in θ for the denoiser. */
        sci_tv_denoise_with(tv, theta, (float)params->tv_weight, params->tv_iters, admm_data_step, &step);
#pragma omp parallel for schedule(static) if (count >= SCI_PARALLEL_MIN)
        for (size_t i = 0; i < count; i++)
            b->data[i] -= v->data[i] - theta->data[i];
        double res = sci_op_forward_residual(mask, v, y, NULL, rowbuf);
        if ((rc = sci_tracer_record(&tr, it, v, res, NAN)) != 0)
            break;
    }
    if (rc == SCI_EDIVERGED) {
        sci_cube_free(v);
        v = NULL;
    }
    result->frames = v;
    v = NULL;
out:
    free(rowbuf);
    sci_tv_free(tv);
    sci_cube_free(theta);
    sci_cube_free(b);
    sci_cube_free(v);
    sci_cube_free(tb);
    sci_cube_free(yhat);
    sci_cube_free(den);
    sci_cube_free(r);
    return rc;
}

/* --- the method's row in the solver table (recon/solver.h) ------------------------------------------------ */

#define ADMM_FIELD(k, t, f, lo, hi, help) {k, t, offsetof(sci_admmtv_params, f), lo, hi, NULL, 0, help}
static const solver_field admm_fields[] = {
    ADMM_FIELD("iters", SOLVER_FIELD_INT, iters, 1, 1e7, "iterations"),
    ADMM_FIELD("lambda", SOLVER_FIELD_DOUBLE, lambda, 0, 1e6, "step size λ (> 0)"),
    ADMM_FIELD("gamma", SOLVER_FIELD_DOUBLE, gamma, 0, 1e6, "added to the mask energy in the data step"),
    ADMM_FIELD("tv_weight", SOLVER_FIELD_DOUBLE, tv_weight, 0, 1e6, "TV weight on the data's scale"),
    ADMM_FIELD("tv_iters", SOLVER_FIELD_INT, tv_iters, 1, 1e5, "TV passes per iteration"),
    ADMM_FIELD("metrics_every", SOLVER_FIELD_INT, metrics_every, 0, 1e9, "PSNR in the trace every k iterations"),
    ADMM_FIELD("ssim_every", SOLVER_FIELD_INT, ssim_every, 0, 1e9, "SSIM in the trace every k iterations"),
};

static void admm_defaults(void *s) { sci_admmtv_params_default(s); }

static void admm_preset(void *s, solver_preset p)
{
    sci_admmtv_params *q = s;
    sci_tv_solver_preset(&q->iters, &q->tv_iters, p);
}

static int admm_check(const void *s, sci_error *err) { return sci_admmtv_params_check(s, err); }

static int admm_run(const sci_problem *p, const void *s, const solver_io *io, sci_result *r)
{
    return sci_admmtv_solve(p, s, r, io->progress, io->user);
}

const solver_ops sci_admmtv_solver = {
    .name = "admm-tv",
    .summary = "ADMM with TV denoising (fast, no camera needed)",
    .caps = 0,
    .settings_size = sizeof(sci_admmtv_params),
    .fields = {{admm_fields, sizeof admm_fields / sizeof admm_fields[0], 0}},
    .defaults = admm_defaults,
    .preset = admm_preset,
    .check = admm_check,
    .run = admm_run,
    .bench_quick = sci_tv_solver_bench_quick,
    .bench_full = sci_tv_solver_bench_full,
};
