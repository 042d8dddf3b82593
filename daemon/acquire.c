/* daemon/acquire.c — the acquisition thread (see the header). */
#include "daemon/acquire.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "daemon/calibrate.h"
#include "daemon/capture.h"

struct scicapd_acquire {
    scicapd_rig *rig;
    pthread_t thread;
    int running;
};

static const scicapd_acquire_kind acquire_kinds[] = {
    [SCICAPD_JOB_CAPTURE] = {.run = scicapd_capture_run, .canceled_event = "capture.canceled"},
    [SCICAPD_JOB_CALIBRATE] = {.run = scicapd_calibrate_run, .canceled_event = "calibrate.canceled"},
};

const scicapd_acquire_kind *scicapd_acquire_kind_get(scicapd_job_kind k)
{
    if ((unsigned)k >= sizeof acquire_kinds / sizeof acquire_kinds[0] || !acquire_kinds[k].run)
        return NULL;
    return &acquire_kinds[k];
}

int scicapd_acquire_new(scicapd_acquire **out, const scicapd_config *cfg, const scicapd_acquire_env *env,
                        sci_error *err)
{
    scicapd_acquire *a = calloc(1, sizeof *a);
    if (!a)
        return sci_error_set(err, -ENOMEM, "acquire: out of memory");
    int rc = scicapd_rig_new(&a->rig, cfg, env, err);
    if (rc < 0) {
        free(a);
        return rc;
    }
    *out = a;
    return 0;
}

void scicapd_acquire_free(scicapd_acquire *a)
{
    if (!a)
        return;
    scicapd_rig_free(a->rig);
    free(a);
}

int scicapd_acquire_reconfigure(scicapd_acquire *a, const scicapd_config *cfg, sci_error *err)
{
    return scicapd_rig_reconfigure(a->rig, cfg, err);
}

int scicapd_acquire_fault(scicapd_acquire *a, const scicapd_simulate_args *f, sci_error *err)
{
    return scicapd_rig_fault(a->rig, f, err);
}

json_t *scicapd_acquire_devices_json(scicapd_acquire *a) { return scicapd_rig_devices_json(a->rig); }
int64_t scicapd_acquire_heartbeat_ns(scicapd_acquire *a) { return scicapd_rig_heartbeat_ns(a->rig); }
int scicapd_acquire_dmd_connected(scicapd_acquire *a) { return scicapd_rig_dmd_connected(a->rig); }

/* j ends canceled without running (canceled while queued, or the daemon stopping); data is the event's. */
static void cancel_queued(scicapd_rig *r, scicapd_job *j, const char *why, json_t *data)
{
    const scicapd_acquire_kind *k = scicapd_acquire_kind_get(j->kind);
    scicapd_job_set_state(scicapd_rig_env_get(r)->jobs, j, SCICAPD_JOB_CANCELED, why);
    scicapd_rig_post(r, j, k ? k->canceled_event : "job.canceled", data);
}

static void run_job(scicapd_rig *r, scicapd_job *j)
{
    const scicapd_acquire_kind *k = scicapd_acquire_kind_get(j->kind);
    if (atomic_load(&j->cancel)) {
        cancel_queued(r, j, "canceled before it started", json_pack("{s:i}", "acquired", 0));
    } else if (k) {
        k->run(r, j);
    } else {
        /* a programming error of the queue's producer: said, not run */
        scicapd_job_set_state(scicapd_rig_env_get(r)->jobs, j, SCICAPD_JOB_FAILED,
                              "not a job for the acquisition thread");
    }
}

static void *acquire_main(void *arg)
{
    scicapd_acquire *a = arg;
    scicapd_rig *r = a->rig;
    const scicapd_rig_env *env = scicapd_rig_env_get(r);
    while (!scicapd_rig_stopping(r)) {
        scicapd_rig_beat(r);
        scicapd_job *j = scicapd_queue_pop(env->in, 200000000);
        scicapd_rig_apply_faults(r);
        scicapd_rig_apply_config(r);
        scicapd_rig_idle(r);
        if (!j)
            continue;
        run_job(r, j);
        scicapd_job_unref(env->jobs, j);
    }
    /* jobs still queued: canceled, and said so */
    scicapd_job *j;
    while ((j = scicapd_queue_take(env->in))) {
        cancel_queued(r, j, "daemon stopping", json_pack("{s:s}", "reason", "daemon stopping"));
        scicapd_job_unref(env->jobs, j);
    }
    return NULL;
}

int scicapd_acquire_start(scicapd_acquire *a, sci_error *err)
{
    int rc = pthread_create(&a->thread, NULL, acquire_main, a);
    if (rc != 0)
        return sci_error_set(err, -rc, "acquire: cannot start the thread: %s", strerror(rc));
    a->running = 1;
    return 0;
}

void scicapd_acquire_stop(scicapd_acquire *a)
{
    if (!a || !a->running)
        return;
    scicapd_rig_stop_request(a->rig);
    pthread_join(a->thread, NULL);
    a->running = 0;
}
