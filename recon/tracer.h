/* recon/tracer.h — what every solver does after each iteration: time it, measure it against the truth when
 * there is one, watch for divergence, tell the progress callback, and let it cancel.
 *
 * Wall and CPU time exclude the tracer's own metric evaluation, so the trace shows what the *method* costs.
 * PSNR (both conventions) is evaluated every `metrics_every` iterations and SSIM every `ssim_every` (0: never),
 * and both always at the last iteration; other rows carry NaN for them.
 *
 * Divergence: a non-finite residual or loss, or a residual above SCI_TRACER_DIVERGE_FACTOR times the larger of
 * 1 and the first iteration's residual, stops the solver with SCI_EDIVERGED and a message naming the iteration.
 *
 *     sci_tracer tr;
 *     sci_tracer_start(&tr, problem, result, progress, user, iters, 1, 10);
 *     for (it = 1; it <= iters; it++) {
 *         ... one iteration ...
 *         if ((rc = sci_tracer_record(&tr, it, x, residual, NAN)) != 0) break;
 *     }
 */
#ifndef SCICAP_RECON_TRACER_H
#define SCICAP_RECON_TRACER_H

#include <stdint.h>

#include "recon/problem.h"

#define SCI_TRACER_DIVERGE_FACTOR 100.0

typedef struct sci_tracer {
    const sci_problem *problem; /* borrowed */
    sci_result *result;         /* borrowed; entries are appended to result->trace */
    sci_progress_fn fn;
    void *user;
    int iters_total, metrics_every, ssim_every;
    int64_t t0_ns, cpu0_ns, skip_ns, skip_cpu_ns; /* skip: time spent inside the tracer */
    double first_residual;
} sci_tracer;

void sci_tracer_start(sci_tracer *tr, const sci_problem *p, sci_result *r, sci_progress_fn fn, void *user,
                      int iters_total, int metrics_every, int ssim_every);
/* Record iteration `iter` of estimate x (w×h×N). Returns 0 to go on, SCI_ECANCELED if the callback asked to stop,
 * SCI_EDIVERGED (message in result->error), or -ENOMEM. */
int sci_tracer_record(sci_tracer *tr, int iter, const sci_cube *x, double residual, double loss);
/* The same with the NeRF diagnostics of a full render (sci_trace_entry.meas_residual, max_weight; NaN: none). */
int sci_tracer_record_ex(sci_tracer *tr, int iter, const sci_cube *x, double residual, double loss,
                         double meas_residual, double max_weight);

#endif
