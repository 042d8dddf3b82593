/* recon/nerf/adam.c — Adam and learning-rate schedules (see adam.h). */
#include "recon/nerf/adam.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct nerf_adam {
    nerf_adam_config cfg;
    size_t n;
    float *m, *s;
    uint32_t *t;
    /* bias corrections by step count, 1 − β1^t and sqrt(1 − β2^t) for t = 1..n_corr (index 0 unused), and the
     * step factor lr·sqrt(1 − β2^t)/(1 − β1^t) of the current call; t_hi bounds every t[j] (UINT32_MAX: not
     * known since the buffers were handed out, found by a scan at the next step) */
    double *c1, *sc2, *k;
    uint32_t n_corr, cap_corr, t_hi;
};

int nerf_adam_new(nerf_adam **out, size_t n_params, const nerf_adam_config *cfg, sci_error *err)
{
    *out = NULL;
    if (!(cfg->beta1 >= 0.0 && cfg->beta1 < 1.0) || !(cfg->beta2 >= 0.0 && cfg->beta2 < 1.0))
        return sci_error_set(err, SCI_ECONFIG, "adam: beta1 %g / beta2 %g outside [0, 1)", cfg->beta1, cfg->beta2);
    if (!(cfg->eps > 0.0)) return sci_error_set(err, SCI_ECONFIG, "adam: eps %g must be > 0", cfg->eps);
    if (!(cfg->weight_decay >= 0.0))
        return sci_error_set(err, SCI_ECONFIG, "adam: weight_decay %g must be >= 0", cfg->weight_decay);
    nerf_adam *a = calloc(1, sizeof *a);
    if (!a) return sci_error_set(err, -ENOMEM, "adam: out of memory");
    a->cfg = *cfg;
    a->n = n_params;
    a->m = calloc(n_params ? n_params : 1, sizeof *a->m);
    a->s = calloc(n_params ? n_params : 1, sizeof *a->s);
    a->t = calloc(n_params ? n_params : 1, sizeof *a->t);
    if (!a->m || !a->s || !a->t) {
        nerf_adam_free(a);
        return sci_error_set(err, -ENOMEM, "adam: out of memory for %zu parameters", n_params);
    }
    *out = a;
    return 0;
}

void nerf_adam_free(nerf_adam *a)
{
    if (!a) return;
    free(a->m);
    free(a->s);
    free(a->t);
    free(a->c1);
    free(a->sc2);
    free(a->k);
    free(a);
}

void nerf_adam_reset(nerf_adam *a)
{
    memset(a->m, 0, a->n * sizeof *a->m);
    memset(a->s, 0, a->n * sizeof *a->s);
    memset(a->t, 0, a->n * sizeof *a->t);
    a->t_hi = 0;
}

uint32_t nerf_adam_steps_of(const nerf_adam *a, size_t j) { return a->t[j]; }
size_t nerf_adam_param_count(const nerf_adam *a) { return a->n; }

void nerf_adam_buffers(nerf_adam *a, float **m, float **s, uint32_t **steps)
{
    *m = a->m;
    *s = a->s;
    *steps = a->t;
    a->t_hi = UINT32_MAX; /* the caller may write step counts */
}

/* Makes a->k[1..t_hi] hold lr·sqrt(1 − β2^t)/(1 − β1^t) for this call (t_hi: the largest step count after it).
 * -ENOMEM leaves the table short: the step then computes the factors itself. */
static int adam_factors(nerf_adam *a, double lr)
{
    if (a->t_hi == UINT32_MAX) {
        uint32_t hi = 0;
        for (size_t j = 0; j < a->n; j++)
            hi = a->t[j] > hi ? a->t[j] : hi;
        a->t_hi = hi;
    }
    if (a->t_hi < UINT32_MAX - 1)
        a->t_hi++; /* a step raises a count by at most one */
    const uint32_t hi = a->t_hi;
    if (hi > a->cap_corr) {
        uint32_t cap = a->cap_corr ? a->cap_corr : 1024;
        while (cap < hi && cap < UINT32_MAX / 2)
            cap *= 2;
        double *c1 = realloc(a->c1, ((size_t)cap + 1) * sizeof *c1);
        if (c1) a->c1 = c1;
        double *sc2 = realloc(a->sc2, ((size_t)cap + 1) * sizeof *sc2);
        if (sc2) a->sc2 = sc2;
        double *k = realloc(a->k, ((size_t)cap + 1) * sizeof *k);
        if (k) a->k = k;
        if (!c1 || !sc2 || !k) return -ENOMEM;
        a->cap_corr = cap;
    }
    const double b1 = a->cfg.beta1, b2 = a->cfg.beta2, lb1 = log(b1), lb2 = log(b2);
    for (uint32_t t = a->n_corr + 1; t <= hi; t++) {
        /* 1 − β^t via expm1 keeps precision for large t and β near 1 */
        a->c1[t] = b1 > 0.0 ? -expm1(t * lb1) : 1.0;
        a->sc2[t] = sqrt(b2 > 0.0 ? -expm1(t * lb2) : 1.0);
    }
    if (hi > a->n_corr) a->n_corr = hi;
    for (uint32_t t = 1; t <= hi; t++)
        a->k[t] = lr * a->sc2[t] / a->c1[t];
    return 0;
}

/* clang before 16 exports a target_clones function as NAME.ifunc, which other files' calls do not link to
 * (the fuzzers are built with clang): a single version there */
#if defined(__clang__) && __clang_major__ < 16
#define CLONES
#else
#define CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#endif

/* The step of parameters [begin, end) with the factor table kt[0..hi] (every t[j] + 1 <= hi). Branch-free, so it
 * vectorises: a parameter the lazy step skips gets its own values written back (in a hash table the skipped ones
 * are scattered, and the branch mispredicted). The arithmetic is the scalar loop's, in the same order (ISO C: no
 * contraction), so the bits are too. */
CLONES static void adam_range(nerf_adam *a, float *params, const float *grad, size_t begin, size_t end,
                              const double *kt, int lazy, double wd)
{
    const double b1 = a->cfg.beta1, b2 = a->cfg.beta2, eps = a->cfg.eps;
    float *restrict pm = a->m, *restrict ps = a->s, *restrict pp = params;
    uint32_t *restrict pt = a->t;
    for (size_t j = begin; j < end; j++) {
        const double g0 = grad[j];
        const int on = !(lazy && g0 == 0.0);
        const double g = g0 + wd * pp[j];
        const uint32_t t = pt[j] + (uint32_t)on;
        const double m = b1 * pm[j] + (1.0 - b1) * g;
        const double sv = sqrt(b2 * (double)ps[j] * ps[j] + (1.0 - b2) * g * g);
        const float p = (float)(pp[j] - kt[t] * m / (sv + eps));
        pt[j] = t;
        pm[j] = on ? (float)m : pm[j];
        ps[j] = on ? (float)sv : ps[j];
        pp[j] = on ? p : pp[j];
    }
}

void nerf_adam_step(nerf_adam *a, float *params, const float *grad, size_t begin, size_t end, double lr, int lazy,
                    int decay)
{
    const double b1 = a->cfg.beta1, b2 = a->cfg.beta2, eps = a->cfg.eps, wd = decay ? a->cfg.weight_decay : 0.0;
    const double lb1 = log(b1), lb2 = log(b2);
    /* the factor depends on the parameter's own step count, and in a lazily stepped hash table neighbours rarely
     * share it: two expm1 per parameter were a third of its time; a table by step count replaces them (same bits) */
    if (adam_factors(a, lr) == 0) {
        a->k[0] = 0.0; /* read (not used) for a parameter with no step yet that the lazy step skips */
#pragma omp parallel for schedule(dynamic, 1) /* elementwise: any schedule gives the same bits */
        for (size_t j0 = begin; j0 < end; j0 += 16384)
            adam_range(a, params, grad, j0, end - j0 < 16384 ? end : j0 + 16384, a->k, lazy, wd);
        return;
    }
#pragma omp parallel for schedule(dynamic, 16384)
    for (size_t j = begin; j < end; j++) { /* no factor table (out of memory): each factor computed */
        double g = grad[j];
        if (lazy && g == 0.0) continue;
        g += wd * params[j];
        uint32_t t = ++a->t[j];
        double m = b1 * a->m[j] + (1.0 - b1) * g;
        double s = sqrt(b2 * (double)a->s[j] * a->s[j] + (1.0 - b2) * g * g);
        a->m[j] = (float)m;
        a->s[j] = (float)s;
        double c1 = b1 > 0.0 ? -expm1(t * lb1) : 1.0, c2 = b2 > 0.0 ? -expm1(t * lb2) : 1.0;
        params[j] = (float)(params[j] - lr * sqrt(c2) / c1 * m / (s + eps));
    }
}

double nerf_lr_at(const nerf_lr_schedule *s, long step)
{
    double lr = s->lr0;
    if (s->decay_steps > 0) lr *= pow(s->decay_rate, (double)step / (double)s->decay_steps);
    if (s->warmup_steps > 0 && step < s->warmup_steps)
        lr *= s->warmup_start + (1.0 - s->warmup_start) * (double)step / (double)s->warmup_steps;
    return lr;
}
