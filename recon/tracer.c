#include "recon/tracer.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "base/clock.h"
#include "recon/metrics.h"

void sci_tracer_start(sci_tracer *tr, const sci_problem *p, sci_result *r, sci_progress_fn fn, void *user,
                      int iters_total, int metrics_every, int ssim_every)
{
    *tr = (sci_tracer){.problem = p, .result = r, .fn = fn, .user = user, .iters_total = iters_total,
                       .metrics_every = metrics_every, .ssim_every = ssim_every, .first_residual = NAN};
    tr->t0_ns = sci_clock_mono_ns();
    tr->cpu0_ns = sci_clock_cpu_ns();
}

int sci_tracer_record(sci_tracer *tr, int iter, const sci_cube *x, double residual, double loss)
{
    return sci_tracer_record_ex(tr, iter, x, residual, loss, NAN, NAN);
}

int sci_tracer_record_ex(sci_tracer *tr, int iter, const sci_cube *x, double residual, double loss,
                         double meas_residual, double max_weight)
{
    int64_t now = sci_clock_mono_ns(), cpu = sci_clock_cpu_ns();
    sci_trace_entry e = {
        .iter = iter,
        .wall_s = (double)(now - tr->t0_ns - tr->skip_ns) * 1e-9,
        .cpu_s = (double)(cpu - tr->cpu0_ns - tr->skip_cpu_ns) * 1e-9,
        .residual = residual,
        .loss = loss,
        .psnr = NAN,
        .psnr_peak1 = NAN,
        .ssim = NAN,
        .meas_residual = meas_residual,
        .max_weight = max_weight,
    };
    const sci_problem *p = tr->problem;
    int last = iter >= tr->iters_total;
    if (p->truth && x && last && x->n == p->truth->n) {
        /* the last iteration's metrics per frame, kept in the result for result.json (one SSIM, not two) */
        double *pf = realloc(tr->result->final_metrics, 3 * (size_t)x->n * sizeof *pf);
        if (pf) {
            tr->result->final_metrics = pf;
            tr->result->final_n = x->n;
            tr->result->final_of = x->data;
            e.psnr = sci_psnr(x, p->truth, SCI_PEAK_FRAME_MAX, 0, pf);
            e.psnr_peak1 = sci_psnr(x, p->truth, SCI_PEAK_FIXED, p->peak, pf + x->n);
            e.ssim = sci_ssim(x, p->truth, p->peak, pf + 2 * x->n);
        }
    }
    if (p->truth && x && isnan(e.ssim)) {
        if (last || (tr->metrics_every > 0 && iter % tr->metrics_every == 0)) {
            e.psnr = sci_psnr(x, p->truth, SCI_PEAK_FRAME_MAX, 0, NULL);
            e.psnr_peak1 = sci_psnr(x, p->truth, SCI_PEAK_FIXED, p->peak, NULL);
        }
        if (last || (tr->ssim_every > 0 && iter % tr->ssim_every == 0))
            e.ssim = sci_ssim(x, p->truth, p->peak, NULL);
    }
    int rc = sci_trace_push(&tr->result->trace, &e) < 0 ? -ENOMEM : 0;
    tr->result->iters_done = iter;
    if (rc == 0 && tr->fn && tr->fn(&e, tr->user) != 0)
        rc = SCI_ECANCELED;
    if (rc == 0) {
        if (isnan(tr->first_residual))
            tr->first_residual = residual;
        double limit = SCI_TRACER_DIVERGE_FACTOR * fmax(1.0, tr->first_residual);
        if (!isfinite(residual) || (!isnan(loss) && !isfinite(loss)) || residual > limit)
            rc = sci_error_set(&tr->result->error, SCI_EDIVERGED,
                               "%s diverged at iteration %d: residual %g (limit %g)%s", tr->result->method, iter,
                               residual, limit, isfinite(loss) || isnan(loss) ? "" : ", loss not finite");
    }
    if (rc == SCI_ECANCELED)
        sci_error_set(&tr->result->error, rc, "%s canceled at iteration %d", tr->result->method, iter);
    if (rc != 0)
        tr->result->stopped = rc;
    tr->skip_ns += sci_clock_mono_ns() - now;
    tr->skip_cpu_ns += sci_clock_cpu_ns() - cpu;
    return rc;
}
