/* daemon/workers.c — reconstruction workers (see the header). */
#include "daemon/workers.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <stddef.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <time.h>
#include <unistd.h>

#include "base/clock.h"
#include "daemon/import.h"
#include "daemon/reconout.h"
#include "daemon/reconq.h"
#include "daemon/reconsubmit.h"
#include "io/problem_dir.h"
#include "io/recon_store.h"
#include "io/staging.h"
#include "recon/solver.h"

#define SCICAPD_IMPORT_RECON_MAX 1000 /* reconstructions one import queues (a .mat may hold more snapshots) */

struct scicapd_workers {
    scicapd_workers_env env;
    scicapd_reconout *names;  /* output folder names reserved by workers publishing right now */
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

/* A method's checkpoint (SOLVER_CHECKPOINTS): kept beside the job's saved entry for a resume after a stop or a
 * crash. Not kept when a user canceled the job (its entry goes too); a failure to write costs the resume, not
 * the run. */
static int on_checkpoint(const void *blob, size_t bytes, int iter, void *user)
{
    run_ctx *c = user;
    if (atomic_load(&c->job->cancel) == SCICAPD_CANCEL_USER && !atomic_load(&c->w->stop))
        return 0;
    sci_error e = {0};
    if (scicapd_reconq_checkpoint_save(c->w->env.store, c->job, blob, bytes, &e) < 0) {
        sci_log_write(c->w->env.log, SCI_LOG_WARNING, "job %llu: %s", (unsigned long long)c->job->id, e.msg);
        return 0;
    }
    post(c->w, c->job, "recon.checkpoint", json_pack("{s:i, s:I}", "iter", iter, "bytes", (json_int_t)bytes));
    return 0;
}

/* Write the result to the capture's next free recon/<method>[.N] (its name into folder, the path into out): the
 * name reserved so that workers finishing together never pick the same one, the folder published without
 * replacing anything. *created is set when recon/ was made here, by this call or an earlier attempt of the same
 * job (one that found no room), so that its name is made durable once. */
static int publish(scicapd_workers *w, const scicapd_job *j, const char *dir, const sci_problem *p,
                   const sci_result *r, char *folder, size_t nf, char *out, size_t no, int *created,
                   sci_error *err)
{
    char rdir[1200];
    snprintf(rdir, sizeof rdir, "%s/recon", dir);
    const int made = mkdir(rdir, 0750) == 0;
    if (!made && errno != EEXIST)
        return sci_error_set(err, -errno, "%s: cannot create: %s", rdir, strerror(errno));
    *created |= made;
    int rc = scicapd_reconout_reserve(w->names, dir, j->recon.spec.method->name, folder, nf, err);
    if (rc < 0)
        return rc;
    snprintf(out, no, "%s/%s", rdir, folder);
    json_t *params = scicapd_recon_spec_json(&j->recon.spec);
    /* which queued job wrote it: a restart after a crash before the entry is dropped finds it done
     * (daemon/reconq.h) rather than running it again */
    /* and for whom: the uid that asked (SO_PEERCRED), so a result is attributed to its user whoever else reads it */
    json_t *job = json_pack("{s:{s:I, s:s, s:I}}", "job", "id", (json_int_t)j->id, "queue_entry", j->persisted,
                            "owner", (json_int_t)j->owner);
    /* storage.fsync promises that a reconstruction the queue forgets after this survives a power cut: its files
     * and the rename that published it reach the disk before the write returns, and a new recon/ folder's name
     * before the entry is dropped */
    const int durable = scicapd_store_fsync_on(w->env.store);
    rc = sci_recon_store_write_ex(out, p, r, params, job, durable ? SCI_STAGING_DURABLE : 0, NULL, err);
    json_decref(job);
    json_decref(params);
    scicapd_reconout_release(w->names, dir, folder);
    if (rc == 0 && durable && *created && (rc = sci_staging_sync(rdir, SCI_SYNC_PARENT)) < 0)
        sci_error_set(err, rc, "%s: cannot make the reconstruction durable: %s", out, sci_strerror(rc));
    return rc;
}

/* A publish that failed for lack of room (ENOSPC or EDQUOT from the write, or a library that dropped errno —
 * OpenEXR says only "File output failed" — while the store has less free than twice the frames as float32 and
 * 1 MiB): 1, with err saying so and naming the bytes free, so the user knows what to free. */
static int no_room(scicapd_workers *w, const sci_result *r, int rc, sci_error *err)
{
    if (rc == -EDQUOT || strstr(err->msg, strerror(EDQUOT)))
        return 1;
    struct statvfs v;
    const char *root = scicapd_store_root(w->env.store);
    if (statvfs(root, &v) != 0)
        return rc == -ENOSPC;
    double free_b = (double)v.f_bavail * (double)v.f_frsize;
    double need = r->frames ? (double)sci_cube_count(r->frames) * 8.0 : 0;
    if (rc != -ENOSPC && !strstr(err->msg, strerror(ENOSPC)) && free_b >= need + 1048576.0 && v.f_favail > 0)
        return 0;
    if (!strstr(err->msg, strerror(ENOSPC))) {
        char msg[sizeof err->msg];
        snprintf(msg, sizeof msg, "%s: %s", strerror(ENOSPC), err->msg);
        sci_error_set(err, -ENOSPC, "%s", msg);
    }
    size_t l = strlen(err->msg);
    snprintf(err->msg + l, sizeof err->msg - l, " (%.0f bytes free on %s)", free_b, root);
    return 1;
}

/* Wait before the attempt-th retry of a publish that found no room: 1 s, doubling up to
 * SCICAPD_ROOM_RETRY_MAX_S (a disk freed by a person is seen within a minute, and a full disk costs a stat and a
 * failed write per wait, not a busy loop). The job keeps its queue entry and its result in memory meanwhile;
 * "recon.waiting" says why and when. SCI_ECANCELED when the job is canceled or the daemon stops while waiting
 * (the entry is then dropped or kept as for any cancel), else 0. */
#define SCICAPD_ROOM_RETRY_MAX_S 60
static int wait_for_room(scicapd_workers *w, scicapd_job *j, int attempt, const sci_error *why)
{
    int wait_s = attempt < 6 ? 1 << attempt : SCICAPD_ROOM_RETRY_MAX_S;
    if (wait_s > SCICAPD_ROOM_RETRY_MAX_S)
        wait_s = SCICAPD_ROOM_RETRY_MAX_S;
    sci_log_write(w->env.log, SCI_LOG_WARNING, "job %llu: %s; kept in the queue, written again in %d s",
                  (unsigned long long)j->id, why->msg, wait_s);
    post(w, j, "recon.waiting", json_pack("{s:s, s:s, s:s, s:i, s:i}", "capture", j->recon.capture_id, "method",
                                          j->recon.spec.method->name, "error", why->msg, "attempt", attempt + 1,
                                          "retry_in_s", wait_s));
    for (int i = 0; i < wait_s * 10; i++) { /* 100 ms steps: a cancel or a stop is seen at once */
        if (atomic_load(&j->cancel) || atomic_load(&w->stop))
            return SCI_ECANCELED;
        struct timespec ts = {0, 100000000L};
        nanosleep(&ts, NULL);
    }
    return atomic_load(&j->cancel) || atomic_load(&w->stop) ? SCI_ECANCELED : 0;
}

/* A job's start: the newest checkpoint its earlier run left (a method with checkpoints and a resumed job) into
 * *resume (malloc'ed, the caller frees; NULL when none or unreadable: the run starts over), the job running and
 * "recon.started" posted. */
static void run_start(scicapd_workers *w, scicapd_job *j, int ckpt, void **resume, size_t *resume_bytes)
{
    const scicapd_recon_args *ra = &j->recon;
    const char *method = ra->spec.method->name;
    sci_error err = {0};
    if (ckpt && scicapd_reconq_checkpoint_load(w->env.store, j, resume, resume_bytes, &err) < 0)
        sci_log_write(w->env.log, SCI_LOG_WARNING, "job %llu: %s; starting over", (unsigned long long)j->id,
                      err.msg);
    if (*resume)
        sci_log_write(w->env.log, SCI_LOG_NOTICE, "job %llu: %s of %s goes on from its checkpoint (%zu bytes)",
                      (unsigned long long)j->id, method, ra->capture_id, *resume_bytes);
    scicapd_job_set_state(w->env.jobs, j, SCICAPD_JOB_RUNNING, NULL);
    json_t *started = json_pack("{s:s, s:s}", "capture", ra->capture_id, "method", method);
    if (*resume)
        json_object_set_new(started, "resume_bytes", json_integer((json_int_t)*resume_bytes));
    post(w, j, "recon.started", started);
}

/* The capture's folder into dir and its snapshots into *pp (*k of them; the caller frees both, also on error):
 * handed over by the writer that stored it (the same values, not read back) or read from the folder. */
static int run_read(scicapd_workers *w, scicapd_job *j, char *dir, size_t ndir, sci_problem ***pp, int *k,
                    sci_error *err)
{
    int rc;
    if ((rc = scicapd_store_capture_dir(w->env.store, j->recon.capture_id, dir, ndir, err)) < 0)
        return rc;
    if (j->problem) {
        if (!(*pp = malloc(sizeof **pp)))
            return sci_error_set(err, -ENOMEM, "out of memory");
        (*pp)[0] = j->problem;
        j->problem = NULL;
        *k = 1;
    } else if ((rc = sci_problem_dir_read(dir, pp, k, err)) < 0) {
        return rc;
    }
    if (*k < 1)
        return sci_error_set(err, SCI_EFORMAT, "%s: no snapshot", dir);
    return 0;
}

/* The daemon's metric cadence for a method that compares with a truth (methods without these knobs keep their
 * own trace). PSNR against the truth on every 10th iteration (and the last) rather than each: progress events go
 * out every 100 ms at most, and two PSNRs per iteration cost as much as half a fast GAP-TV iteration. SSIM (a
 * Gaussian-window pass over every frame, ~25 ms for 256×256×8: a third of a fast GAP-TV solve) only on the last
 * iteration: result.json has it per frame, and the default every 10th iteration tripled it. */
static void run_settings_metrics(const solver_ops *m, void *settings, int iters)
{
    if (m->caps & SOLVER_NEEDS_CAMERA)
        return;
    sci_error err = {0};
    json_t *every = json_pack("{s:i, s:i}", "metrics_every", iters >= 20 ? iters / 10 : 1, "ssim_every", 0);
    solver_settings_set(m, settings, "metrics_every", json_object_get(every, "metrics_every"), NULL,
                        "metrics_every", &err);
    solver_settings_set(m, settings, "ssim_every", json_object_get(every, "ssim_every"), NULL, "ssim_every", &err);
    json_decref(every);
}

/* The solve: the job's method on p into *r with progress events, the job's cancel flag and, for a method with
 * checkpoints (ckpt), its checkpoints kept and resume continued from. Sets ctx->iters and *solve_s (wall time);
 * returns solver_run's code, with the reason in err on failure (SCI_ECANCELED: canceled). */
static int run_solve(scicapd_workers *w, scicapd_job *j, run_ctx *ctx, const sci_problem *p, int ckpt,
                     const void *resume, size_t resume_bytes, sci_result *r, double *solve_s, sci_error *err)
{
    const solver_ops *m = j->recon.spec.method;
    int64_t ts = sci_clock_mono_ns();
    scicapd_span sp;
    scicapd_span_begin(&sp);
    _Alignas(max_align_t) unsigned char settings[SCICAPD_SETTINGS_MAX];
    memcpy(settings, j->recon.spec.settings, sizeof settings);
    ctx->iters = solver_settings_iters(m, settings);
    run_settings_metrics(m, settings, ctx->iters);
    /* the job's cancel flag reaches the solver itself: a method whose iterations take seconds (desci's block
     * matching) stops inside one instead of at the next progress call */
    solver_io io = {.progress = on_progress, .user = ctx, .cancel = &j->cancel};
    if (ckpt) {
        io.checkpoint_fn = on_checkpoint;
        io.checkpoint_user = ctx;
        io.checkpoint_every = w->env.checkpoint_every;
        io.resume = resume;
        io.resume_bytes = resume_bytes;
    }
    int rc = solver_run(m, p, settings, &io, r);
    /* a checkpoint that does not fit this run (damaged, another version, or the last step's, taken just before a
     * crash): the run starts over rather than fail */
    if (rc < 0 && rc != SCI_ECANCELED && resume) {
        sci_log_write(w->env.log, SCI_LOG_WARNING, "job %llu: checkpoint not used (%s); starting over",
                      (unsigned long long)j->id, r->error.msg);
        sci_result_free_contents(r);
        memset(r, 0, sizeof *r);
        io.resume = NULL;
        io.resume_bytes = 0;
        rc = solver_run(m, p, settings, &io, r);
    }
    *solve_s = sci_clock_s(ts, sci_clock_mono_ns());
    scicapd_timing_add(w->env.timing, SCICAPD_STAGE_RECON_SOLVE, &sp);
    if (rc == SCI_ECANCELED)
        sci_error_set(err, rc, "canceled after %d iterations", r->iters_done);
    else if (rc < 0)
        sci_error_set(err, rc, "%s", r->error.msg[0] ? r->error.msg : sci_strerror(rc));
    return rc;
}

/* The result written (publish: its folder name into folder, its path into out). No room: the result waits in
 * memory and its entry in the queue until there is (a full disk is a person's to fix, and the solve need not be
 * run again); any other write error, or a cancel while waiting, fails the job. */
static int run_write(scicapd_workers *w, scicapd_job *j, const char *dir, const sci_problem *p,
                     const sci_result *r, char *folder, size_t nf, char *out, size_t no, sci_error *err)
{
    scicapd_span sp;
    scicapd_span_begin(&sp);
    int rc, rdir_new = 0;
    for (int attempt = 0; (rc = publish(w, j, dir, p, r, folder, nf, out, no, &rdir_new, err)) < 0; attempt++) {
        if (!no_room(w, r, rc, err))
            return rc;
        if ((rc = wait_for_room(w, j, attempt, err)) < 0) {
            sci_error_set(err, rc, "canceled while waiting for room to write it");
            return rc;
        }
        memset(err, 0, sizeof *err);
    }
    scicapd_timing_add(w->env.timing, SCICAPD_STAGE_RECON_WRITE, &sp);
    return 0;
}

/* A written result: the job done, its queue entry dropped and "recon.done" posted with the result's figures. */
static void run_done(scicapd_workers *w, scicapd_job *j, const run_ctx *ctx, const sci_result *r, const char *out,
                     const char *folder, double solve_s, int64_t t0_ns)
{
    const scicapd_recon_args *ra = &j->recon;
    const char *method = ra->spec.method->name;
    const sci_trace_entry *last = r->trace.len ? &r->trace.e[r->trace.len - 1] : NULL;
    json_t *d = json_pack("{s:s, s:s, s:s, s:s, s:i, s:f, s:f}", "capture", ra->capture_id, "method", method, "dir",
                          out, "folder", folder, "iters", r->iters_done, "solve_s", solve_s, "total_s",
                          sci_clock_s(t0_ns, sci_clock_mono_ns()));
    json_t *budget = scicapd_recon_budget_json(&ra->spec);
    if (budget)
        json_object_set_new(d, "budget", budget);
    if (last && isfinite(last->residual))
        json_object_set_new(d, "residual", json_real(last->residual));
    if (last && isfinite(last->psnr)) {
        json_object_set_new(d, "psnr", json_real(last->psnr));
        json_object_set_new(d, "psnr_peak1", json_real(last->psnr_peak1));
        if (isfinite(last->ssim))
            json_object_set_new(d, "ssim", json_real(last->ssim));
        scicapd_job_set_progress(w->env.jobs, j, r->iters_done, ctx->iters, last->psnr);
    }
    json_object_set_new(d, "owner", json_integer((json_int_t)j->owner));
    scicapd_job_add_output(w->env.jobs, j, out);
    scicapd_job_set_state(w->env.jobs, j, SCICAPD_JOB_DONE, NULL);
    sci_log_write(w->env.log, SCI_LOG_INFO, "job %llu: %s of %s done in %.2f s", (unsigned long long)j->id, method,
                  ra->capture_id, solve_s);
    scicapd_reconq_drop(w->env.store, j); /* before the event: a client that sees it sees the queue without it */
    post(w, j, "recon.done", d);
}

/* A job that failed or was canceled (rc < 0): its queue entry dropped unless the daemon's stop interrupted it
 * (then kept for the next start), its state set and "recon.canceled" or "recon.failed" posted. */
static void run_fail(scicapd_workers *w, scicapd_job *j, int rc, const sci_result *r, sci_error *err)
{
    int canceled = rc == SCI_ECANCELED;
    if (canceled && stopped_by_daemon(w, j))
        snprintf(err->msg, sizeof err->msg, "daemon stopping after %d iterations; resumed at the next start",
                 r->iters_done);
    else
        scicapd_reconq_drop(w->env.store, j);
    scicapd_job_set_state(w->env.jobs, j, canceled ? SCICAPD_JOB_CANCELED : SCICAPD_JOB_FAILED, err->msg);
    post(w, j, canceled ? "recon.canceled" : "recon.failed",
         json_pack("{s:s, s:s, s:s}", "capture", j->recon.capture_id, "method", j->recon.spec.method->name, "error",
                   err->msg));
}

/* One reconstruction: start, read, solve, write, then done or failed. */
static void run(scicapd_workers *w, scicapd_job *j)
{
    sci_error err = {0};
    char dir[1100], out[1300], folder[96];
    sci_problem **pp = NULL;
    int k = 0, rc;
    sci_result r = {0};
    double solve_s = 0;
    int64_t t0 = sci_clock_mono_ns();
    /* a method with checkpoints continues from the newest one its job left (a resumed job) */
    const int ckpt = (j->recon.spec.method->caps & SOLVER_CHECKPOINTS) && j->persisted[0];
    void *resume = NULL;
    size_t resume_bytes = 0;
    run_start(w, j, ckpt, &resume, &resume_bytes);
    scicapd_span sp;
    scicapd_span_begin(&sp);
    if ((rc = run_read(w, j, dir, sizeof dir, &pp, &k, &err)) < 0)
        goto done;
    scicapd_timing_add(w->env.timing, SCICAPD_STAGE_RECON_READ, &sp);
    run_ctx ctx = {.w = w, .job = j, .t0_ns = sci_clock_mono_ns()};
    if ((rc = run_solve(w, j, &ctx, pp[0], ckpt, resume, resume_bytes, &r, &solve_s, &err)) < 0)
        goto done;
    if ((rc = run_write(w, j, dir, pp[0], &r, folder, sizeof folder, out, sizeof out, &err)) < 0)
        goto done;
    run_done(w, j, &ctx, &r, out, folder, solve_s, t0);
done:
    if (rc < 0)
        run_fail(w, j, rc, &r, &err);
    sci_result_free_contents(&r);
    sci_problem_array_free(pp, k);
    free(resume);
}

static void run_import(scicapd_workers *w, scicapd_job *j);

/* One job off the queue: run it, or, when it was canceled or the daemon stops before it started, say so. */
static void process(scicapd_workers *w, scicapd_job *j)
{
    if (atomic_load(&w->stop) || atomic_load(&j->cancel)) {
        int later = stopped_by_daemon(w, j) && j->kind == SCICAPD_JOB_RECONSTRUCT; /* imports are not persisted */
        const char *why = later ? "daemon stopping; resumed at the next start"
                          : atomic_load(&w->stop) ? "daemon stopping" : "canceled";
        scicapd_job_set_state(w->env.jobs, j, SCICAPD_JOB_CANCELED, why);
        if (j->kind == SCICAPD_JOB_IMPORT)
            post(w, j, "import.canceled", json_pack("{s:s}", "error", why));
        else
            post(w, j, "recon.canceled", json_pack("{s:s, s:s}", "capture", j->recon.capture_id, "error", why));
        if (!later)
            scicapd_reconq_drop(w->env.store, j);
        return;
    }
    atomic_fetch_add(&w->busy, 1);
    if (j->kind == SCICAPD_JOB_IMPORT)
        run_import(w, j);
    else
        run(w, j);
    atomic_fetch_sub(&w->busy, 1);
}

/* What scicapd_recon_submit needs of the workers (borrowed). */
static scicapd_recon_submit_env recon_env(scicapd_workers *w)
{
    return (scicapd_recon_submit_env){.jobs = w->env.jobs, .store = w->env.store, .mailbox = w->env.mailbox,
                                      .queue = w->env.in, .log = w->env.log};
}

/* An import's reconstructions made, persisted and announced (daemon/reconsubmit.h), each snapshot's or its
 * recon.rejected: up to SCICAPD_IMPORT_RECON_MAX, into r (the caller's references). Returns how many. */
static int import_prepare_recons(scicapd_workers *w, scicapd_job *j, json_t *ids, scicapd_job **r)
{
    const scicapd_import_args *a = j->import;
    scicapd_recon_submit_env env = recon_env(w);
    size_t i;
    json_t *v;
    int nr = 0;
    json_array_foreach(ids, i, v) {
        const char *why = NULL;
        sci_error e2 = {0};
        if (nr == SCICAPD_IMPORT_RECON_MAX) {
            why = "more snapshots than one import reconstructs; request the rest with reconstruct";
        } else {
            scicapd_recon_request q = {.client = j->client, .owner = j->owner, .request_id = j->request_id,
                                       .capture_id = json_string_value(v), .spec = a->recon,
                                       .origin = "import_job", .origin_job = j->id,
                                       .mode = SCICAPD_ENQUEUE_TRY};
            if (scicapd_recon_prepare(&env, &q, &r[nr], &why, &e2) == 0)
                nr++;
        }
        if (why)
            post(w, j, "recon.rejected", json_pack("{s:s, s:s}", "capture", json_string_value(v), "reason", why));
    }
    return nr;
}

/* A prepared reconstruction of an import into the queue, after import.done. Without waiting: this runs on a
 * worker, and a worker waiting for room only workers make could wait for ever. When the queue is full (or
 * closed) it runs here instead, as imports always did, so a full queue never loses an import's reconstruction;
 * a stopping daemon's then keeps its entry (process). Takes the reference. */
static void import_enqueue(scicapd_workers *w, scicapd_job *r)
{
    scicapd_recon_submit_env env = recon_env(w);
    sci_error err = {0};
    if (scicapd_recon_enqueue(&env, r, SCICAPD_ENQUEUE_TRY, NULL, &err) == 0)
        return;
    process(w, r);
    scicapd_job_unref(w->env.jobs, r);
}

/* An import (daemon/import.h): the passed files read, each snapshot stored as a capture, then, when asked, its
 * reconstructions queued like any other (each its own job, persisted first so that a stop resumes them).
 * Their recon.queued events come before import.done, as a capture's come before capture.done: a client that
 * waits knows what to wait for when the import's last word arrives. */
static void run_import(scicapd_workers *w, scicapd_job *j)
{
    scicapd_import_args *a = j->import;
    sci_error err = {0};
    sci_problem **pp = NULL;
    int k = 0, stored = 0;
    sci_mat_info info;
    scicapd_job_set_state(w->env.jobs, j, SCICAPD_JOB_RUNNING, NULL);
    post(w, j, "import.started", json_pack("{s:s, s:i}", "kind", a->folder ? "folder" : "mat", "files", a->nfiles));
    int rc = scicapd_import_read(w->env.store, j->id, a, &pp, &k, &info, &err);
    json_t *ids = json_array();
    for (int i = 0; rc == 0 && i < k; i++) {
        if (atomic_load(&j->cancel) || atomic_load(&w->stop)) {
            rc = sci_error_set(&err, SCI_ECANCELED, "canceled after %d of %d snapshots", i, k);
            break;
        }
        char id[32], dir[1100];
        sci_problem *p = pp[i];
        pp[i] = NULL;
        if ((rc = scicapd_import_store(w->env.store, a, &info, j->owner, j->id, i, p, id, dir, &err)) < 0)
            break;
        stored++;
        json_array_append_new(ids, json_string(id));
        scicapd_job_add_output(w->env.jobs, j, id);
        scicapd_job_set_progress(w->env.jobs, j, i + 1, k, NAN);
        post(w, j, "import.stored", json_pack("{s:s, s:s, s:i, s:i}", "capture", id, "dir", dir, "index", i, "count",
                                              k));
    }
    sci_problem_array_free(pp, k);
    if (rc < 0) {
        int canceled = rc == SCI_ECANCELED;
        scicapd_job_set_state(w->env.jobs, j, canceled ? SCICAPD_JOB_CANCELED : SCICAPD_JOB_FAILED, err.msg);
        post(w, j, canceled ? "import.canceled" : "import.failed",
             json_pack("{s:s, s:O}", "error", err.msg, "captures", ids));
        sci_log_write(w->env.log, SCI_LOG_WARNING, "job %llu: import: %s", (unsigned long long)j->id, err.msg);
        json_decref(ids);
        return;
    }
    scicapd_job *r[SCICAPD_IMPORT_RECON_MAX];
    int nr = a->reconstruct ? import_prepare_recons(w, j, ids, r) : 0;
    json_t *d = json_pack("{s:O, s:i}", "captures", ids, "snapshots", stored);
    if (!a->folder) {
        json_object_set_new(d, "white", json_real(info.white));
        json_object_set_new(d, "mask_variable", json_string(info.mask_var));
        if (info.how[0])
            json_object_set_new(d, "scale_auto", json_string(info.how));
    }
    scicapd_job_set_state(w->env.jobs, j, SCICAPD_JOB_DONE, NULL);
    sci_log_write(w->env.log, SCI_LOG_INFO, "job %llu: imported %d snapshots from %s (uid %d)",
                  (unsigned long long)j->id, stored, a->names[a->folder ? 0 : a->data_index], (int)j->owner);
    post(w, j, "import.done", d);
    json_decref(ids);
    for (int n = 0; n < nr; n++)
        import_enqueue(w, r[n]);
}

static void *worker_main(void *arg)
{
    scicapd_workers *w = arg;
    omp_set_num_threads(w->omp_threads);
    scicapd_job *j;
    while ((j = scicapd_queue_pop(w->env.in, -1))) {
        process(w, j);
        scicapd_job_unref(w->env.jobs, j);
    }
    return NULL;
}

int scicapd_workers_auto_threads(int count)
{
    cpu_set_t set;
    int cpus = sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set) : (int)sysconf(_SC_NPROCESSORS_ONLN);
    int t = count > 0 ? cpus / count : cpus;
    return t < 1 ? 1 : t;
}

int scicapd_workers_start(scicapd_workers **out, const scicapd_workers_env *env, int count, int omp_threads,
                          sci_error *err)
{
    scicapd_workers *w = calloc(1, sizeof *w);
    if (!w || !(w->threads = calloc((size_t)count, sizeof *w->threads))) {
        free(w);
        return sci_error_set(err, -ENOMEM, "workers: out of memory");
    }
    if (scicapd_reconout_new(&w->names) < 0) {
        free(w->threads);
        free(w);
        return sci_error_set(err, -ENOMEM, "workers: out of memory");
    }
    w->env = *env;
    w->count = count;
    w->omp_threads = omp_threads > 0 ? omp_threads : scicapd_workers_auto_threads(count);
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
    scicapd_reconout_free(w->names);
    free(w->threads);
    free(w);
}

int scicapd_workers_busy(scicapd_workers *w) { return w ? atomic_load(&w->busy) : 0; }
