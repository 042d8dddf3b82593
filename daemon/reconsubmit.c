/* daemon/reconsubmit.c — reconstructions into the queue (see the header). */
#include "daemon/reconsubmit.h"

#include <errno.h>
#include <stdio.h>

#include "daemon/reconq.h"

static void set_reason(const char **reason, const char *why)
{
    if (reason)
        *reason = why;
}

/* j never reached the queue: out of the table, and the caller's reference dropped. */
static void forget(const scicapd_recon_submit_env *env, scicapd_job *j)
{
    scicapd_jobs_forget(env->jobs, j);
    scicapd_job_unref(env->jobs, j);
}

json_t *scicapd_recon_queued_json(const scicapd_job *j)
{
    const scicapd_recon_spec *s = &j->recon.spec;
    json_t *o = json_pack("{s:I, s:s, s:s, s:s, s:s}", "job", (json_int_t)j->id, "state", "queued", "capture",
                          j->recon.capture_id, "method", s->method->name, "preset", s->preset);
    json_t *b = o ? scicapd_recon_budget_json(s) : NULL;
    if (b)
        json_object_set_new(o, "budget", b);
    return o;
}

int scicapd_recon_prepare(const scicapd_recon_submit_env *env, const scicapd_recon_request *req, scicapd_job **out,
                          const char **reason, sci_error *err)
{
    scicapd_job *j;
    set_reason(reason, NULL);
    if (scicapd_jobs_create(env->jobs, SCICAPD_JOB_RECONSTRUCT, req->client, req->owner, req->request_id, &j) < 0) {
        sci_problem_free(req->problem);
        set_reason(reason, "out of memory");
        return sci_error_set(err, -ENOMEM, "out of memory");
    }
    snprintf(j->recon.capture_id, sizeof j->recon.capture_id, "%s", req->capture_id);
    j->recon.spec = req->spec;
    j->problem = req->problem; /* the worker need not read back what was just written */
    int rc = scicapd_reconq_save(env->store, j, err);
    if (rc < 0) {
        sci_log_write(env->log, SCI_LOG_ERR, "job %llu: %s", (unsigned long long)j->id, err->msg);
        set_reason(reason, "cannot save the queue entry");
        scicapd_reconq_drop(env->store, j);
        forget(env, j);
        return rc;
    }
    /* announced before the hand-over: once queued, a worker may post recon.started (or be done with the job)
     * before this thread runs again */
    if (req->origin)
        scicapd_mailbox_post(env->mailbox, j->client, (long)j->owner, 1,
                             scicapd_event("recon.queued", j->id, j->request_id,
                                           json_pack("{s:s, s:s, s:I}", "capture", j->recon.capture_id, "method",
                                                     j->recon.spec.method->name, req->origin,
                                                     (json_int_t)req->origin_job)));
    *out = j;
    return 0;
}

int scicapd_recon_enqueue(const scicapd_recon_submit_env *env, scicapd_job *j, scicapd_enqueue_mode mode,
                          const char **reason, sci_error *err)
{
    set_reason(reason, NULL);
    int wait = mode == SCICAPD_ENQUEUE_WAIT;
    int rc = wait ? scicapd_queue_push_wait(env->queue, j) : scicapd_queue_push(env->queue, j);
    if (rc == 0)
        return 0;
    if (mode == SCICAPD_ENQUEUE_TRY)
        return sci_error_set(err, rc, rc == SCI_EBUSY ? "reconstruction queue full" : "the daemon is stopping");
    if (rc == -EPIPE && wait) {
        /* stopping: the saved entry stays and is resumed at the next start */
        set_reason(reason, "daemon stopping; resumed at the next start");
        sci_error_set(err, -EPIPE, "the daemon is stopping");
    } else {
        scicapd_reconq_drop(env->store, j);
        if (rc == SCI_EBUSY) {
            set_reason(reason, "reconstruction queue full");
            sci_error_set(err, rc, "reconstruction queue full (%d jobs); try again later",
                          scicapd_queue_capacity(env->queue));
        } else {
            set_reason(reason, "daemon stopping");
            sci_error_set(err, rc, "the daemon is stopping");
        }
    }
    forget(env, j);
    return rc;
}

int scicapd_recon_submit(const scicapd_recon_submit_env *env, const scicapd_recon_request *req, json_t **queued,
                         const char **reason, sci_error *err)
{
    scicapd_job *j;
    int rc = scicapd_recon_prepare(env, req, &j, reason, err);
    if (rc < 0)
        return rc;
    json_t *reply = queued ? scicapd_recon_queued_json(j) : NULL; /* before the queue: a worker may take j */
    if ((rc = scicapd_recon_enqueue(env, j, req->mode, reason, err)) < 0) {
        json_decref(reply);
        return rc;
    }
    if (queued)
        *queued = reply;
    return 0;
}
