/* recon/nerf/trainer_ckpt.c — checkpoints of a training run: the whole state as one validated blob (trainer.h). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "recon/nerf/trainer_run.h"

/* Checkpoint header (trainer.h); the arrays follow it. */
#define CKPT_MAGIC "SCINERF"
#define CKPT_VERSION 1u
/* flags: each model's weights' moving average follows its Adam step counts (a run with ema_steps, once begun) */
#define CKPT_EMA 1u

typedef struct ckpt_header {
    char magic[8];
    uint32_t version, flags; /* CKPT_EMA */
    char method[NERF_CKPT_METHOD_MAX];
    int32_t w, h, n, iter;
    uint64_t n_params[2], n_pose_params;
    uint64_t rng[4];
    double wall_s, cpu_s;
    float box[6]; /* the scene box the models were built with */
} ckpt_header;


static uint64_t fnv1a(const unsigned char *p, size_t n)
{
    uint64_t h = 1469598103934665603ull;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

static size_t ckpt_bytes(const nerf_trainer_run_state *r)
{
    size_t b = sizeof(ckpt_header);
    for (int k = 0; k < r->n_pass; k++)
        b += r->ps[k].m->n_params * ((r->ema_live ? 4 : 3) * sizeof(float) + sizeof(uint32_t));
    size_t np = (size_t)nerf_poses_param_count(r->poses);
    return b + np * 4 * sizeof(double) + sizeof(int64_t) + sizeof(uint64_t);
}

static unsigned char *put(unsigned char *o, const void *src, size_t n)
{
    memcpy(o, src, n);
    return o + n;
}

int nerf_trainer_ckpt_save(nerf_trainer_run_state *r, int iter, double wall_s, double cpu_s, unsigned char **out,
                           size_t *bytes)
{
    size_t n = ckpt_bytes(r);
    unsigned char *buf = malloc(n), *o = buf;
    if (!buf)
        return -ENOMEM;
    ckpt_header h = {.magic = CKPT_MAGIC, .version = CKPT_VERSION, .flags = r->ema_live ? CKPT_EMA : 0,
                     .w = r->w, .h = r->h, .n = r->n, .iter = iter,
                     .n_pose_params = (uint64_t)nerf_poses_param_count(r->poses), .wall_s = wall_s, .cpu_s = cpu_s};
    snprintf(h.method, sizeof h.method, "%s", r->c->method);
    memcpy(h.box, r->c->box_lo, sizeof r->c->box_lo);
    memcpy(h.box + 3, r->c->box_hi, sizeof r->c->box_hi);
    for (int k = 0; k < r->n_pass; k++)
        h.n_params[k] = r->ps[k].m->n_params;
    memcpy(h.rng, r->rng.s, sizeof h.rng);
    o = put(o, &h, sizeof h);
    for (int k = 0; k < r->n_pass; k++) {
        nerf_trainer_pass *p = &r->ps[k];
        float *m, *s;
        uint32_t *t;
        nerf_adam_buffers(p->adam, &m, &s, &t);
        size_t np = p->m->n_params;
        o = put(o, p->params, np * sizeof(float));
        o = put(o, m, np * sizeof(float));
        o = put(o, s, np * sizeof(float));
        o = put(o, t, np * sizeof(uint32_t));
        if (r->ema_live)
            o = put(o, p->ema, np * sizeof(float));
    }
    size_t npp = (size_t)nerf_poses_param_count(r->poses);
    long *step;
    double *st = nerf_poses_state(r->poses, &step);
    int64_t step64 = *step;
    o = put(o, nerf_poses_params(r->poses), npp * sizeof(double));
    o = put(o, st, 3 * npp * sizeof(double));
    o = put(o, &step64, sizeof step64);
    uint64_t sum = fnv1a(buf, (size_t)(o - buf));
    o = put(o, &sum, sizeof sum);
    *out = buf;
    *bytes = n;
    return 0;
}

static int ckpt_header_check(const void *blob, size_t bytes, ckpt_header *h, sci_error *err)
{
    if (!blob || bytes < sizeof *h + sizeof(uint64_t))
        return sci_error_set(err, SCI_EFORMAT, "checkpoint: %zu bytes is too short for a checkpoint", bytes);
    memcpy(h, blob, sizeof *h);
    if (memcmp(h->magic, CKPT_MAGIC, sizeof CKPT_MAGIC) != 0)
        return sci_error_set(err, SCI_EFORMAT, "checkpoint: not a scicap NeRF checkpoint (bad magic)");
    if (h->version != CKPT_VERSION)
        return sci_error_set(err, SCI_EFORMAT, "checkpoint: version %u, this build reads %u", h->version,
                             CKPT_VERSION);
    uint64_t sum;
    memcpy(&sum, (const unsigned char *)blob + bytes - sizeof sum, sizeof sum);
    if (sum != fnv1a(blob, bytes - sizeof sum))
        return sci_error_set(err, SCI_EFORMAT, "checkpoint: checksum mismatch (truncated or corrupted)");
    h->method[sizeof h->method - 1] = 0;
    return 0;
}

int nerf_checkpoint_peek(const void *blob, size_t bytes, int *iter, char method[NERF_CKPT_METHOD_MAX],
                         sci_error *err)
{
    ckpt_header h;
    int rc = ckpt_header_check(blob, bytes, &h, err);
    if (rc < 0)
        return rc;
    if (iter)
        *iter = h.iter;
    if (method)
        memcpy(method, h.method, sizeof h.method);
    return 0;
}

static int all_finite_f(const float *v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(v[i]))
            return 0;
    return 1;
}

int nerf_trainer_ckpt_load(nerf_trainer_run_state *r, const void *blob, size_t bytes, sci_error *err)
{
    ckpt_header h;
    int rc = ckpt_header_check(blob, bytes, &h, err);
    if (rc < 0)
        return rc;
    const char *m = r->c->method;
    if (strcmp(h.method, m) != 0)
        return sci_error_set(err, SCI_EFORMAT, "checkpoint: written by method '%s', this run is '%s'", h.method, m);
    if (h.w != r->w || h.h != r->h || h.n != r->n)
        return sci_error_set(err, SCI_ESHAPE, "checkpoint: problem %dx%dx%d, this one is %dx%dx%d", h.w, h.h, h.n,
                             r->w, r->h, r->n);
    for (int k = 0; k < 2; k++) {
        uint64_t want = k < r->n_pass ? r->ps[k].m->n_params : 0;
        if (h.n_params[k] != want)
            return sci_error_set(err, SCI_ESHAPE,
                                 "checkpoint: %s model has %llu parameters, this configuration %llu (another "
                                 "network: resume with the settings it was written with, e.g. its inter_gate, "
                                 "blocks or hash table)",
                                 k ? "fine" : "coarse", (unsigned long long)h.n_params[k], (unsigned long long)want);
    }
    if (h.flags & ~CKPT_EMA)
        return sci_error_set(err, SCI_EFORMAT, "checkpoint: unknown flags 0x%x", (unsigned)h.flags);
    if ((h.flags & CKPT_EMA) && r->c->ema_steps <= 0)
        return sci_error_set(err, -EINVAL, "checkpoint: holds a moving average of the weights; resume with the "
                             "ema_steps it was written with");
    r->ema_live = (h.flags & CKPT_EMA) != 0;
    /* A checkpoint of a run with known poses may start a run that optimises them (scene first, poses after): the
     * poses then start as configured. Otherwise the pose parametrisation must be the same. */
    const int skip_poses = h.n_pose_params == 0 && nerf_poses_param_count(r->poses) > 0;
    if (!skip_poses && h.n_pose_params != (uint64_t)nerf_poses_param_count(r->poses))
        return sci_error_set(err, SCI_ESHAPE, "checkpoint: %llu pose parameters, this pose mode has %d",
                             (unsigned long long)h.n_pose_params, nerf_poses_param_count(r->poses));
    size_t want = ckpt_bytes(r) - (skip_poses ? (size_t)nerf_poses_param_count(r->poses) * 4 * sizeof(double) : 0);
    if (bytes != want)
        return sci_error_set(err, SCI_EFORMAT, "checkpoint: %zu bytes, expected %zu", bytes, want);
    if (h.iter < 0 || h.iter > 10000000 || !isfinite(h.wall_s) || !isfinite(h.cpu_s))
        return sci_error_set(err, SCI_EFORMAT, "checkpoint: iteration %d or times out of range", h.iter);
    const unsigned char *in = (const unsigned char *)blob + sizeof h;
    for (int k = 0; k < r->n_pass; k++) {
        nerf_trainer_pass *p = &r->ps[k];
        float *mm, *s;
        uint32_t *t;
        nerf_adam_buffers(p->adam, &mm, &s, &t);
        size_t np = p->m->n_params;
        memcpy(p->params, in, np * sizeof(float)), in += np * sizeof(float);
        memcpy(mm, in, np * sizeof(float)), in += np * sizeof(float);
        memcpy(s, in, np * sizeof(float)), in += np * sizeof(float);
        memcpy(t, in, np * sizeof(uint32_t)), in += np * sizeof(uint32_t);
        if (r->ema_live)
            memcpy(p->ema, in, np * sizeof(float)), in += np * sizeof(float);
        if (!all_finite_f(p->params, np) || !all_finite_f(mm, np) || !all_finite_f(s, np) ||
            (r->ema_live && !all_finite_f(p->ema, np)))
            return sci_error_set(err, SCI_ENONFINITE, "checkpoint: non-finite %s model parameters or moments",
                                 k ? "fine" : "coarse");
    }
    if (!skip_poses) { /* else the poses keep their configured start */
        size_t npp = (size_t)h.n_pose_params;
        long *step;
        double *st = nerf_poses_state(r->poses, &step), *xi = nerf_poses_params(r->poses);
        int64_t step64;
        memcpy(xi, in, npp * sizeof(double)), in += npp * sizeof(double);
        memcpy(st, in, 3 * npp * sizeof(double)), in += 3 * npp * sizeof(double);
        memcpy(&step64, in, sizeof step64);
        for (size_t i = 0; i < 4 * npp; i++)
            if (!isfinite(i < npp ? xi[i] : st[i - npp]))
                return sci_error_set(err, SCI_ENONFINITE, "checkpoint: non-finite pose parameters");
        *step = (long)step64;
    }
    memcpy(r->rng.s, h.rng, sizeof h.rng);
    r->wall0_ns = (int64_t)(h.wall_s * 1e9);
    r->cpu0_ns = (int64_t)(h.cpu_s * 1e9);
    return h.iter;
}


int nerf_trainer_ckpt_box(const void *blob, size_t bytes, float lo[3], float hi[3], sci_error *err)
{
    ckpt_header h;
    int rc = ckpt_header_check(blob, bytes, &h, err);
    if (rc < 0)
        return rc;
    for (int d = 0; d < 6; d++)
        if (!isfinite(h.box[d]))
            return sci_error_set(err, SCI_EFORMAT, "checkpoint: scene box not finite");
    memcpy(lo, h.box, 3 * sizeof *lo);
    memcpy(hi, h.box + 3, 3 * sizeof *hi);
    return 0;
}
