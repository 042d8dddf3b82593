/* daemon/jobs.h — jobs (capture, calibrate, reconstruct) and the table the `jobs` and `cancel` commands read.
 *
 * A job is created on the event-loop thread with its arguments fully resolved (so a reload never changes a job
 * already accepted), queued, and run by the acquisition thread or a reconstruction worker. Its state and
 * progress are changed under the table's lock; the arguments are immutable after creation. Jobs are
 * reference-counted: the table holds one reference, a queue or a worker another.
 * Cancel sets an atomic flag the runner checks between snapshots and between solver iterations.
 * The table keeps every unfinished job and the most recent SCICAPD_JOBS_HISTORY finished ones.
 * Ownership: each job records the peer uid of its submitter (SO_PEERCRED); the daemon shows and cancels a job
 * only for that uid or an admin (daemon/daemon.c). Jobs the daemon makes itself inherit their origin's owner:
 * a capture's reconstructions its capture's, a resumed reconstruction the uid persisted with it.
 * Thread-safe.
 */
#ifndef SCICAP_DAEMON_JOBS_H
#define SCICAP_DAEMON_JOBS_H

#include <jansson.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <sys/types.h>

#include "daemon/protocol.h"
#include "recon/problem.h"

#define SCICAPD_JOBS_HISTORY 256

typedef enum scicapd_job_kind {
    SCICAPD_JOB_CAPTURE, SCICAPD_JOB_CALIBRATE, SCICAPD_JOB_RECONSTRUCT, SCICAPD_JOB_IMPORT
} scicapd_job_kind;
typedef enum scicapd_job_state {
    SCICAPD_JOB_QUEUED, SCICAPD_JOB_RUNNING, SCICAPD_JOB_DONE, SCICAPD_JOB_FAILED, SCICAPD_JOB_CANCELED
} scicapd_job_state;

const char *scicapd_job_kind_name(scicapd_job_kind k);
const char *scicapd_job_state_name(scicapd_job_state s);

/* Why a job was told to stop: a user's cancel ends it for good; a shutdown leaves a persisted reconstruction to
 * be resumed at the next start (daemon/reconq.h). */
/* SCICAPD_CANCEL_STORAGE: a capture's snapshot could not be stored (the disk is full, ...): acquiring more would
 * only lose them too, so the capture stops at the first failure */
enum { SCICAPD_CANCEL_USER = 1, SCICAPD_CANCEL_SHUTDOWN = 2, SCICAPD_CANCEL_STORAGE = 3 };

typedef struct scicapd_job {
    uint64_t id;               /* 1, 2, ... per daemon run */
    scicapd_job_kind kind;
    uint64_t client;           /* connection that submitted it (0: the daemon itself) */
    uid_t owner;               /* peer uid of the submitter */
    char persisted[96];        /* reconstruct: its file under ROOT/recon-queue/ ("" = not persisted) */
    json_t *request_id;        /* the submitter's request id (owned, immutable) */
    int64_t submitted_ns, started_ns, finished_ns; /* CLOCK_MONOTONIC */
    atomic_int cancel;         /* 0, SCICAPD_CANCEL_USER (cancel command) or SCICAPD_CANCEL_SHUTDOWN */
    /* arguments (immutable) */
    scicapd_capture_args capture;
    scicapd_calib_args calib;
    scicapd_recon_args recon;
    struct scicapd_import_args *import; /* import: the arguments and passed descriptors (owned; daemon/import.h) */
    sci_problem *problem;      /* reconstruct: the capture's problem handed over by the writer that stored it (owned;
                                  the worker takes it), or NULL: the worker reads the capture folder */
    /* under the table lock */
    scicapd_job_state state;
    int done, total;           /* snapshots stored / iterations run, of total */
    int settled;               /* capture: snapshots the writers finished with (stored or failed) */
    double psnr;               /* latest PSNR (reconstruct with truth), NaN otherwise */
    char error[256];
    json_t *outputs;           /* array of capture ids / output folders (owned) */
    int refs;
} scicapd_job;

typedef struct scicapd_jobs scicapd_jobs;

int scicapd_jobs_new(scicapd_jobs **out);
void scicapd_jobs_free(scicapd_jobs *t);

/* A new job in state queued, registered in the table, with 2 references (table + caller). -ENOMEM. */
int scicapd_jobs_create(scicapd_jobs *t, scicapd_job_kind kind, uint64_t client, uid_t owner,
                        const json_t *request_id, scicapd_job **out);
/* Take a reference to job `id` (NULL if unknown). */
scicapd_job *scicapd_jobs_find(scicapd_jobs *t, uint64_t id);
void scicapd_job_unref(scicapd_jobs *t, scicapd_job *j);
/* Forget a job that was never queued (e.g. queue full): it leaves the table. */
void scicapd_jobs_forget(scicapd_jobs *t, scicapd_job *j);

void scicapd_job_set_state(scicapd_jobs *t, scicapd_job *j, scicapd_job_state s, const char *error);
void scicapd_job_set_progress(scicapd_jobs *t, scicapd_job *j, int done, int total, double psnr);
/* Capture: one more snapshot finished by a writer (stored = 1, or failed); done counts the stored ones.
 * Returns the number settled so far (writers run in parallel: this, not the index, says when a job is over). */
int scicapd_job_settle(scicapd_jobs *t, scicapd_job *j, int stored);
/* Append an output name (capture id or folder) to the job's outputs. */
void scicapd_job_add_output(scicapd_jobs *t, scicapd_job *j, const char *name);
scicapd_job_state scicapd_job_state_get(scicapd_jobs *t, scicapd_job *j);

/* Snapshot of one job / all jobs as JSON (new references). */
json_t *scicapd_job_json(scicapd_jobs *t, scicapd_job *j);
/* Jobs owned by `owner`, or every job when all != 0. */
json_t *scicapd_jobs_json(scicapd_jobs *t, uid_t owner, int all);
/* 1 when connection `client` submitted a job that is not finished (its connection waits for events). */
int scicapd_jobs_client_busy(scicapd_jobs *t, uint64_t client);
/* Counts by state (for status and STATUS=). */
void scicapd_jobs_count(scicapd_jobs *t, int *queued, int *running, int *finished);
/* Set the cancel flag of every unfinished job to SCICAPD_CANCEL_SHUTDOWN (a user's cancel stays). */
void scicapd_jobs_cancel_all(scicapd_jobs *t);

#endif
