/* daemon/workers.c — reconstruction workers (see the header). */
#include "daemon/workers.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "base/clock.h"
#include "daemon/reconq.h"
#include "io/problem_dir.h"
#include "io/recon_store.h"
#include "recon/admmtv.h"
#include "recon/gaptv.h"

struct scicapd_workers {
    scicapd_workers_env env;
    int count, omp_threads;
    pthread_t *threads;
    int started;
    atomic_int stop, busy;
};

typedef struct run_ctx {
    scicapd_workers *w;
    scicapd_job *job;
    int iters;
    int64_t t0_ns, last_ns;
} run_ctx;

static void post(scicapd_workers *w, const scicapd_job *j, const char *name, json_t *data)
{
    scicapd_mailbox_post(w->env.mailbox, j->client, (long)j->owner, 1, scicapd_event(name, j->id, j->request_id, data));
}

static int on_progress(const sci_trace_entry *e, void *user)
{
    run_ctx *c = user;
    int64_t now = sci_clock_mono_ns();
    scicapd_job_set_progress(c->w->env.jobs, c->job, e->iter, c->iters, e->psnr);
    if (now - c->last_ns >= 100000000 || e->iter == c->iters) {
        c->last_ns = now;
        double el = (double)(now - c->t0_ns) * 1e-9;
        double eta = e->iter > 0 ? el / e->iter * (c->iters - e->iter) : NAN;
        json_t *d = json_pack("{s:i, s:i, s:f, s:f, s:f}", "iter", e->iter, "iters", c->iters, "residual",
                              isfinite(e->residual) ? e->residual : -1.0, "elapsed_s", el, "eta_s", eta);
        if (isfinite(e->psnr))
            json_object_set_new(d, "psnr", json_real(e->psnr));
        post(c->w, c->job, "recon.progress", d);
    }
    return atomic_load(&c->job->cancel) || atomic_load(&c->w->stop);
}

/* Stopped by the daemon's stop rather than by a user: the saved copy stays for the next start. */
static int stopped_by_daemon(scicapd_workers *w, scicapd_job *j)
{
    return atomic_load(&w->stop) || atomic_load(&j->cancel) == SCICAPD_CANCEL_SHUTDOWN;
}

static void run(scicapd_workers *w, scicapd_job *j)
{
    const scicapd_recon_args *ra = &j->recon;
    const char *method = scicapd_method_name(ra->spec.method);
    sci_error err = {0};
    char dir[1100], out[1300];
    sci_problem **pp = NULL;
    int k = 0, rc;
    sci_result r = {0};
    int64_t t0 = sci_clock_mono_ns();
    scicapd_job_set_state(w->env.jobs, j, SCICAPD_JOB_RUNNING, NULL);
    post(w, j, "recon.started", json_pack("{s:s, s:s}", "capture", ra->capture_id, "method", method));
    if ((rc = scicapd_store_capture_dir(w->env.store, ra->capture_id, dir, sizeof dir, &err)) < 0 ||
        (rc = sci_problem_dir_read(dir, &pp, &k, &err)) < 0)
        goto done;
    if (k < 1) {
        rc = sci_error_set(&err, SCI_EFORMAT, "%s: no snapshot", dir);
        goto done;
    }
    run_ctx ctx = {.w = w, .job = j, .t0_ns = sci_clock_mono_ns()};
    int64_t ts = sci_clock_mono_ns();
    if (ra->spec.method == SCICAPD_METHOD_ADMMTV) {
        ctx.iters = ra->spec.admm.iters;
        rc = sci_admmtv_solve(pp[0], &ra->spec.admm, &r, on_progress, &ctx);
    } else {
        ctx.iters = ra->spec.gap.iters;
        rc = sci_gaptv_solve(pp[0], &ra->spec.gap, &r, on_progress, &ctx);
    }
    double solve_s = sci_clock_s(ts, sci_clock_mono_ns());
    if (rc < 0) {
        if (rc == SCI_ECANCELED)
            sci_error_set(&err, rc, "canceled after %d iterations", r.iters_done);
        else
            sci_error_set(&err, rc, "%s", r.error.msg[0] ? r.error.msg : sci_strerror(rc));
        goto done;
    }
    snprintf(out, sizeof out, "%s/recon/%s", dir, method);
    char rdir[1200];
    snprintf(rdir, sizeof rdir, "%s/recon", dir);
    if (mkdir(rdir, 0750) != 0 && errno != EEXIST) {
        rc = sci_error_set(&err, -errno, "%s: cannot create: %s", rdir, strerror(errno));
        goto done;
    }
    json_t *params = scicapd_recon_spec_json(&ra->spec);
    rc = sci_recon_store_write(out, pp[0], &r, params, 1, &err);
    json_decref(params);
    if (rc < 0)
        goto done;
    const sci_trace_entry *last = r.trace.len ? &r.trace.e[r.trace.len - 1] : NULL;
    json_t *d = json_pack("{s:s, s:s, s:s, s:i, s:f, s:f}", "capture", ra->capture_id, "method", method, "dir", out,
                          "iters", r.iters_done, "solve_s", solve_s, "total_s", sci_clock_s(t0, sci_clock_mono_ns()));
    if (last && isfinite(last->psnr)) {
        json_object_set_new(d, "psnr", json_real(last->psnr));
        json_object_set_new(d, "psnr_peak1", json_real(last->psnr_peak1));
        if (isfinite(last->ssim))
            json_object_set_new(d, "ssim", json_real(last->ssim));
        scicapd_job_set_progress(w->env.jobs, j, r.iters_done, ctx.iters, last->psnr);
    }
    scicapd_job_add_output(w->env.jobs, j, out);
    scicapd_job_set_state(w->env.jobs, j, SCICAPD_JOB_DONE, NULL);
    sci_log_write(w->env.log, SCI_LOG_INFO, "job %llu: %s of %s done in %.2f s", (unsigned long long)j->id, method,
                  ra->capture_id, solve_s);
    post(w, j, "recon.done", d);
done:
    if (rc < 0) {
        int canceled = rc == SCI_ECANCELED;
        if (canceled && stopped_by_daemon(w, j))
            snprintf(err.msg, sizeof err.msg, "daemon stopping after %d iterations; resumed at the next start",
                     r.iters_done);
        scicapd_job_set_state(w->env.jobs, j, canceled ? SCICAPD_JOB_CANCELED : SCICAPD_JOB_FAILED, err.msg);
        post(w, j, canceled ? "recon.canceled" : "recon.failed",
             json_pack("{s:s, s:s, s:s}", "capture", ra->capture_id, "method", method, "error", err.msg));
    }
    if (rc >= 0 || !(rc == SCI_ECANCELED && stopped_by_daemon(w, j)))
        scicapd_reconq_drop(w->env.store, j);
    sci_result_free_contents(&r);
    sci_problem_array_free(pp, k);
}

static void *worker_main(void *arg)
{
    scicapd_workers *w = arg;
    if (w->omp_threads > 0)
        omp_set_num_threads(w->omp_threads);
    scicapd_job *j;
    while ((j = scicapd_queue_pop(w->env.in, -1))) {
        if (atomic_load(&w->stop) || atomic_load(&j->cancel)) {
            int later = stopped_by_daemon(w, j);
            scicapd_job_set_state(w->env.jobs, j, SCICAPD_JOB_CANCELED,
                                  later ? "daemon stopping; resumed at the next start" : "canceled");
            post(w, j, "recon.canceled", json_pack("{s:s, s:s}", "capture", j->recon.capture_id, "error",
                                                   later ? "daemon stopping; resumed at the next start" : "canceled"));
            if (!later)
                scicapd_reconq_drop(w->env.store, j);
        } else {
            atomic_fetch_add(&w->busy, 1);
            run(w, j);
            atomic_fetch_sub(&w->busy, 1);
        }
        scicapd_job_unref(w->env.jobs, j);
    }
    return NULL;
}

int scicapd_workers_start(scicapd_workers **out, const scicapd_workers_env *env, int count, int omp_threads,
                          sci_error *err)
{
    scicapd_workers *w = calloc(1, sizeof *w);
    if (!w || !(w->threads = calloc((size_t)count, sizeof *w->threads))) {
        free(w);
        return sci_error_set(err, -ENOMEM, "workers: out of memory");
    }
    w->env = *env;
    w->count = count;
    w->omp_threads = omp_threads;
    for (int i = 0; i < count; i++) {
        int rc = pthread_create(&w->threads[i], NULL, worker_main, w);
        if (rc != 0) {
            scicapd_queue_close(env->in);
            scicapd_workers_stop(w);
            return sci_error_set(err, -rc, "workers: cannot start thread %d: %s", i, strerror(rc));
        }
        w->started++;
    }
    *out = w;
    return 0;
}

void scicapd_workers_stop(scicapd_workers *w)
{
    if (!w)
        return;
    atomic_store(&w->stop, 1);
    for (int i = 0; i < w->started; i++)
        pthread_join(w->threads[i], NULL);
    free(w->threads);
    free(w);
}

int scicapd_workers_busy(scicapd_workers *w) { return w ? atomic_load(&w->busy) : 0; }
