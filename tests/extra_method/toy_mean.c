/* tests/extra_method/toy_mean.c — "toy-mean", a method that exists only in the test build of $(BUILD)/extra-method
 * (recon/solver.c compiled with -DSCICAP_EXTRA_SOLVER=sci_toy_mean_solver): this file and that one table row are
 * all it takes for scicap recon, scicapd, the Python module and scicap bench to offer it
 * (tests/integration/test_extra_method.c, tests/python/test_extra_method.py).
 *
 * The method: every frame starts as the snapshot divided by the sum of the masks (the mean scene each pixel saw;
 * zero with mean_start false), then `iters` projections onto the measurement,
 * x_f += gain · M_f (y − Σ_f M_f x_f) / Σ_f M_f², without a prior.
 * Cheap (a few passes over the cube) and real: it returns frames and a trace row per iteration like every method.
 */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>

#include "recon/sci_ops.h"
#include "recon/solver.h"
#include "recon/tracer.h"

/* Only the keys every row must have (iters) and one of its own: the keys other methods share (metrics_every, ...)
 * are optional, and this row shows that every interface copes without them. */
typedef struct toy_mean_params {
    int iters;      /* projections after the mean start, >= 1 */
    double gain;    /* step of each projection, (0, 2) keeps it stable */
    int mean_start; /* 1: start from the mean scene, 0: from zero */
} toy_mean_params;

static const solver_field toy_mean_fields[] = {
    {"iters", SOLVER_FIELD_INT, offsetof(toy_mean_params, iters), 1, 100, NULL, 0, "projections after the mean start"},
    {"gain", SOLVER_FIELD_DOUBLE, offsetof(toy_mean_params, gain), 0.1, 1.9, NULL, 0,
     "step of each projection onto the snapshot"},
    {"mean_start", SOLVER_FIELD_BOOL, offsetof(toy_mean_params, mean_start), 0, 1, NULL, 0,
     "start from the snapshot over the masks' sum (else from zero)"},
};

static void toy_mean_defaults(void *s)
{
    *(toy_mean_params *)s = (toy_mean_params){.iters = 3, .gain = 1, .mean_start = 1};
}

static void toy_mean_preset(void *s, solver_preset p)
{
    static const int iters[SOLVER_PRESET_COUNT] = {1, 3, 10};
    ((toy_mean_params *)s)->iters = iters[p];
}

/* x_f = y / Σ_f M_f where the masks open the pixel, else 0. */
static void toy_mean_start(const sci_cube *mask, const sci_cube *y, sci_cube *x)
{
    const size_t fs = sci_cube_frame_size(mask);
    for (size_t i = 0; i < fs; i++) {
        double sum = 0;
        for (int f = 0; f < mask->n; f++)
            sum += sci_cube_frame(mask, f)[i];
        const float v = sum > 0 ? (float)(y->data[i] / sum) : 0.0f;
        for (int f = 0; f < mask->n; f++)
            sci_cube_frame(x, f)[i] = v;
    }
}

static int toy_mean_run(const sci_problem *p, const void *settings, const solver_io *io, sci_result *result)
{
    const toy_mean_params *q = settings;
    sci_error *err = &result->error;
    int rc = sci_problem_validate(p, err);
    if (rc < 0)
        return rc;
    const sci_cube *mask = p->mask, *y = p->meas;
    const size_t fs = sci_cube_frame_size(mask);
    sci_cube *x = NULL, *yhat = NULL, *phi = NULL;
    double *rowbuf = malloc(2 * (size_t)mask->h * sizeof *rowbuf);
    if (!rowbuf) {
        rc = sci_error_set(err, -ENOMEM, "toy-mean: out of memory");
        goto out;
    }
    if ((rc = sci_cube_new(&x, mask->w, mask->h, mask->n, err)) < 0 ||
        (rc = sci_cube_new(&yhat, mask->w, mask->h, 1, err)) < 0 ||
        (rc = sci_cube_new(&phi, mask->w, mask->h, 1, err)) < 0)
        goto out;
    sci_op_phi_sum(mask, phi);
    if (q->mean_start)
        toy_mean_start(mask, y, x);
    sci_tracer tr;
    sci_tracer_start(&tr, p, result, io->progress, io->user, q->iters, 1, 0); /* PSNR every row, SSIM at the end */
    sci_op_forward_residual(mask, x, y, yhat, rowbuf);
    for (int it = 1; it <= q->iters; it++) {
        for (size_t i = 0; i < fs; i++) {
            const float r = (float)(q->gain * (y->data[i] - yhat->data[i]) / phi->data[i]);
            for (int f = 0; f < mask->n; f++)
                sci_cube_frame(x, f)[i] += r * sci_cube_frame(mask, f)[i];
        }
        double res = sci_op_forward_residual(mask, x, y, yhat, rowbuf);
        result->iters_done = it;
        if ((rc = sci_tracer_record(&tr, it, x, res, NAN)) != 0)
            break;
    }
    if (rc != SCI_EDIVERGED) {
        result->frames = x;
        x = NULL;
    }
out:
    free(rowbuf);
    sci_cube_free(x);
    sci_cube_free(yhat);
    sci_cube_free(phi);
    return rc;
}

/* the second point's real and boolean show that every kind of value is named in the CSV as --set reads it */
static const char *const toy_mean_bench_quick[] = {"{\"iters\":1}", "{\"iters\":4, \"gain\":0.7, \"mean_start\":false}",
                                                   NULL};
static const char *const toy_mean_bench_full[] = {"{\"iters\":1}", "{\"iters\":4}", "{\"iters\":16}", NULL};

const solver_ops sci_toy_mean_solver = {
    .name = "toy-mean",
    .summary = "the snapshot over the masks' sum, then plain projections (a test build's extra method)",
    .caps = 0,
    .settings_size = sizeof(toy_mean_params),
    .fields = {{toy_mean_fields, sizeof toy_mean_fields / sizeof toy_mean_fields[0], 0}},
    .defaults = toy_mean_defaults,
    .preset = toy_mean_preset,
    .run = toy_mean_run,
    .bench_quick = toy_mean_bench_quick,
    .bench_full = toy_mean_bench_full,
};
