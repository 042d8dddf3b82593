/* daemon/daemon.c — the scicapd object: construction in dependency order, the event loop, request dispatch,
 * and teardown in reverse order. */
#include "daemon/daemon.h"

#include <errno.h>
#include <grp.h>
#include <math.h>
#include <poll.h>
#include <pwd.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "base/clock.h"
#include "daemon/acquire.h"
#include "daemon/catalog.h"
#include "daemon/config.h"
#include "daemon/control.h"
#include "daemon/import.h"
#include "daemon/jobs.h"
#include "daemon/loop.h"
#include "daemon/mailbox.h"
#include "daemon/notify.h"
#include "daemon/protocol.h"
#include "daemon/queue.h"
#include "daemon/reconq.h"
#include "daemon/reconsubmit.h"
#include "daemon/store.h"
#include "daemon/timing.h"
#include "daemon/web.h"
#include "daemon/workers.h"

/* Snapshots waiting for a writer: enough to keep every writer busy while the acquisition thread runs ahead. */
#define STORE_QUEUE_MIN 8
/* A capture's reconstruction gets the snapshot's problem from memory up to this size (a 256×256×8 simulated
 * capture holds 4.5 MB); larger ones are read back from the folder, so a full queue never pins gigabytes. */
#define HANDOVER_MAX_BYTES (64LL << 20)

struct scicapd {
    const sci_log *log;
    scicapd_options opts;
    char opt_socket[1024], opt_storage[1024], opt_runtime[1024], opt_config[1024];
    scicapd_config *cfg;        /* in force; swapped by reload (event-loop thread only) */
    scicapd_notify notify;
    scicapd_store *store;
    scicapd_store_recovery recovered;
    int resumed;                /* reconstructions read back from ROOT/recon-queue at start */
    json_t *interrupted;        /* the capture a killed daemon left running (ROOT/capture.running), or NULL */
    scicapd_jobs *jobs;
    scicapd_mailbox *mailbox;
    scicapd_queue *acq_q, *store_q, *recon_q;
    scicapd_acquire *acq;
    scicapd_workers *workers;
    scicapd_timing *timing;     /* per-stage time counters, shown by status */
    scicapd_control *ctl;
    scicapd_web *web;           /* the web view, or NULL when web is off (the default) */
    int sfd, stopfd;
    scicapd_loop *loop;         /* the event loop while scicapd_run runs (daemon/loop.h), else NULL */
    sigset_t oldmask;
    int store_started;
    atomic_int stopping;
    atomic_long stored;
    int64_t started_ns, last_status_ns;
};

/* ---- configuration ---- */
static scicapd_control_limits control_limits(const scicapd_config *c)
{
    return (scicapd_control_limits){.max_clients = c->max_clients, .admin_slots = c->admin_slots,
                                    .max_line = c->max_line_bytes, .request_timeout_ms = c->request_timeout_ms,
                                    .idle_timeout_ms = c->idle_timeout_ms, .max_per_uid = c->max_per_uid,
                                    .stall_timeout_ms = c->stall_timeout_ms};
}


static int load_config(scicapd *d, scicapd_config **out, sci_error *err)
{
    scicapd_config *c;
    int rc = scicapd_config_load(&c, d->opts.config_path, err);
    if (rc < 0)
        return rc;
    if (d->opts.socket_path)
        snprintf(c->socket_path, sizeof c->socket_path, "%s", d->opts.socket_path);
    if (d->opts.storage_root)
        snprintf(c->storage_root, sizeof c->storage_root, "%s", d->opts.storage_root);
    if (d->opts.runtime_dir)
        snprintf(c->runtime_dir, sizeof c->runtime_dir, "%s", d->opts.runtime_dir);
    if (d->opts.fsync >= 0)
        c->fsync = d->opts.fsync;
    *out = c;
    return 0;
}

/* Reload: the new configuration replaces the old one only if it loaded cleanly. */
static int reload(scicapd *d, json_t **restart, sci_error *err)
{
    scicapd_notify_reloading(&d->notify);
    scicapd_config *c;
    int rc = load_config(d, &c, err);
    if (rc < 0) {
        sci_log_write(d->log, SCI_LOG_ERR, "reload refused, the running configuration stays: %s", err->msg);
        scicapd_notify_ready(&d->notify, "reload refused; running on the previous configuration");
        return rc;
    }
    json_t *keys = scicapd_config_restart_keys(d->cfg, c);
    scicapd_config_free(d->cfg);
    d->cfg = c;
    scicapd_control_limits lim = control_limits(c);
    scicapd_control_set_limits(d->ctl, &lim);
    scicapd_queue_resize(d->acq_q, c->capture_queue);
    scicapd_queue_resize(d->recon_q, c->recon_queue);
    scicapd_store_set_previews(d->store, c->previews);
    sci_error e2 = {0};
    if (scicapd_acquire_reconfigure(d->acq, c, &e2) < 0)
        sci_log_write(d->log, SCI_LOG_ERR, "reload: devices keep their settings: %s", e2.msg);
    sci_log_write(d->log, SCI_LOG_NOTICE, "configuration reloaded from %s%s", c->path[0] ? c->path : "(defaults)",
                  json_array_size(keys) ? " (some changes need a restart)" : "");
    scicapd_notify_ready(&d->notify, "configuration reloaded");
    if (restart)
        *restart = keys;
    else
        json_decref(keys);
    return 0;
}

/* What scicapd_recon_submit needs of the daemon (borrowed). */
static scicapd_recon_submit_env recon_env(scicapd *d)
{
    return (scicapd_recon_submit_env){.jobs = d->jobs, .store = d->store, .mailbox = d->mailbox,
                                      .queue = d->recon_q, .log = d->log};
}

/* ---- from the writer thread ---- */

static long long problem_bytes(const sci_problem *p)
{
    long long n = 0;
    const sci_cube *c[] = {p->meas, p->mask, p->truth};
    for (int i = 0; i < 3; i++)
        if (c[i])
            n += (long long)sci_cube_count(c[i]) * (long long)sizeof(float);
    return n;
}

static void on_stored(void *user, scicapd_snapshot *s, int rc, const sci_error *err)
{
    scicapd *d = user;
    scicapd_job *j = s->job;
    if (!j) {
        scicapd_snapshot_free(d->jobs, s);
        return;
    }
    const scicapd_capture_args *c = &j->capture;
    if (rc < 0) {
        int none = 0; /* stop acquiring: the next snapshots would fail the same way */
        atomic_compare_exchange_strong(&j->cancel, &none, SCICAPD_CANCEL_STORAGE);
        sci_log_write(d->log, SCI_LOG_ERR, "job %llu: storing snapshot %d failed: %s", (unsigned long long)j->id,
                      s->index, err->msg);
        scicapd_job_settle(d->jobs, j, 0);
        if (scicapd_job_state_get(d->jobs, j) == SCICAPD_JOB_RUNNING)
            scicapd_job_set_state(d->jobs, j, SCICAPD_JOB_FAILED, err->msg);
        scicapd_mailbox_post(d->mailbox, j->client, (long)j->owner, 1,
                             scicapd_event("capture.failed", j->id, j->request_id,
                                           json_pack("{s:i, s:s}", "index", s->index, "error", err->msg)));
        scicapd_snapshot_free(d->jobs, s);
        return;
    }
    atomic_fetch_add(&d->stored, 1);
    scicapd_job_add_output(d->jobs, j, s->capture_id);
    double latency_ms = (double)(sci_clock_mono_ns() - j->submitted_ns) * 1e-6;
    scicapd_mailbox_post(d->mailbox, j->client, (long)j->owner, 1,
                         scicapd_event("capture.stored", j->id, j->request_id,
                                       json_pack("{s:s, s:s, s:i, s:b, s:f}", "capture", s->capture_id, "dir", s->dir,
                                                 "index", s->index, "broken", s->broken, "latency_ms", latency_ms)));
    if (c->reconstruct) {
        scicapd_recon_request q = {.client = j->client, .owner = j->owner, .request_id = j->request_id,
                                   .capture_id = s->capture_id, .spec = c->recon, .origin = "capture_job",
                                   .origin_job = j->id, .mode = SCICAPD_ENQUEUE_WAIT};
        if (problem_bytes(s->problem) <= HANDOVER_MAX_BYTES) {
            q.problem = s->problem; /* the worker need not read back what was just written */
            s->problem = NULL;
        }
        /* back-pressure: a full queue holds this writer, the store queue then the acquisition, so a capture runs
         * at the pace its reconstructions keep up with instead of refusing them */
        const char *why = NULL;
        sci_error e2 = {0};
        scicapd_recon_submit_env env = recon_env(d);
        if (scicapd_recon_submit(&env, &q, NULL, &why, &e2) < 0)
            scicapd_mailbox_post(d->mailbox, j->client, (long)j->owner, 1,
                                 scicapd_event("recon.rejected", j->id, j->request_id,
                                               json_pack("{s:s, s:s}", "capture", s->capture_id, "reason",
                                                         why ? why : e2.msg)));
    }
    /* after the events of this snapshot: capture.done is the job's last word */
    if (scicapd_job_settle(d->jobs, j, 1) == c->count && scicapd_job_state_get(d->jobs, j) == SCICAPD_JOB_RUNNING) {
        scicapd_job_set_state(d->jobs, j, SCICAPD_JOB_DONE, NULL);
        json_t *o = scicapd_job_json(d->jobs, j);
        scicapd_mailbox_post(d->mailbox, j->client, (long)j->owner, 1,
                             scicapd_event("capture.done", j->id, j->request_id, o));
    }
    scicapd_snapshot_free(d->jobs, s);
}

/* The capture a daemon killed during it left in ROOT/capture.running (daemon/capture.c): logged, reported by
 * status as recovered.capture_interrupted, and the mark removed. Its snapshots stored before the kill stay. */
static json_t *interrupted_capture(const char *root, const sci_log *log)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/capture.running", root);
    json_t *m = json_load_file(path, 0, NULL);
    if (!m && access(path, F_OK) != 0)
        return NULL;
    if (!m)
        m = json_pack("{s:s}", "error", "capture.running unreadable");
    sci_log_write(log, SCI_LOG_WARNING, "capture job %lld (uid %lld, %lld snapshots asked) was interrupted when the "
                  "daemon last stopped: not resumed; the snapshots stored before stay",
                  (long long)json_integer_value(json_object_get(m, "job")),
                  (long long)json_integer_value(json_object_get(m, "owner")),
                  (long long)json_integer_value(json_object_get(m, "count")));
    unlink(path);
    return m;
}

/* ---- requests ---- */

/* Root, the daemon's own user, or a member of control.admin_group (primary or supplementary). */
static int is_admin_cred(const scicapd *d, uid_t uid, gid_t gid)
{
    if (uid == 0 || uid == geteuid())
        return 1;
    const char *gname = d->cfg->admin_group;
    struct group *g = gname[0] ? getgrnam(gname) : NULL;
    if (!g)
        return 0;
    if (gid == g->gr_gid)
        return 1;
    struct passwd *pw = getpwuid(uid);
    if (!pw)
        return 0;
    gid_t groups[256];
    int n = 256;
    if (getgrouplist(pw->pw_name, pw->pw_gid, groups, &n) < 0)
        return 0;
    for (int i = 0; i < n; i++)
        if (groups[i] == g->gr_gid)
            return 1;
    return 0;
}

static int is_admin(const scicapd *d, const scicapd_client *c) { return is_admin_cred(d, c->uid, c->gid); }

/* control hooks */
static int hook_is_admin(void *user, uid_t uid, gid_t gid) { return is_admin_cred(user, uid, gid); }
static int hook_busy(void *user, const scicapd_client *c)
{
    return scicapd_jobs_client_busy(((scicapd *)user)->jobs, c->id);
}

static void reply(scicapd *d, scicapd_client *c, char *line)
{
    scicapd_control_send_to(d->ctl, c, line);
    free(line);
}

static void reply_err(scicapd *d, scicapd_client *c, const json_t *id, scicapd_errcode code, const char *msg)
{
    reply(d, c, scicapd_reply_error(id, code, msg));
}

static json_t *status_json(scicapd *d)
{
    int q, r, f;
    scicapd_jobs_count(d->jobs, &q, &r, &f);
    return json_pack("{s:s, s:i, s:i, s:f, s:s, s:s, s:s, s:b, s:{s:[i,i], s:[i,i], s:[i,i]}, s:{s:i, s:i, s:i},"
                     " s:i, s:i, s:i, s:I, s:{s:i, s:i, s:i, s:o}, s:b, s:o, s:o}",
                     "version", SCICAP_VERSION, "protocol", SCICAPD_PROTOCOL_VERSION, "pid", (int)getpid(),
                     "uptime_s", sci_clock_s(d->started_ns, sci_clock_mono_ns()), "config",
                     d->cfg->path[0] ? d->cfg->path : "(built-in defaults)", "socket", d->cfg->socket_path,
                     "storage", scicapd_store_root(d->store), "dmd_connected", scicapd_acquire_dmd_connected(d->acq),
                     "queues", "capture", scicapd_queue_len(d->acq_q), scicapd_queue_capacity(d->acq_q),
                     "reconstruction", scicapd_queue_len(d->recon_q), scicapd_queue_capacity(d->recon_q), "storage",
                     scicapd_queue_len(d->store_q), scicapd_queue_capacity(d->store_q), "jobs", "queued", q,
                     "running", r, "finished", f, "workers_busy", scicapd_workers_busy(d->workers), "clients",
                     scicapd_control_clients(d->ctl), "watchers", scicapd_control_watchers(d->ctl),
                     "captures_stored", (json_int_t)atomic_load(&d->stored),
                     "recovered", "captures", d->recovered.captures, "removed_partial", d->recovered.removed,
                     "reconstructions_resumed", d->resumed, "capture_interrupted",
                     d->interrupted ? json_incref(d->interrupted) : json_null(),
                     "stopping", atomic_load(&d->stopping), "devices", scicapd_acquire_devices_json(d->acq),
                     "timing", scicapd_timing_json(d->timing));
}

/* A capture, calibrate or import job into queue q (reconstructions: scicapd_recon_submit), answered {job, state}
 * or why not. */
static void submit(scicapd *d, scicapd_client *c, const json_t *id, scicapd_job *j, scicapd_queue *q,
                   const char *what)
{
    int rc = scicapd_queue_push(q, j);
    if (rc < 0) {
        char msg[128];
        snprintf(msg, sizeof msg, "%s queue full (%d jobs); try again later", what, scicapd_queue_capacity(q));
        scicapd_jobs_forget(d->jobs, j);
        scicapd_job_unref(d->jobs, j);
        reply_err(d, c, id, rc == SCI_EBUSY ? SCICAPD_E_BUSY : SCICAPD_E_SHUTTING_DOWN,
                  rc == SCI_EBUSY ? msg : "the daemon is stopping");
        return;
    }
    reply(d, c, scicapd_reply_ok(id, json_pack("{s:I, s:s}", "job", (json_int_t)j->id, "state", "queued")));
}

/* ---- request dispatch (checks 5-6, then one handler per command) ---- */

/* Check 5's results: the typed arguments of whichever command the request names. */
typedef struct request_args {
    scicapd_capture_args cap;
    scicapd_calib_args cal;
    scicapd_recon_args rec;
    scicapd_simulate_args sim;
    scicapd_import_args *imp; /* owned here until an import job takes it; NULL otherwise */
    uint64_t job_id;
    long limit;
} request_args;

/* Answers one checked request on the event-loop thread: a reply or an error, always with r->id. */
typedef void (*request_handler)(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a);

/* Check 5: the command's arguments into a, or < 0 with the reason in err. Import takes the descriptors the
 * client passed with the line. */
static int request_args_parse(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a,
                              sci_error *err)
{
    switch (r->cmd) {
    case SCICAPD_CMD_CAPTURE: return scicapd_args_capture(r, d->cfg, &a->cap, err);
    case SCICAPD_CMD_CALIBRATE: return scicapd_args_calibrate(r, d->cfg, &a->cal, err);
    case SCICAPD_CMD_RECONSTRUCT: return scicapd_args_reconstruct(r, d->cfg, &a->rec, err);
    case SCICAPD_CMD_CANCEL: return scicapd_args_cancel(r, &a->job_id, err);
    case SCICAPD_CMD_SIMULATE: return scicapd_args_simulate(r, &a->sim, err);
    case SCICAPD_CMD_CAPTURES: return scicapd_args_captures(r, &a->limit, err);
    case SCICAPD_CMD_IMPORT: {
        int fds[SCICAPD_CLIENT_MAX_FDS];
        int n = scicapd_client_take_fds(c, fds, SCICAPD_CLIENT_MAX_FDS);
        return scicapd_args_import(r, d->cfg, fds, n, &a->imp, err);
    }
    default: return scicapd_args_none(r, err);
    }
}

/* Check 6 (permission), then whether a stopping daemon still takes the command: 1 if it may run, else 0 with
 * the client answered. */
static int request_allowed(scicapd *d, scicapd_client *c, const scicapd_request *r, const request_args *a)
{
    if (scicapd_cmd_is_admin(r->cmd) && !is_admin(d, c)) {
        char msg[200];
        snprintf(msg, sizeof msg, "\"%s\" needs root, the daemon's user or group \"%s\" (peer uid %d)",
                 scicapd_cmd_name(r->cmd), d->cfg->admin_group, (int)c->uid);
        sci_log_write(d->log, SCI_LOG_WARNING, "client %llu: %s", (unsigned long long)c->id, msg);
        reply_err(d, c, r->id, SCICAPD_E_PERMISSION, msg);
        return 0;
    }
    if (a->imp && a->imp->allow_large && !is_admin(d, c)) { /* the limits protect the disk everyone shares */
        char msg[200];
        snprintf(msg, sizeof msg, "allow_large needs root, the daemon's user or group \"%s\" (peer uid %d)",
                 d->cfg->admin_group, (int)c->uid);
        reply_err(d, c, r->id, SCICAPD_E_PERMISSION, msg);
        return 0;
    }
    if (atomic_load(&d->stopping) && r->cmd != SCICAPD_CMD_STATUS && r->cmd != SCICAPD_CMD_JOBS) {
        reply_err(d, c, r->id, SCICAPD_E_SHUTTING_DOWN, "the daemon is stopping");
        return 0;
    }
    return 1;
}

static void handle_status(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    reply(d, c, scicapd_reply_ok(r->id, status_json(d)));
}

static void handle_devices(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    reply(d, c, scicapd_reply_ok(r->id, scicapd_acquire_devices_json(d->acq)));
}

/* A user sees their own jobs; admins see everyone's. */
static void handle_jobs(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    reply(d, c, scicapd_reply_ok(r->id, json_pack("{s:o}", "jobs",
                                                  scicapd_jobs_json(d->jobs, c->uid, is_admin(d, c)))));
}

/* Every user sees the stored captures: any of them may be reconstructed. */
static void handle_captures(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    sci_error err = {0};
    json_t *list = scicapd_catalog_list(scicapd_store_root(d->store), a->limit, &err);
    if (list)
        reply(d, c, scicapd_reply_ok(r->id, list));
    else
        reply_err(d, c, r->id, SCICAPD_E_FAILED, err.msg);
}

static void handle_watch(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    c->watching = 1;
    reply(d, c, scicapd_reply_ok(r->id, json_pack("{s:b}", "watching", 1)));
}

/* Capture and calibrate: a job on the acquisition queue. */
static void handle_acquire(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    scicapd_job *j = NULL;
    if (scicapd_jobs_create(d->jobs, r->cmd == SCICAPD_CMD_CAPTURE ? SCICAPD_JOB_CAPTURE : SCICAPD_JOB_CALIBRATE,
                            c->id, c->uid, r->id, &j) < 0) {
        reply_err(d, c, r->id, SCICAPD_E_FAILED, "out of memory");
        return;
    }
    j->capture = a->cap;
    j->calib = a->cal;
    submit(d, c, r->id, j, d->acq_q, "capture");
}

/* Read, stored and reconstructed on a worker: the loop never waits for files. */
static void handle_import(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    scicapd_job *j = NULL;
    if (scicapd_jobs_create(d->jobs, SCICAPD_JOB_IMPORT, c->id, c->uid, r->id, &j) < 0) {
        reply_err(d, c, r->id, SCICAPD_E_FAILED, "out of memory");
        return;
    }
    j->import = a->imp;
    a->imp = NULL;
    submit(d, c, r->id, j, d->recon_q, "reconstruction");
}

static void handle_reconstruct(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    sci_error err = {0};
    char dir[1100];
    if (scicapd_store_capture_dir(d->store, a->rec.capture_id, dir, sizeof dir, &err) < 0) {
        reply_err(d, c, r->id, SCICAPD_E_NOT_FOUND, err.msg);
        return;
    }
    scicapd_recon_request q = {.client = c->id, .owner = c->uid, .request_id = r->id,
                               .capture_id = a->rec.capture_id, .spec = a->rec.spec,
                               .mode = SCICAPD_ENQUEUE_REFUSE};
    scicapd_recon_submit_env env = recon_env(d);
    json_t *queued = NULL;
    int rc = scicapd_recon_submit(&env, &q, &queued, NULL, &err);
    if (rc < 0)
        reply_err(d, c, r->id, rc == SCI_EBUSY ? SCICAPD_E_BUSY : rc == -EPIPE ? SCICAPD_E_SHUTTING_DOWN
                                                                                : SCICAPD_E_FAILED, err.msg);
    else
        reply(d, c, scicapd_reply_ok(r->id, queued));
}

static void handle_cancel(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    scicapd_job *t = scicapd_jobs_find(d->jobs, a->job_id);
    if (!t) {
        char msg[64];
        snprintf(msg, sizeof msg, "no job %llu", (unsigned long long)a->job_id);
        reply_err(d, c, r->id, SCICAPD_E_NOT_FOUND, msg);
        return;
    }
    if (t->owner != c->uid && !is_admin(d, c)) {
        char msg[160];
        snprintf(msg, sizeof msg, "job %llu belongs to uid %d; only its owner, root or group \"%s\" may cancel it",
                 (unsigned long long)a->job_id, (int)t->owner, d->cfg->admin_group);
        sci_log_write(d->log, SCI_LOG_WARNING, "client %llu (uid %d): %s", (unsigned long long)c->id, (int)c->uid,
                      msg);
        reply_err(d, c, r->id, SCICAPD_E_PERMISSION, msg);
        scicapd_job_unref(d->jobs, t);
        return;
    }
    int none = 0; /* a shutdown's mark, if already set, stays */
    atomic_compare_exchange_strong(&t->cancel, &none, SCICAPD_CANCEL_USER);
    reply(d, c, scicapd_reply_ok(r->id, json_pack("{s:I, s:s}", "job", (json_int_t)t->id, "state",
                                                  scicapd_job_state_name(scicapd_job_state_get(d->jobs, t)))));
    scicapd_job_unref(d->jobs, t);
}

static void handle_reload(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    sci_error err = {0};
    json_t *restart = NULL;
    if (reload(d, &restart, &err) < 0)
        reply_err(d, c, r->id, SCICAPD_E_FAILED, err.msg);
    else
        reply(d, c, scicapd_reply_ok(r->id, json_pack("{s:s, s:o}", "config", d->cfg->path[0] ? d->cfg->path : "",
                                                      "restart_needed", restart)));
}

static void handle_shutdown(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    sci_log_write(d->log, SCI_LOG_NOTICE, "shutdown requested by client %llu (pid %d uid %d)",
                  (unsigned long long)c->id, (int)c->pid, (int)c->uid);
    reply(d, c, scicapd_reply_ok(r->id, NULL));
    scicapd_request_stop(d);
}

static void handle_simulate(scicapd *d, scicapd_client *c, const scicapd_request *r, request_args *a)
{
    sci_error err = {0};
    if (scicapd_acquire_fault(d->acq, &a->sim, &err) < 0)
        reply_err(d, c, r->id, err.code == -ENOTSUP ? SCICAPD_E_UNSUPPORTED : SCICAPD_E_BUSY, err.msg);
    else
        reply(d, c, scicapd_reply_ok(r->id, NULL));
}

/* Every command's handler, by command (daemon/protocol.h). */
static const request_handler request_handlers[SCICAPD_CMD_COUNT] = {
    [SCICAPD_CMD_STATUS] = handle_status,
    [SCICAPD_CMD_DEVICES] = handle_devices,
    [SCICAPD_CMD_CAPTURE] = handle_acquire,
    [SCICAPD_CMD_CALIBRATE] = handle_acquire,
    [SCICAPD_CMD_RECONSTRUCT] = handle_reconstruct,
    [SCICAPD_CMD_JOBS] = handle_jobs,
    [SCICAPD_CMD_CANCEL] = handle_cancel,
    [SCICAPD_CMD_WATCH] = handle_watch,
    [SCICAPD_CMD_RELOAD] = handle_reload,
    [SCICAPD_CMD_SHUTDOWN] = handle_shutdown,
    [SCICAPD_CMD_SIMULATE] = handle_simulate,
    [SCICAPD_CMD_IMPORT] = handle_import,
    [SCICAPD_CMD_CAPTURES] = handle_captures,
};

static void on_line(void *user, scicapd_client *c, const char *line, size_t len)
{
    scicapd *d = user;
    scicapd_request r;
    sci_error err = {0};
    /* checks 2-4: JSON, version, command */
    scicapd_errcode ec = scicapd_request_parse(line, len, &r, &err);
    if (ec != SCICAPD_OK) {
        reply_err(d, c, r.id, ec, err.msg);
        scicapd_request_clear(&r);
        return;
    }
    request_args a = {0};
    if (request_args_parse(d, c, &r, &a, &err) < 0) /* check 5 */
        reply_err(d, c, r.id, SCICAPD_E_BAD_ARGUMENTS, err.msg);
    else if (request_allowed(d, c, &r, &a) && (unsigned)r.cmd < SCICAPD_CMD_COUNT && request_handlers[r.cmd])
        request_handlers[r.cmd](d, c, &r, &a);
    scicapd_import_args_free(a.imp);
    scicapd_request_clear(&r);
}

/* ---- life ---- */

/* Reconstructions the previous run had queued or running (ROOT/recon-queue): queued again in their order, with
 * their owners, before any client can add to the queue. The queue grows for them if needed (a smaller
 * configured capacity refuses new requests until it drains, never these). */
static int resume_reconstructions(scicapd *d, sci_error *err)
{
    scicapd_reconq_item *it;
    int n, rc;
    if ((rc = scicapd_reconq_load(d->store, d->log, &it, &n, err)) < 0)
        return rc;
    if (n > scicapd_queue_capacity(d->recon_q))
        scicapd_queue_resize(d->recon_q, n);
    for (int i = 0; i < n; i++) {
        scicapd_job *j;
        if ((rc = scicapd_jobs_create(d->jobs, SCICAPD_JOB_RECONSTRUCT, 0, it[i].owner, NULL, &j)) < 0) {
            free(it);
            return sci_error_set(err, rc, "resuming reconstructions: out of memory");
        }
        snprintf(j->recon.capture_id, sizeof j->recon.capture_id, "%s", it[i].capture_id);
        j->recon.spec = it[i].spec;
        snprintf(j->persisted, sizeof j->persisted, "%s", it[i].file);
        scicapd_queue_push(d->recon_q, j); /* room was made above */
        sci_log_write(d->log, SCI_LOG_NOTICE, "job %llu: resumed the reconstruction of %s (%s, uid %d) queued "
                      "before the last stop", (unsigned long long)j->id, j->recon.capture_id,
                      j->recon.spec.method->name, (int)j->owner);
    }
    scicapd_queue_resize(d->recon_q, d->cfg->recon_queue);
    d->resumed = n;
    free(it);
    return 0;
}

static int web_start(scicapd *d, sci_error *err)
{
    const scicapd_config *c = d->cfg;
    char token[SCICAPD_PATH_MAX + 16];
    if (c->web_token_file[0])
        snprintf(token, sizeof token, "%s", c->web_token_file);
    else
        snprintf(token, sizeof token, "%s/web.token", c->runtime_dir);
    scicapd_web_options o = {.host = c->web_host, .port = c->web_port, .control = c->web_control,
                             .token_file = token, .token_group = c->socket_group, .socket_path = c->socket_path,
                             .storage_root = c->storage_root, .curves_path = c->recon_curves,
                             .max_connections = c->web_max_connections,
                             .timeout_s = c->web_timeout_s};
    return scicapd_web_start(&d->web, &o, d->log, err);
}

/* Threads created before scicapd_new (OpenBLAS starts its pool from a library constructor) do not block the
 * signals; one delivered there is sent on to the main thread (tid == pid), where it is blocked and read from
 * the signalfd. Async-signal-safe. */
static void forward_to_main(int sig)
{
    int saved = errno;
    /* On the main thread itself (scicapd_free restored its mask while shutting down) there is nowhere to forward
     * to: sending it again would recurse forever. The shutdown is already under way: drop it. */
    if (syscall(SYS_gettid) != getpid())
        syscall(SYS_tgkill, getpid(), getpid(), sig);
    errno = saved;
}

int scicapd_new(scicapd **out, const scicapd_options *o, const sci_log *log, sci_error *err)
{
    scicapd *d = calloc(1, sizeof *d);
    if (!d)
        return sci_error_set(err, -ENOMEM, "scicapd: out of memory");
    d->log = log;
    d->opts = *o;
    d->sfd = d->stopfd = -1;
    d->started_ns = sci_clock_mono_ns();
    scicapd_notify_init(&d->notify);
    int rc;
    /* 1. configuration */
    if ((rc = load_config(d, &d->cfg, err)) < 0)
        goto fail;
    /* 2. storage (and recovery of a crashed run) */
    if (mkdir(d->cfg->runtime_dir, 0750) != 0 && errno != EEXIST) {
        rc = sci_error_set(err, -errno, "runtime folder %s: %s", d->cfg->runtime_dir, strerror(errno));
        goto fail;
    }
    if ((rc = scicapd_store_open(&d->store, d->cfg->storage_root, d->cfg->fsync, log, &d->recovered, err)) < 0)
        goto fail;
    if (d->recovered.removed)
        sci_log_write(log, SCI_LOG_WARNING, "storage %s: removed %d partial folders left by an interrupted run",
                      d->cfg->storage_root, d->recovered.removed);
    sci_log_write(log, SCI_LOG_INFO, "storage %s: %d captures", d->cfg->storage_root, d->recovered.captures);
    d->interrupted = interrupted_capture(d->cfg->storage_root, log);
    scicapd_import_sweep(d->store); /* staging copies an interrupted import left */
    /* 3. queues and the job table */
    if ((rc = scicapd_jobs_new(&d->jobs)) < 0 || (rc = scicapd_mailbox_new(&d->mailbox)) < 0 ||
        (rc = scicapd_timing_new(&d->timing)) < 0 ||
        (rc = scicapd_queue_new(&d->acq_q, d->cfg->capture_queue)) < 0 ||
        (rc = scicapd_queue_new(&d->store_q, d->cfg->writers * 2 > STORE_QUEUE_MIN ? d->cfg->writers * 2
                                                                                 : STORE_QUEUE_MIN)) < 0 ||
        (rc = scicapd_queue_new(&d->recon_q, d->cfg->recon_queue)) < 0) {
        sci_error_set(err, rc, "scicapd: %s", sci_strerror(rc));
        goto fail;
    }
    /* 3b. reconstructions the previous run left queued (no worker runs yet) */
    if ((rc = resume_reconstructions(d, err)) < 0)
        goto fail;
    /* 4. signals, before any thread starts so that all inherit the mask */
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &set, &d->oldmask);
    struct sigaction sa = {.sa_handler = forward_to_main, .sa_flags = SA_RESTART};
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    d->sfd = signalfd(-1, &set, SFD_CLOEXEC | SFD_NONBLOCK);
    d->stopfd = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
    if (d->sfd < 0 || d->stopfd < 0) {
        rc = sci_error_set(err, -errno, "scicapd: signalfd/eventfd: %s", strerror(errno));
        goto fail;
    }
    /* 5. devices */
    scicapd_acquire_env ae = {.jobs = d->jobs, .mailbox = d->mailbox, .store = d->store, .in = d->acq_q,
                              .out = d->store_q, .timing = d->timing, .log = log};
    if ((rc = scicapd_acquire_new(&d->acq, d->cfg, &ae, err)) < 0)
        goto fail;
    /* 5b. the web view (off unless the configuration has a "web" section): before the control socket, so that a
     * client that found the socket listening finds the web view and its token file too; until the socket below
     * listens, the web's state and control requests answer 503 */
    if (d->cfg->web_enabled && (rc = web_start(d, err)) < 0)
        goto fail;
    /* 6. the control socket */
    if (d->cfg->admin_group[0] && strcmp(d->cfg->admin_group, d->cfg->socket_group) == 0)
        sci_log_write(log, SCI_LOG_WARNING, "control.admin_group is the socket's group \"%s\": every user who can "
                      "reach the socket may cancel others' jobs and shut the daemon down", d->cfg->admin_group);
    scicapd_control_limits lim = control_limits(d->cfg);
    scicapd_control_hooks hooks = {.on_line = on_line, .is_admin = hook_is_admin, .busy = hook_busy, .user = d};
    if ((rc = scicapd_control_open(&d->ctl, d->cfg->socket_path, d->cfg->socket_mode, d->cfg->socket_group, &lim,
                                   &hooks, log, err)) < 0)
        goto fail;
    /* 7. threads: writer, reconstruction workers, acquisition */
    scicapd_store_set_previews(d->store, d->cfg->previews);
    d->store_started = 1; /* stop joins whatever threads did start */
    if ((rc = scicapd_store_start(d->store, d->store_q, d->cfg->writers, on_stored, d, d->timing, err)) < 0)
        goto fail;
    scicapd_workers_env we = {.jobs = d->jobs, .mailbox = d->mailbox, .store = d->store, .in = d->recon_q,
                              .timing = d->timing, .log = log,
                              .checkpoint_every = d->cfg->recon_checkpoint_every};
    if ((rc = scicapd_workers_start(&d->workers, &we, d->cfg->workers, d->cfg->recon_threads, err)) < 0 ||
        (rc = scicapd_acquire_start(d->acq, err)) < 0)
        goto fail;
    sci_log_write(log, SCI_LOG_NOTICE, "scicapd %s listening on %s (config %s, storage %s)", SCICAP_VERSION,
                  d->cfg->socket_path, d->cfg->path[0] ? d->cfg->path : "built-in defaults", d->cfg->storage_root);
    *out = d;
    return 0;
fail:
    scicapd_free(d);
    return rc;
}

void scicapd_ready(scicapd *d)
{
    char s[160];
    snprintf(s, sizeof s, "ready: %d captures in %s", d->recovered.captures, d->cfg->storage_root);
    scicapd_notify_ready(&d->notify, s);
}

void scicapd_request_stop(scicapd *d)
{
    uint64_t one = 1;
    ssize_t w = write(d->stopfd, &one, sizeof one);
    (void)w;
}

static void deliver(scicapd *d)
{
    scicapd_letter *l = scicapd_mailbox_take(d->mailbox);
    for (scicapd_letter *p = l; p; p = p->next) {
        if (p->client)
            scicapd_control_send(d->ctl, p->client, p->line);
        if (p->broadcast) {
            scicapd_control_broadcast(d->ctl, p->line, p->client, p->owner);
            scicapd_web_publish(d->web, p->line); /* what an admin's `scicap watch` sees */
        }
    }
    scicapd_letters_free(l);
}

static void housekeeping(scicapd *d)
{
    int64_t now = sci_clock_mono_ns();
    scicapd_control_expire(d->ctl, now);
    if (now - d->last_status_ns >= 2000000000LL) {
        d->last_status_ns = now;
        int q, r, f;
        scicapd_jobs_count(d->jobs, &q, &r, &f);
        scicapd_notify_status(&d->notify, "%s; %ld captures stored; jobs: %d queued, %d running; %d clients",
                              scicapd_acquire_dmd_connected(d->acq) ? "ready" : "DMD disconnected",
                              (long)atomic_load(&d->stored), q, r, scicapd_control_clients(d->ctl));
    }
}

/* The systemd watchdog (a loop timer): fed when due, only while the acquisition thread shows signs of life within
 * the interval. Returns the ms to the next ping (-1 without a watchdog: the timer ends). */
static int on_watchdog(void *user)
{
    scicapd *d = user;
    int64_t period = scicapd_notify_watchdog_period_ns(&d->notify);
    if (period <= 0)
        return -1;
    int64_t now = sci_clock_mono_ns();
    if (now - d->notify.last_ping_ns >= period) {
        if (now - scicapd_acquire_heartbeat_ns(d->acq) < 2 * period)
            scicapd_notify_watchdog(&d->notify);
        else
            sci_log_write(d->log, SCI_LOG_ERR, "acquisition thread silent for %.1f s: watchdog not fed",
                          sci_clock_s(scicapd_acquire_heartbeat_ns(d->acq), now));
    }
    int64_t left = d->notify.last_ping_ns + period - now;
    return left <= 0 ? 0 : (int)(left / 1000000) + 1;
}

static void on_signal(void *user, int fd, short revents)
{
    scicapd *d = user;
    struct signalfd_siginfo si;
    while (read(fd, &si, sizeof si) == sizeof si) {
        if (si.ssi_signo == SIGHUP) {
            sci_error err = {0};
            sci_log_write(d->log, SCI_LOG_NOTICE, "SIGHUP: reloading the configuration");
            reload(d, NULL, &err);
        } else {
            sci_log_write(d->log, SCI_LOG_NOTICE, "signal %d: stopping", (int)si.ssi_signo);
            scicapd_loop_stop(d->loop);
        }
    }
}

static void on_stopfd(void *user, int fd, short revents) { scicapd_loop_stop(((scicapd *)user)->loop); }
/* The mailbox's eventfd only wakes the loop: the letters are delivered after every turn (on_turn_end). */
static void on_mail(void *user, int fd, short revents) { (void)user; }

static int control_fill(void *user, struct pollfd *fds, int max) { return scicapd_control_pollfds(user, fds, max); }
static void control_dispatch(void *user, const struct pollfd *fds, int n) { scicapd_control_dispatch(user, fds, n); }
static int control_deadline(void *user, int64_t now_ns) { return scicapd_control_next_deadline_ms(user, now_ns); }

static void on_turn_end(void *user)
{
    scicapd *d = user;
    deliver(d);
    housekeeping(d);
}

int scicapd_run(scicapd *d)
{
    /* a turn waits at most 1 s: the status line and the connections' deadlines are checked after each */
    int rc = scicapd_loop_new(&d->loop, 1000);
    if (rc < 0)
        return rc;
    if ((rc = scicapd_loop_add_fd(d->loop, d->sfd, POLLIN, on_signal, d)) < 0 ||
        (rc = scicapd_loop_add_fd(d->loop, scicapd_mailbox_fd(d->mailbox), POLLIN, on_mail, d)) < 0 ||
        (rc = scicapd_loop_add_fd(d->loop, d->stopfd, POLLIN, on_stopfd, d)) < 0 ||
        (rc = scicapd_loop_add_poller(d->loop, control_fill, control_dispatch, control_deadline, d->ctl)) < 0 ||
        (rc = scicapd_loop_add_timer(d->loop, 0, on_watchdog, d)) < 0)
        goto out;
    scicapd_loop_set_after(d->loop, on_turn_end, d);
    rc = scicapd_loop_run(d->loop);
out:
    scicapd_loop_free(d->loop);
    d->loop = NULL;
    return rc < 0 ? rc : 0;
}

void scicapd_free(scicapd *d)
{
    if (!d)
        return;
    json_decref(d->interrupted);
    d->interrupted = NULL;
    atomic_store(&d->stopping, 1);
    scicapd_notify_stopping(&d->notify, "stopping: finishing the current snapshot, canceling reconstructions");
    /* first: its threads call the control socket, which stops serving below */
    scicapd_web_stop(d->web);
    d->web = NULL;
    scicapd_control_stop_listening(d->ctl);
    /* acquisition: no new jobs; the current snapshot finishes and goes to the writer */
    if (d->acq_q)
        scicapd_queue_close(d->acq_q);
    if (d->jobs) {
        /* reconstructions stop at their next iteration and write nothing */
        scicapd_jobs_cancel_all(d->jobs);
    }
    scicapd_acquire_stop(d->acq);
    if (d->recon_q)
        scicapd_queue_close(d->recon_q);
    scicapd_workers_stop(d->workers);
    /* the writer stores everything acquired */
    if (d->store_q)
        scicapd_queue_close(d->store_q);
    if (d->store_started)
        scicapd_store_stop(d->store);
    /* last words to the clients */
    if (d->ctl && d->mailbox) {
        deliver(d);
        /* a loop of the connections alone: no signal or reload may run now */
        scicapd_loop *l = NULL;
        if (scicapd_loop_new(&l, 20) == 0 &&
            scicapd_loop_add_poller(l, control_fill, control_dispatch, NULL, d->ctl) > 0)
            for (int i = 0; i < 50 && scicapd_control_flushing(d->ctl); i++)
                scicapd_loop_turn(l, 20);
        scicapd_loop_free(l);
    }
    scicapd_control_close(d->ctl);
    scicapd_acquire_free(d->acq);
    scicapd_job *j;
    while (d->recon_q && (j = scicapd_queue_take(d->recon_q)))
        scicapd_job_unref(d->jobs, j);
    scicapd_queue_free(d->recon_q);
    scicapd_queue_free(d->store_q);
    scicapd_queue_free(d->acq_q);
    scicapd_mailbox_free(d->mailbox);
    scicapd_jobs_free(d->jobs);
    scicapd_timing_free(d->timing);
    scicapd_store_close(d->store);
    if (d->sfd >= 0) {
        close(d->sfd);
        pthread_sigmask(SIG_SETMASK, &d->oldmask, NULL);
    }
    if (d->stopfd >= 0)
        close(d->stopfd);
    scicapd_config_free(d->cfg);
    free(d);
}
