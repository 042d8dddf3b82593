/* daemon/jobs.c — job objects and the job table (an array under one mutex; a few hundred entries at most). */
#include "daemon/jobs.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "daemon/import_args.h"

struct scicapd_jobs {
    pthread_mutex_t mu;
    scicapd_job **v;
    int len, cap;
    uint64_t next_id;
};

const char *scicapd_job_kind_name(scicapd_job_kind k)
{
    return k == SCICAPD_JOB_CAPTURE     ? "capture"
           : k == SCICAPD_JOB_CALIBRATE ? "calibrate"
           : k == SCICAPD_JOB_IMPORT    ? "import"
                                        : "reconstruct";
}

const char *scicapd_job_state_name(scicapd_job_state s)
{
    static const char *const n[] = {"queued", "running", "done", "failed", "canceled"};
    return (unsigned)s <= SCICAPD_JOB_CANCELED ? n[s] : "?";
}

int scicapd_jobs_new(scicapd_jobs **out)
{
    scicapd_jobs *t = calloc(1, sizeof *t);
    if (!t)
        return -ENOMEM;
    pthread_mutex_init(&t->mu, NULL);
    t->next_id = 1;
    *out = t;
    return 0;
}

static void job_free(scicapd_job *j)
{
    json_decref(j->request_id);
    json_decref(j->outputs);
    sci_problem_free(j->problem);
    scicapd_import_args_free(j->import);
    free(j);
}

void scicapd_jobs_free(scicapd_jobs *t)
{
    if (!t)
        return;
    for (int i = 0; i < t->len; i++)
        if (--t->v[i]->refs == 0)
            job_free(t->v[i]);
    free(t->v);
    pthread_mutex_destroy(&t->mu);
    free(t);
}

static int finished(const scicapd_job *j) { return j->state >= SCICAPD_JOB_DONE; }

/* Drop the oldest finished jobs beyond the history limit. Lock held. */
static void trim(scicapd_jobs *t)
{
    int nfin = 0;
    for (int i = 0; i < t->len; i++)
        nfin += finished(t->v[i]);
    int w = 0;
    for (int i = 0; i < t->len; i++) {
        scicapd_job *j = t->v[i];
        if (nfin > SCICAPD_JOBS_HISTORY && finished(j)) {
            nfin--;
            if (--j->refs == 0)
                job_free(j);
            continue;
        }
        t->v[w++] = j;
    }
    t->len = w;
}

int scicapd_jobs_create(scicapd_jobs *t, scicapd_job_kind kind, uint64_t client, uid_t owner,
                        const json_t *request_id, scicapd_job **out)
{
    scicapd_job *j = calloc(1, sizeof *j);
    if (!j)
        return -ENOMEM;
    j->kind = kind;
    j->client = client;
    j->owner = owner;
    j->request_id = request_id ? json_incref((json_t *)request_id) : json_null();
    j->outputs = json_array();
    j->psnr = NAN;
    j->submitted_ns = sci_clock_mono_ns();
    j->refs = 2;
    pthread_mutex_lock(&t->mu);
    if (t->len == t->cap) {
        int nc = t->cap ? t->cap * 2 : 64;
        scicapd_job **nv = realloc(t->v, (size_t)nc * sizeof *nv);
        if (!nv) {
            pthread_mutex_unlock(&t->mu);
            job_free(j);
            return -ENOMEM;
        }
        t->v = nv;
        t->cap = nc;
    }
    j->id = t->next_id++;
    t->v[t->len++] = j;
    pthread_mutex_unlock(&t->mu);
    *out = j;
    return 0;
}

scicapd_job *scicapd_jobs_find(scicapd_jobs *t, uint64_t id)
{
    scicapd_job *r = NULL;
    pthread_mutex_lock(&t->mu);
    for (int i = 0; i < t->len; i++)
        if (t->v[i]->id == id) {
            r = t->v[i];
            r->refs++;
        }
    pthread_mutex_unlock(&t->mu);
    return r;
}

void scicapd_job_unref(scicapd_jobs *t, scicapd_job *j)
{
    if (!j)
        return;
    pthread_mutex_lock(&t->mu);
    int last = --j->refs == 0;
    pthread_mutex_unlock(&t->mu);
    if (last)
        job_free(j);
}

void scicapd_jobs_forget(scicapd_jobs *t, scicapd_job *j)
{
    pthread_mutex_lock(&t->mu);
    for (int i = 0; i < t->len; i++)
        if (t->v[i] == j) {
            memmove(t->v + i, t->v + i + 1, (size_t)(t->len - i - 1) * sizeof *t->v);
            t->len--;
            j->refs--;
            break;
        }
    pthread_mutex_unlock(&t->mu);
}

void scicapd_job_set_state(scicapd_jobs *t, scicapd_job *j, scicapd_job_state s, const char *error)
{
    int64_t now = sci_clock_mono_ns();
    pthread_mutex_lock(&t->mu);
    j->state = s;
    if (s == SCICAPD_JOB_RUNNING)
        j->started_ns = now;
    if (s >= SCICAPD_JOB_DONE)
        j->finished_ns = now;
    if (error)
        snprintf(j->error, sizeof j->error, "%s", error);
    if (s >= SCICAPD_JOB_DONE)
        trim(t);
    pthread_mutex_unlock(&t->mu);
}

void scicapd_job_set_progress(scicapd_jobs *t, scicapd_job *j, int done, int total, double psnr)
{
    pthread_mutex_lock(&t->mu);
    j->done = done;
    j->total = total;
    if (!isnan(psnr))
        j->psnr = psnr;
    pthread_mutex_unlock(&t->mu);
}

int scicapd_job_settle(scicapd_jobs *t, scicapd_job *j, int stored)
{
    pthread_mutex_lock(&t->mu);
    int n = ++j->settled;
    if (stored)
        j->done++;
    pthread_mutex_unlock(&t->mu);
    return n;
}

void scicapd_job_add_output(scicapd_jobs *t, scicapd_job *j, const char *name)
{
    pthread_mutex_lock(&t->mu);
    json_array_append_new(j->outputs, json_string(name));
    pthread_mutex_unlock(&t->mu);
}

scicapd_job_state scicapd_job_state_get(scicapd_jobs *t, scicapd_job *j)
{
    pthread_mutex_lock(&t->mu);
    scicapd_job_state s = j->state;
    pthread_mutex_unlock(&t->mu);
    return s;
}

/* Lock held. */
static json_t *job_json(const scicapd_job *j)
{
    int64_t now = sci_clock_mono_ns();
    json_t *o = json_pack("{s:I, s:s, s:s, s:i, s:i, s:O, s:f, s:I}", "job", (json_int_t)j->id, "kind",
                          scicapd_job_kind_name(j->kind), "state", scicapd_job_state_name(j->state), "done", j->done,
                          "total", j->total, "outputs", j->outputs, "age_s",
                          (double)(now - j->submitted_ns) * 1e-9, "owner", (json_int_t)j->owner);
    if (!o)
        return NULL;
    if (!isnan(j->psnr))
        json_object_set_new(o, "psnr", json_real(j->psnr));
    if (j->error[0])
        json_object_set_new(o, "error", json_string(j->error));
    if (j->started_ns)
        json_object_set_new(o, "run_s", json_real((double)((j->finished_ns ? j->finished_ns : now) - j->started_ns) *
                                                  1e-9));
    if (j->kind == SCICAPD_JOB_RECONSTRUCT) {
        json_object_set_new(o, "capture", json_string(j->recon.capture_id));
        json_object_set_new(o, "method", json_string(j->recon.spec.method->name));
    } else if (j->kind == SCICAPD_JOB_CAPTURE) {
        json_object_set_new(o, "mask_set", json_string(j->capture.mask_set.name));
    } else {
        json_object_set_new(o, "calibration", json_string(j->calib.kind == SCICAPD_CALIB_DARK ? "dark" : "masks"));
    }
    return o;
}

json_t *scicapd_job_json(scicapd_jobs *t, scicapd_job *j)
{
    pthread_mutex_lock(&t->mu);
    json_t *o = job_json(j);
    pthread_mutex_unlock(&t->mu);
    return o;
}

json_t *scicapd_jobs_json(scicapd_jobs *t, uid_t owner, int all)
{
    json_t *a = json_array();
    pthread_mutex_lock(&t->mu);
    for (int i = 0; i < t->len; i++)
        if (all || t->v[i]->owner == owner)
            json_array_append_new(a, job_json(t->v[i]));
    pthread_mutex_unlock(&t->mu);
    return a;
}

int scicapd_jobs_client_busy(scicapd_jobs *t, uint64_t client)
{
    int busy = 0;
    pthread_mutex_lock(&t->mu);
    for (int i = 0; i < t->len && !busy; i++)
        busy = t->v[i]->client == client && !finished(t->v[i]);
    pthread_mutex_unlock(&t->mu);
    return busy;
}

void scicapd_jobs_count(scicapd_jobs *t, int *queued, int *running, int *fin)
{
    int q = 0, r = 0, f = 0;
    pthread_mutex_lock(&t->mu);
    for (int i = 0; i < t->len; i++) {
        scicapd_job_state s = t->v[i]->state;
        q += s == SCICAPD_JOB_QUEUED;
        r += s == SCICAPD_JOB_RUNNING;
        f += s >= SCICAPD_JOB_DONE;
    }
    pthread_mutex_unlock(&t->mu);
    *queued = q;
    *running = r;
    *fin = f;
}

void scicapd_jobs_cancel_all(scicapd_jobs *t)
{
    pthread_mutex_lock(&t->mu);
    for (int i = 0; i < t->len; i++)
        if (!finished(t->v[i])) {
            int none = 0;
            atomic_compare_exchange_strong(&t->v[i]->cancel, &none, SCICAPD_CANCEL_SHUTDOWN);
        }
    pthread_mutex_unlock(&t->mu);
}
