/* recon/desci.c — DeSCI, GAP-WNNM (see desci.h). */
#include "recon/desci.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "recon/gaptv.h"
#include "recon/sci_ops.h"
#include "recon/tracer.h"
#include "recon/wnnm.h"

void sci_desci_params_default(sci_desci_params *p)
{
    *p = (sci_desci_params){.window = 30, .c = sqrt(2.0), .match_every = 20, .lambda = 1.0, .accelerate = 1,
                            .metrics_every = 1, .ssim_every = 10};
    sci_desci_preset(p, SOLVER_PRESET_BALANCED);
}

/* From the measured curves on drop40 snapshot 1 (PSNR peak = frame max, 2 threads; times under a load of 1 to 4
 * from other jobs): from GAP-TV's 100 iterations (34.6 dB), σ 12 gains fast — 38.99 dB at 10 iterations, 40.84 at
 * 20, 41.99 at 30 — and levels off near 42.2 (42.17 at 40, 42.05 at 80: each block matching dips it by 0.5 dB for
 * a few iterations); a σ 6 stage after it lifts that to 43.2 (30 + 30: 43.22 dB in 210 s at load 3.7, 40 + 40:
 * 43.23). The reference recipe from Aᵀy: 43.11 dB in 1354 s at load 3 to 4 (36.5 at 30 iterations, 38.0 at 80,
 * 40.96 at 200). So fast = 20 at σ 12 (40.84 dB, 34 s at load 1.2: one block matching), balanced = 30 + 30 at
 * σ 12, 6 (43.22, as high as the reference recipe at a sixth of its time), best = the reference recipe itself,
 * which needs no TV start and is the published method. */
void sci_desci_preset(sci_desci_params *q, solver_preset p)
{
    switch (p) {
    case SOLVER_PRESET_FAST:
        q->iters = 20, q->sigma = (solver_values){1, {12}}, q->tv_init = 100;
        break;
    case SOLVER_PRESET_BALANCED:
        q->iters = 60, q->sigma = (solver_values){2, {12, 6}}, q->tv_init = 100;
        break;
    case SOLVER_PRESET_BEST:
        q->iters = 300, q->sigma = (solver_values){5, {100, 50, 25, 12, 6}}, q->tv_init = 0;
        break;
    }
    q->patch = q->group = q->step = 0;
    q->window = 30, q->match_every = 20;
}

int sci_desci_params_check(const sci_desci_params *p, sci_error *err)
{
    if (p->sigma.n < 1 || p->sigma.n > SOLVER_LIST_MAX)
        return sci_error_set(err, -EINVAL, "desci: sigma needs 1 to %d stages (has %d)", SOLVER_LIST_MAX,
                             p->sigma.n);
    if (p->iters < 1 || p->iters > 1000000)
        return sci_error_set(err, -EINVAL, "desci: iters must be in [1, 1e6] (got %d)", p->iters);
    for (int i = 0; i < p->sigma.n; i++)
        if (!(p->sigma.v[i] > 0 && p->sigma.v[i] <= 255))
            return sci_error_set(err, -EINVAL, "desci: sigma[%d] must be in (0, 255] (got %g)", i, p->sigma.v[i]);
    if (p->patch < 0 || p->patch > 64 || p->group < 0 || p->group > 4096 || p->step < 0 || p->step > 64)
        return sci_error_set(err, -EINVAL, "desci: patch in [0, 64], group in [0, 4096], step in [0, 64] "
                                           "(0: from sigma; got %d, %d, %d)", p->patch, p->group, p->step);
    if (p->window < 0 || p->window > 1024)
        return sci_error_set(err, -EINVAL, "desci: window must be in [0, 1024] (got %d)", p->window);
    if (!(p->c > 0) || !isfinite(p->c))
        return sci_error_set(err, -EINVAL, "desci: c must be > 0 (got %g)", p->c);
    if (p->match_every < 1)
        return sci_error_set(err, -EINVAL, "desci: match_every must be >= 1 (got %d)", p->match_every);
    if (!(p->lambda > 0) || !isfinite(p->lambda))
        return sci_error_set(err, -EINVAL, "desci: lambda must be > 0 (got %g)", p->lambda);
    if (p->tv_init < 0 || p->tv_init > 100000)
        return sci_error_set(err, -EINVAL, "desci: tv_init must be in [0, 1e5] (got %d)", p->tv_init);
    if (p->threads < 0 || p->threads > 1024 || p->metrics_every < 0 || p->ssim_every < 0)
        return sci_error_set(err, -EINVAL, "desci: threads and metrics intervals must be >= 0");
    return 0;
}

/* Stage of iteration it (1-based) when `iters` split evenly over `stages`, the first taking the remainder. */
static int stage_of(int it, int iters, int stages)
{
    const int base = iters / stages, extra = iters % stages;
    int end = 0;
    for (int s = 0; s < stages; s++) {
        end += base + (s < extra);
        if (it <= end)
            return s;
    }
    return stages - 1;
}

/* The WNNM parameters of a stage: vparaconfig.m's by σ, then the overrides. */
static sci_wnnm_params stage_params(const sci_desci_params *q, double sigma255)
{
    sci_wnnm_params w;
    sci_wnnm_params_for_sigma(&w, sigma255);
    if (q->patch > 0)
        w.patch = q->patch, w.step = sci_wnnm_step_for_patch(q->patch);
    if (q->group > 0)
        w.group = q->group;
    if (q->step > 0)
        w.step = q->step;
    w.window = q->window;
    w.c = q->c;
    return w;
}

static int same_geometry(const sci_wnnm_params *a, const sci_wnnm_params *b)
{
    return a->patch == b->patch && a->group == b->group && a->step == b->step && a->window == b->window;
}

/* x⁰: Aᵀy, or tv_init iterations of GAP-TV at its benchmark settings (TV weight on the problem's scale). */
static int start_point(const sci_problem *p, const sci_desci_params *q, sci_cube *x, sci_error *err)
{
    if (q->tv_init == 0) {
        sci_op_adjoint(p->mask, p->meas, x);
        return 0;
    }
    sci_gaptv_params tv;
    sci_gaptv_params_default(&tv);
    tv.iters = q->tv_init;
    tv.metrics_every = tv.ssim_every = 0;
    tv.tv_weight *= p->peak > 0 ? p->peak : 1.0;
    sci_result r = {0};
    int rc = sci_gaptv_solve(p, &tv, &r, NULL, NULL);
    if (rc == 0 && r.frames)
        memcpy(x->data, r.frames->data, sci_cube_count(x) * sizeof *x->data);
    else
        sci_error_set(err, rc < 0 ? rc : -EINVAL, "desci: GAP-TV start: %s", r.error.msg);
    sci_result_free_contents(&r);
    return rc < 0 ? rc : 0;
}

/* --- checkpoints ---------------------------------------------------------------------------------------------
 * A blob: header, then x (N frames), ȳ (one frame) and, when groups exist, the image they were matched on (N
 * frames). Re-matching that image at resume gives the same groups, so a resumed run repeats the uninterrupted
 * one's arithmetic. The settings hash covers what changes the frames (not threads or metrics intervals). */
#define DESCI_CKPT_MAGIC "SCIDESCI"
#define DESCI_CKPT_VERSION 1u

typedef struct desci_ckpt_header {
    char magic[8];
    uint32_t version;
    int32_t w, h, n;
    int32_t iter;       /* complete iterations the state follows */
    int32_t has_match;  /* 1: the matched-on image follows ȳ */
    int32_t pad;
    uint64_t settings;  /* FNV-1a of the settings that change the frames */
    uint64_t meas;      /* FNV-1a of the measurement */
} desci_ckpt_header;

static uint64_t fnv1a(uint64_t h, const void *data, size_t bytes)
{
    const unsigned char *b = data;
    for (size_t i = 0; i < bytes; i++)
        h = (h ^ b[i]) * 1099511628211ull;
    return h;
}

static uint64_t settings_hash(const sci_desci_params *q)
{
    sci_desci_params k = {0}; /* copied field by field: padding and the run-only fields stay zero */
    k.iters = q->iters, k.sigma = q->sigma, k.patch = q->patch, k.group = q->group, k.step = q->step;
    k.window = q->window, k.c = q->c, k.match_every = q->match_every, k.lambda = q->lambda;
    k.accelerate = q->accelerate, k.tv_init = q->tv_init;
    uint64_t h = 14695981039346656037ull;
    const int ints[] = {k.iters, k.sigma.n, k.patch, k.group, k.step, k.window, k.match_every, k.accelerate,
                        k.tv_init};
    h = fnv1a(h, ints, sizeof ints);
    h = fnv1a(h, k.sigma.v, (size_t)k.sigma.n * sizeof *k.sigma.v);
    const double dbl[] = {k.c, k.lambda};
    return fnv1a(h, dbl, sizeof dbl);
}

/* Hand out the state after `iter` complete iterations. 0 or the callback's nonzero return (-ENOMEM on no memory). */
static int ckpt_write(const solver_io *io, const sci_desci_params *q, const sci_problem *p, int iter,
                      const sci_cube *x, const sci_cube *ybar, const sci_cube *xm, int has_match)
{
    const size_t count = sci_cube_count(x), fs = sci_cube_frame_size(x);
    const size_t bytes = sizeof(desci_ckpt_header) + (count * (has_match ? 2 : 1) + fs) * sizeof(float);
    unsigned char *blob = malloc(bytes);
    if (!blob)
        return -ENOMEM;
    desci_ckpt_header hd = {.version = DESCI_CKPT_VERSION, .w = x->w, .h = x->h, .n = x->n, .iter = iter,
                            .has_match = has_match, .settings = settings_hash(q),
                            .meas = fnv1a(14695981039346656037ull, p->meas->data,
                                          sci_cube_count(p->meas) * sizeof(float))};
    memcpy(hd.magic, DESCI_CKPT_MAGIC, 8);
    unsigned char *o = blob;
    memcpy(o, &hd, sizeof hd), o += sizeof hd;
    memcpy(o, x->data, count * sizeof(float)), o += count * sizeof(float);
    memcpy(o, ybar->data, fs * sizeof(float)), o += fs * sizeof(float);
    if (has_match)
        memcpy(o, xm->data, count * sizeof(float));
    const int rc = io->checkpoint_fn(blob, bytes, iter, io->checkpoint_user);
    free(blob);
    return rc;
}

/* Read a blob into x, ȳ and xm; *iter and *has_match from its header. -EINVAL with a message saying what differs. */
static int ckpt_read(const solver_io *io, const sci_desci_params *q, const sci_problem *p, sci_cube *x,
                     sci_cube *ybar, sci_cube *xm, int *iter, int *has_match, sci_error *err)
{
    desci_ckpt_header hd;
    if (io->resume_bytes < sizeof hd)
        return sci_error_set(err, -EINVAL, "desci: resume: %zu bytes is too short for a DeSCI checkpoint",
                             io->resume_bytes);
    memcpy(&hd, io->resume, sizeof hd);
    if (memcmp(hd.magic, DESCI_CKPT_MAGIC, 8) != 0)
        return sci_error_set(err, -EINVAL, "desci: resume: not a DeSCI checkpoint (bad magic)");
    if (hd.version != DESCI_CKPT_VERSION)
        return sci_error_set(err, -EINVAL, "desci: resume: checkpoint version %u, this build reads %u",
                             hd.version, DESCI_CKPT_VERSION);
    if (hd.w != x->w || hd.h != x->h || hd.n != x->n)
        return sci_error_set(err, -EINVAL, "desci: resume: checkpoint of a %dx%dx%d problem, this one is %dx%dx%d",
                             hd.w, hd.h, hd.n, x->w, x->h, x->n);
    if (hd.settings != settings_hash(q))
        return sci_error_set(err, -EINVAL, "desci: resume: checkpoint made with other settings (iters, sigma, "
                                           "patch, group, step, window, c, match_every, lambda, accelerate or "
                                           "tv_init differ)");
    if (hd.meas != fnv1a(14695981039346656037ull, p->meas->data, sci_cube_count(p->meas) * sizeof(float)))
        return sci_error_set(err, -EINVAL, "desci: resume: checkpoint of another measurement");
    const size_t count = sci_cube_count(x), fs = sci_cube_frame_size(x);
    const size_t bytes = sizeof hd + (count * (hd.has_match ? 2 : 1) + fs) * sizeof(float);
    if (hd.iter < 0 || hd.iter > q->iters || (hd.has_match != 0 && hd.has_match != 1) || io->resume_bytes != bytes)
        return sci_error_set(err, -EINVAL, "desci: resume: damaged checkpoint (iteration %d, %zu bytes, "
                                           "expected %zu)", hd.iter, io->resume_bytes, bytes);
    const unsigned char *i = (const unsigned char *)io->resume + sizeof hd;
    memcpy(x->data, i, count * sizeof(float)), i += count * sizeof(float);
    memcpy(ybar->data, i, fs * sizeof(float)), i += fs * sizeof(float);
    if (hd.has_match)
        memcpy(xm->data, i, count * sizeof(float));
    *iter = hd.iter, *has_match = hd.has_match;
    return 0;
}

/* --- the run ---------------------------------------------------------------------------------------------------
 * One run's inputs (borrowed for the call), buffers (owned, freed by desci_state_free) and the state a checkpoint
 * names. */
typedef struct desci_state {
    const sci_problem *problem;
    const sci_desci_params *params;
    const solver_io *io;
    sci_result *result;
    sci_tracer tr;
    sci_cube *x, *xprev, *yhat, *ybar, *ybprev, *phi, *r;
    sci_cube *xm, *xmn; /* the image the groups were matched on; the one being matched */
    double *rowbuf;
    sci_wnnm *wn;
    sci_wnnm_params cur;
    int first, has_match, done;
} desci_state;

/* rc: the status so far (>= 0); returned unchanged by a success that allocates nothing new to report. */
static int desci_state_alloc(desci_state *d, int rc, sci_error *err)
{
    const sci_cube *mask = d->problem->mask;
    const int w = mask->w, h = mask->h, n = mask->n;
    d->rowbuf = malloc(2 * (size_t)h * sizeof *d->rowbuf);
    if (!d->rowbuf || (rc = sci_cube_new(&d->x, w, h, n, err)) < 0 ||
        (rc = sci_cube_new(&d->xprev, w, h, n, err)) < 0 || (rc = sci_cube_new(&d->yhat, w, h, 1, err)) < 0 ||
        (rc = sci_cube_new(&d->ybar, w, h, 1, err)) < 0 || (rc = sci_cube_new(&d->ybprev, w, h, 1, err)) < 0 ||
        (rc = sci_cube_new(&d->xm, w, h, n, err)) < 0 || (rc = sci_cube_new(&d->xmn, w, h, n, err)) < 0 ||
        (rc = sci_cube_new(&d->phi, w, h, 1, err)) < 0 || (rc = sci_cube_new(&d->r, w, h, 1, err)) < 0) {
        if (rc >= 0)
            rc = sci_error_set(err, -ENOMEM, "desci: out of memory");
    }
    return rc;
}

static void desci_state_free(desci_state *d)
{
    free(d->rowbuf);
    sci_wnnm_free(d->wn);
    sci_cube_free(d->x);
    sci_cube_free(d->xprev);
    sci_cube_free(d->yhat);
    sci_cube_free(d->ybar);
    sci_cube_free(d->ybprev);
    sci_cube_free(d->xm);
    sci_cube_free(d->xmn);
    sci_cube_free(d->phi);
    sci_cube_free(d->r);
}

/* State from a checkpoint, and the groups that were in use when it was taken. */
static int desci_resume(desci_state *d, sci_error *err)
{
    const sci_desci_params *params = d->params;
    const sci_cube *mask = d->problem->mask;
    int rc;
    if ((rc = ckpt_read(d->io, params, d->problem, d->x, d->ybar, d->xm, &d->first, &d->has_match, err)) < 0)
        return rc;
    d->done = d->first++;
    sci_op_forward_residual(mask, d->x, d->problem->meas, d->yhat, d->rowbuf);
    if (d->has_match && d->done < params->iters) { /* the groups in use when the checkpoint was taken */
        d->cur = stage_params(params, params->sigma.v[stage_of(d->done, params->iters, params->sigma.n)]);
        if ((rc = sci_wnnm_new(&d->wn, mask->w, mask->h, mask->n, &d->cur, params->threads, err)) < 0 ||
            (rc = sci_wnnm_match(d->wn, d->xm->data, d->io->cancel)) < 0) {
            if (rc == SCI_ECANCELED)
                d->result->stopped = rc, sci_error_set(err, rc, "desci canceled at resume");
            return rc;
        }
    }
    return rc;
}

/* x⁰ and ȳ⁰ of a fresh run. */
static int desci_begin(desci_state *d, sci_error *err)
{
    int rc;
    if ((rc = start_point(d->problem, d->params, d->x, err)) < 0) /* its time counts in the trace's */
        return rc;
    sci_op_forward_residual(d->problem->mask, d->x, d->problem->meas, d->yhat, d->rowbuf);
    /* ȳ = 0 is the reference's start from Aᵀy; from a warm start it would make the first step
     * x += λAᵀ((y − 2ŷ) ⊘ Φ) ≈ −λAᵀ(y ⊘ Φ) and throw the start away (5 dB after one step from GAP-TV's
     * 34.6). ȳ = A(x⁰) makes the first step the plain GAP step, which keeps it. */
    if (d->params->tv_init > 0)
        memcpy(d->ybar->data, d->yhat->data, sci_cube_frame_size(d->problem->mask) * sizeof *d->ybar->data);
    return rc;
}

/* A new WNNM plan when the stage's patch geometry differs from the current one (then *match = 1). rc: the
 * status so far, returned unchanged when the plan stays. */
static int desci_stage_plan(desci_state *d, double sigma255, int rc, int *match, sci_error *err)
{
    const sci_wnnm_params want = stage_params(d->params, sigma255);
    if (d->wn && same_geometry(&want, &d->cur))
        return rc;
    const sci_cube *mask = d->problem->mask;
    sci_wnnm_free(d->wn); /* one plan at a time: the groups of a 256×256×8 problem take 35–70 MB */
    d->wn = NULL;
    if ((rc = sci_wnnm_new(&d->wn, mask->w, mask->h, mask->n, &want, d->params->threads, err)) < 0) {
        sci_error_prefix(err, "desci: sigma %g: ", sigma255);
        return rc;
    }
    d->cur = want;
    *match = 1;
    return rc;
}

/* The GAP step on x (with the accelerated ȳ update), after saving x and ȳ for a cancel. */
static void desci_gap_step(desci_state *d)
{
    const sci_desci_params *params = d->params;
    const sci_cube *y = d->problem->meas, *mask = d->problem->mask;
    const int n = mask->n;
    const size_t fs = sci_cube_frame_size(mask), count = sci_cube_count(mask);
    const float lambda = (float)params->lambda;
    sci_cube *x = d->x, *ybar = d->ybar;
    memcpy(d->xprev->data, x->data, count * sizeof *x->data);
    memcpy(d->ybprev->data, ybar->data, fs * sizeof *ybar->data);
    const float *yv = y->data, *yh = d->yhat->data, *ph = d->phi->data;
    float *yb = ybar->data, *rv = d->r->data;
    for (size_t i = 0; i < fs; i++) {
        if (params->accelerate)
            yb[i] += yv[i] - yh[i];
        rv[i] = ((params->accelerate ? yb[i] : yv[i]) - yh[i]) / ph[i];
    }
    for (int k = 0; k < n; k++) {
        const float *m = mask->data + (size_t)k * fs;
        float *xk = x->data + (size_t)k * fs;
        for (size_t i = 0; i < fs; i++)
            xk[i] += lambda * (m[i] * rv[i]);
    }
}

/* Iteration it: plan, GAP step, (re)match, denoise, record, checkpoint. rc: the status so far (>= 0; the
 * denoise runs only when it is 0 after matching). Returns the new status: 0 to go on, nonzero to stop with x
 * handed out, or with *fatal set to stop without. */
static int desci_iterate(desci_state *d, int it, int rc, int *fatal, sci_error *err)
{
    const sci_desci_params *params = d->params;
    const solver_io *io = d->io;
    const sci_cube *mask = d->problem->mask;
    const size_t fs = sci_cube_frame_size(mask), count = sci_cube_count(mask);
    const double peak = d->problem->peak > 0 ? d->problem->peak : 1.0;
    const double sigma255 = params->sigma.v[stage_of(it, params->iters, params->sigma.n)];
    int match = (it - 1) % params->match_every == 0;
    if ((rc = desci_stage_plan(d, sigma255, rc, &match, err)) < 0)
        return *fatal = 1, rc;
    desci_gap_step(d);
    if (match) {
        memcpy(d->xmn->data, d->x->data, count * sizeof *d->x->data);
        rc = sci_wnnm_match(d->wn, d->x->data, io->cancel);
    }
    if (rc == 0)
        rc = sci_wnnm_denoise(d->wn, d->x->data, sigma255 / 255.0 * peak, d->x->data, io->cancel);
    if (rc == SCI_ECANCELED) {
        /* inside an iteration: hand out the last complete iterate */
        memcpy(d->x->data, d->xprev->data, count * sizeof *d->x->data);
        memcpy(d->ybar->data, d->ybprev->data, fs * sizeof *d->ybar->data);
        sci_error_set(err, rc, "desci canceled at iteration %d", it);
        d->result->stopped = rc;
        return rc;
    }
    if (rc < 0) {
        sci_error_set(err, rc, "desci: iteration %d (sigma %g): the eigensolver failed on a patch group "
                               "(a non-finite estimate?)", it, sigma255);
        return *fatal = 1, rc;
    }
    if (match) { /* the iteration is complete: its groups become the ones a checkpoint names */
        sci_cube *t = d->xm;
        d->xm = d->xmn, d->xmn = t, d->has_match = 1;
    }
    d->done = it;
    const double res = sci_op_forward_residual(mask, d->x, d->problem->meas, d->yhat, d->rowbuf);
    if ((rc = sci_tracer_record(&d->tr, it, d->x, res, NAN)) != 0)
        return rc;
    if (io->checkpoint_fn && io->checkpoint_every > 0 && it % io->checkpoint_every == 0 && it < params->iters)
        rc = ckpt_write(io, params, d->problem, it, d->x, d->ybar, d->xm, d->has_match);
    return rc;
}

int sci_desci_solve_io(const sci_problem *problem, const sci_desci_params *params, const solver_io *io,
                       sci_result *result)
{
    snprintf(result->method, sizeof result->method, "desci");
    sci_error *err = &result->error;
    int rc = sci_desci_params_check(params, err);
    if (rc == 0)
        rc = sci_problem_validate(problem, err);
    if (rc == 0 && params->iters < params->sigma.n)
        rc = sci_error_set(err, -EINVAL, "desci: iters (%d) must be at least one per sigma stage (%d)",
                           params->iters, params->sigma.n);
    if (rc < 0)
        return rc;
    desci_state d = {.problem = problem, .params = params, .io = io, .result = result, .first = 1};
    if ((rc = desci_state_alloc(&d, rc, err)) < 0)
        goto out;
    sci_op_phi_sum(problem->mask, d.phi);
    sci_tracer_start(&d.tr, problem, result, io->progress, io->user, params->iters, params->metrics_every,
                     params->ssim_every);
    if ((rc = io->resume ? desci_resume(&d, err) : desci_begin(&d, err)) < 0)
        goto out;
    for (int it = d.first; it <= params->iters; it++) {
        int fatal = 0;
        rc = desci_iterate(&d, it, rc, &fatal, err);
        if (fatal)
            goto out;
        if (rc != 0)
            break;
    }
    /* at the end and on a cancel: the state after the last complete iteration */
    if (io->checkpoint_fn && (rc == 0 || rc == SCI_ECANCELED)) {
        const int crc = ckpt_write(io, params, problem, d.done, d.x, d.ybar, d.xm, d.has_match);
        if (crc != 0 && rc == 0)
            rc = crc;
    }
    if (rc != SCI_EDIVERGED) {
        result->frames = d.x; /* never hand out a diverged estimate */
        d.x = NULL;
    }
out:
    desci_state_free(&d);
    return rc;
}

int sci_desci_solve(const sci_problem *problem, const sci_desci_params *params, sci_result *result,
                    sci_progress_fn progress, void *user, const atomic_int *cancel)
{
    const solver_io io = {.progress = progress, .user = user, .cancel = cancel};
    return sci_desci_solve_io(problem, params, &io, result);
}

/* --- the method's row in the solver table (recon/solver.h) ------------------------------------------------ */

#define DESCI_FIELD(k, t, f, lo, hi, help) {k, t, offsetof(sci_desci_params, f), lo, hi, NULL, 0, help}
static const solver_field desci_fields[] = {
    DESCI_FIELD("iters", SOLVER_FIELD_INT, iters, 1, 1e6, "GAP iterations over all sigma stages (split evenly)"),
    DESCI_FIELD("sigma", SOLVER_FIELD_LIST, sigma, 0.001, 255,
                "WNNM sigma of each stage on the 0-255 scale, e.g. 100,50,25,12,6"),
    DESCI_FIELD("patch", SOLVER_FIELD_INT, patch, 0, 64, "patch side in pixels (0: from sigma, 6 to 9)"),
    DESCI_FIELD("group", SOLVER_FIELD_INT, group, 0, 4096, "similar patches per group (0: from sigma, 70 to 140)"),
    DESCI_FIELD("step", SOLVER_FIELD_INT, step, 0, 64, "key patch grid step (0: floor(patch/2 - 1))"),
    DESCI_FIELD("window", SOLVER_FIELD_INT, window, 0, 1024, "block-matching search radius in pixels, all frames"),
    DESCI_FIELD("c", SOLVER_FIELD_DOUBLE, c, 0, 100, "WNNM weight constant (> 0)"),
    DESCI_FIELD("match_every", SOLVER_FIELD_INT, match_every, 1, 1e6, "block matching every k iterations"),
    DESCI_FIELD("lambda", SOLVER_FIELD_DOUBLE, lambda, 0, 1e6, "GAP step size λ (> 0)"),
    DESCI_FIELD("accelerate", SOLVER_FIELD_BOOL, accelerate, 0, 1, "accelerated GAP (ȳ accumulation)"),
    DESCI_FIELD("tv_init", SOLVER_FIELD_INT, tv_init, 0, 1e5, "GAP-TV iterations for the starting point (0: Aᵀy)"),
    DESCI_FIELD("threads", SOLVER_FIELD_INT, threads, 0, 1024, "OpenMP threads (0: all)"),
    DESCI_FIELD("metrics_every", SOLVER_FIELD_INT, metrics_every, 0, 1e9, "PSNR in the trace every k iterations"),
    DESCI_FIELD("ssim_every", SOLVER_FIELD_INT, ssim_every, 0, 1e9, "SSIM in the trace every k iterations"),
};

static void desci_defaults(void *s) { sci_desci_params_default(s); }

static void desci_preset(void *s, solver_preset p) { sci_desci_preset(s, p); }

static int desci_check(const void *s, sci_error *err) { return sci_desci_params_check(s, err); }

static int desci_run(const sci_problem *p, const void *s, const solver_io *io, sci_result *r)
{
    return sci_desci_solve_io(p, s, io, r);
}

/* The bench grid: a short σ 12 run from GAP-TV on a small search window (the quick suite checks the report's
 * pipeline, in seconds), then fast and balanced. Best (the reference recipe, 20 minutes or
 * more on 256 × 256 × 8) is left to a run of its own, to keep the report's time in bounds. */
static const char *const desci_bench_quick[] = {
    "{\"iters\":2,\"sigma\":[12],\"tv_init\":20,\"window\":8,\"group\":24}", NULL};
static const char *const desci_bench_full[] = {"{\"iters\":10,\"sigma\":[12],\"tv_init\":100}",
                                               "{\"preset\":\"fast\"}", "{\"preset\":\"balanced\"}", NULL};

const solver_ops sci_desci_solver = {
    .name = "desci",
    .summary = "GAP with weighted-nuclear-norm (WNNM) denoising of similar-patch groups across frames (slow, best)",
    .caps = SOLVER_CHECKPOINTS,
    .settings_size = sizeof(sci_desci_params),
    .fields = {{desci_fields, sizeof desci_fields / sizeof desci_fields[0], 0}},
    .defaults = desci_defaults,
    .preset = desci_preset,
    .check = desci_check,
    .run = desci_run,
    .bench_quick = desci_bench_quick,
    .bench_full = desci_bench_full,
};
