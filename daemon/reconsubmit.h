/* daemon/reconsubmit.h — the one way a reconstruction reaches the reconstruction queue: a reconstruct job for a
 * stored capture is made, persisted (daemon/reconq.h: it survives the daemon), announced, then queued.
 *
 * Three callers, one flow: the explicit "reconstruct" request (event loop: REFUSE when the queue is full, the
 * caller replies), a capture's snapshot stored with reconstruct on (a writer thread: WAIT for room, so a capture
 * runs at the pace its reconstructions keep up with) and an import's snapshots (a worker: TRY, and run it there
 * when the queue is full, since a worker waiting for room only workers make could wait for ever).
 *
 *     scicapd_recon_request q = {.client = j->client, .owner = j->owner, .request_id = j->request_id,
 *                                .capture_id = id, .spec = spec, .origin = "capture_job", .origin_job = j->id,
 *                                .mode = SCICAPD_ENQUEUE_WAIT};
 *     const char *why;
 *     if (scicapd_recon_submit(&env, &q, NULL, &why, &err) < 0)
 *         ... post recon.rejected with reason why ...
 *
 * scicapd_recon_submit is scicapd_recon_prepare then scicapd_recon_enqueue; an import calls the two apart so
 * that its reconstructions are announced before import.done and queued after it (a client that waits knows
 * what to wait for when the import's last word arrives). Thread-safe (the job table, mailbox and queue are).
 */
#ifndef SCICAP_DAEMON_RECONSUBMIT_H
#define SCICAP_DAEMON_RECONSUBMIT_H

#include <jansson.h>
#include <stdint.h>
#include <sys/types.h>

#include "base/error.h"
#include "base/log.h"
#include "daemon/jobs.h"
#include "daemon/mailbox.h"
#include "daemon/queue.h"
#include "daemon/store.h"

/* What a full (or closed) queue does to a submission. */
typedef enum scicapd_enqueue_mode {
    SCICAPD_ENQUEUE_REFUSE, /* SCI_EBUSY at once; the job forgotten, its entry removed */
    SCICAPD_ENQUEUE_WAIT,   /* wait for room */
    SCICAPD_ENQUEUE_TRY,    /* SCI_EBUSY / -EPIPE at once, the job and its entry left to the caller (who runs it) */
} scicapd_enqueue_mode;

typedef struct scicapd_recon_submit_env {
    scicapd_jobs *jobs;       /* borrowed; outlive the calls */
    scicapd_store *store;
    scicapd_mailbox *mailbox;
    scicapd_queue *queue;     /* the reconstruction queue (workers pop it) */
    const sci_log *log;
} scicapd_recon_submit_env;

typedef struct scicapd_recon_request {
    uint64_t client;           /* connection the job's events go to (0: none) */
    uid_t owner;               /* the job's owner (the capture's or import's, or the requester) */
    const json_t *request_id;  /* copied into the job; may be NULL */
    const char *capture_id;    /* stored capture */
    scicapd_recon_spec spec;   /* resolved method, preset, parameters */
    sci_problem *problem;      /* the capture's problem handed over (taken, also on error), or NULL: read back */
    const char *origin;        /* "capture_job" or "import_job": recon.queued is posted naming origin_job;
                                  NULL: no event (the caller replies to its request) */
    uint64_t origin_job;
    scicapd_enqueue_mode mode; /* when the queue is full */
} scicapd_recon_request;

/* Make the job, persist it, announce it (origin set) and queue it. 0: queued (the queue holds the job; *queued,
 * when asked, is the reply's {job, state, capture, method, preset[, budget]}, new reference). Not queued:
 *   -ENOMEM        the job could not be made             (*reason "out of memory")
 *   -errno         the entry could not be saved, err naming the file; logged   ("cannot save the queue entry")
 *   SCI_EBUSY      REFUSE and the queue is full; the entry removed              ("reconstruction queue full")
 *   -EPIPE         the queue is closed (the daemon stops): with WAIT the entry stays and is resumed at the next
 *                  start ("daemon stopping; resumed at the next start"), with REFUSE it is removed
 * and the job is forgotten (TRY is for scicapd_recon_enqueue only). err->msg says it for a reply; *reason (static, may be NULL) for a recon.rejected. */
int scicapd_recon_submit(const scicapd_recon_submit_env *env, const scicapd_recon_request *req, json_t **queued,
                         const char **reason, sci_error *err);

/* The first half: the job made, persisted and announced, not queued (*out: the caller's reference). Errors as
 * above (-ENOMEM, -errno), the job then forgotten. */
int scicapd_recon_prepare(const scicapd_recon_submit_env *env, const scicapd_recon_request *req, scicapd_job **out,
                          const char **reason, sci_error *err);
/* The second half: queue prepared job j, taking the caller's reference; on error also, except with TRY, where
 * the caller keeps j (and its entry) on SCI_EBUSY / -EPIPE. Errors SCI_EBUSY and -EPIPE as above. */
int scicapd_recon_enqueue(const scicapd_recon_submit_env *env, scicapd_job *j, scicapd_enqueue_mode mode,
                          const char **reason, sci_error *err);

/* A queued reconstruction's reply data: {job, state "queued", capture, method, preset[, budget]} (new ref). */
json_t *scicapd_recon_queued_json(const scicapd_job *j);

#endif
