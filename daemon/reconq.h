/* daemon/reconq.h — the reconstruction queue on disk: what was queued survives the daemon.
 *
 * Every reconstruct job, from a request or a capture's auto-reconstruction, is saved as one small JSON file
 * under ROOT/recon-queue/ before it enters the in-memory queue, and its file is removed when the job ends for
 * good (done, failed, or canceled by a user). A job stopped because the daemon stops (SIGTERM, shutdown, or a
 * kill -9 that never ran the cleanup) keeps its file, and so does one waiting for room to write its result
 * (daemon/workers.h); at the next start scicapd_reconq_load reads the files in
 * submission order and the daemon queues them again, with their owner uid, before it accepts connections.
 *
 *     r-<CLOCK_REALTIME ns, 20 digits>-<job id>.json
 *     {"capture": "c000042", "owner": 1000, "method": "gap-tv", "preset": "fast",
 *      "params": {"iters": 30, "lambda": 1, "tv_weight": 0.1, "tv_iters": 5, "accelerate": true},
 *      "budget": {"budget_s": 2, "method": "gap-tv", "setting": "iters=30 tv_iters=5", "predicted_s": 1.7,
 *                 "expected_psnr_db": 29.1}}                      (budget only when chosen so; setting optional)
 *
 * A method with checkpoints (recon/solver.h SOLVER_CHECKPOINTS: the NeRF methods) keeps its newest one beside
 * its entry, r-<...>-<job id>.ckpt (the method's own blob, written every reconstruction.checkpoint_every steps
 * and when the daemon stops): a resumed job continues from it instead of starting over. It goes with the entry.
 *
 * Completion is durable in the output itself: the result.json a job publishes names its entry, so an entry left
 * behind by a crash after the publish is recognised at load (scicapd_reconq_load) and not run again.
 *
 * A file is written beside and renamed (fsync'd with storage.fsync), so a crash leaves the old state or the
 * new, never half a file; a file that cannot be read back is renamed bad-<name> (kept for a person to look at)
 * and reported. Thread-safe: functions touch only the file of the job they are given.
 */
#ifndef SCICAP_DAEMON_RECONQ_H
#define SCICAP_DAEMON_RECONQ_H

#include <sys/types.h>

#include "base/error.h"
#include "base/log.h"
#include "daemon/jobs.h"
#include "daemon/store.h"

/* One job read back: the capture, its owner and the spec resolved as at submission. */
typedef struct scicapd_reconq_item {
    char capture_id[64];
    uid_t owner;
    scicapd_recon_spec spec;
    char file[96];            /* its name under ROOT/recon-queue/ (becomes the job's `persisted`) */
} scicapd_reconq_item;

/* Save reconstruct job j (its recon args and owner) and set j->persisted. Call before queueing j. -errno with
 * err naming the file. */
int scicapd_reconq_save(scicapd_store *st, scicapd_job *j, sci_error *err);
/* Remove j's file and its checkpoint (no-op when j->persisted is empty or the files are gone). */
void scicapd_reconq_drop(scicapd_store *st, const scicapd_job *j);
/* Replace j's checkpoint with `bytes` bytes of blob (beside, then renamed). -ENOENT when j is not persisted (a
 * job that would not be resumed needs none), -errno with err naming the file. */
int scicapd_reconq_checkpoint_save(scicapd_store *st, const scicapd_job *j, const void *blob, size_t bytes,
                                   sci_error *err);
/* j's checkpoint, if any: 1 with *blob (caller frees) and *bytes, 0 when there is none, -errno on a read error. */
int scicapd_reconq_checkpoint_load(scicapd_store *st, const scicapd_job *j, void **blob, size_t *bytes,
                                   sci_error *err);
/* Every saved job, oldest first: *items (caller frees with free()) and *n. Unreadable files are renamed and
 * logged, not returned. A job whose output is already published — a <capture>/recon/<method>[.N]/result.json names
 * its entry under "job"."queue_entry", written by daemon/workers.c — is complete: the daemon died between the publish
 * and the removal of the entry. Its entry (and checkpoint) is removed and logged, not returned, so a kill -9 at
 * that moment never runs a job twice. -ENOMEM, or -errno when the folder cannot be created or read. */
int scicapd_reconq_load(scicapd_store *st, const sci_log *log, scicapd_reconq_item **items, int *n, sci_error *err);

#endif
