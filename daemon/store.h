/* daemon/store.h — the storage root: capture folders, calibrations, crash recovery, and the writer thread.
 *
 *     ROOT/captures/c000042/          one snapshot (docs/capture-folder.md): a problem folder (io/problem_dir.h:
 *                                     problem.json, meas_*.exr, mask_*.exr, truth_*.exr on the simulator) plus
 *                                     raw.tif (16-bit counts), dmd_mask_*.png (the masks shown), dark.tif and
 *                                     calibration.json (the calibration used), meta.json, and recon/<method>/
 *     ROOT/calibrations/dark-000003/  a dark frame (dark.tif + calibration.json)
 *     ROOT/calibrations/masks-random8-000004/  measured masks (mask_*.exr stack + calibration.json)
 *     ROOT/calibrations/dark.json, masks-random8.json   which calibration is current (replaced atomically)
 *     ROOT/dmd_masks/<hash>/          the PNGs of one mask stack as shown on the DMD, written once and hard-linked
 *                                     into every capture folder that used it
 *     ROOT/mask_stacks/<hash>/        the reconstruction's masks of a capture (mask.json, mask_*.exr,
 *                                     preview_mask_*.png), written once per mask stack and hard-linked likewise
 *                                     (checked against the masks once per run before the first link)
 *     ROOT/ids.json                   the capture/calibration id high-water mark (below)
 *     ROOT/recon-queue/r-*.json       reconstructions queued or running, resumed at start (daemon/reconq.h)
 *
 * Atomicity: a capture is written under ROOT/captures/.c000042.partial and renamed when complete (after fsync
 * of every file and of the folder when fsync is on); only then is it announced. A kill -9 leaves at most a
 * dot-named partial folder, a *.tmp-<pid> folder or a ROOT/.<name>.tmp-XXXXXX file (an interrupted atomic write of
 * one of ROOT's own files), which scicapd_store_open removes: a reader never sees half a capture, and every
 * announced capture survives.
 * Capture ids are c000001, c000002, ... and are never reused, not after a crash, not after captures are deleted:
 * ROOT/ids.json holds a durable high-water mark (the largest capture and calibration number that may have been
 * handed out), written and fsync'd before any id above it is used, STORE_ID_BLOCK (16) at a time; numbering
 * continues after the larger of the mark and the largest folder found at open. A clean close writes the exact
 * mark; a crash may leave gaps (up to 15 ids, and those of folders that were never complete). The
 * acquisition thread reserves each snapshot's id before queueing it, so ids follow acquisition order even though
 * `writers` threads write folders in parallel.
 * The writer threads take snapshots from a bounded queue and call on_stored for each (success or failure), in
 * completion order: with several writers, snapshot i+1 may be announced before snapshot i.
 * Thread-safe: ids are allocated under a lock; each folder is written by one thread.
 */
#ifndef SCICAP_DAEMON_STORE_H
#define SCICAP_DAEMON_STORE_H

#include <jansson.h>
#include <stdint.h>

#include "base/log.h"
#include "daemon/jobs.h"
#include "daemon/queue.h"
#include "daemon/timing.h"
#include "recon/problem.h"

typedef struct scicapd_store scicapd_store;

/* What the acquisition thread hands to the writer. Everything is owned by the snapshot. */
typedef struct scicapd_snapshot {
    scicapd_job *job;        /* reference (released by scicapd_snapshot_free through the jobs table) */
    int index;               /* 0-based snapshot of the job */
    sci_problem *problem;    /* meas in calibrated units, the masks used, truth on the simulator */
    sci_cube *raw;           /* counts, w×h×1; NULL for an import (no raw.tif) */
    sci_cube *dmd_masks;     /* as shown on the DMD (0/1); NULL for an import (no dmd_mask_*.png) */
    sci_cube *dark;          /* dark frame subtracted (counts), or NULL */
    json_t *meta;            /* settings, identities, timestamps, sync report */
    json_t *calibration;     /* the calibration record used, or NULL */
    int broken;              /* sync report says broken (stored, flagged in meta.json) */
    char capture_id[32];     /* set by the store */
    char dir[1100];          /* final folder, set by the store */
} scicapd_snapshot;

void scicapd_snapshot_free(scicapd_jobs *jobs, scicapd_snapshot *s);

typedef struct scicapd_store_recovery {
    int captures;            /* complete captures found */
    int removed;             /* partial folders and interrupted temporary files removed */
} scicapd_store_recovery;

/* Lock ROOT (ROOT/scicapd.lock, flock, for the store's life: -EBUSY naming the holder's pid when another
 * scicapd has it, before anything is touched), create ROOT/captures and ROOT/calibrations if needed, remove
 * partial outputs of a previous run, find the next capture id. Errors: -errno naming the folder; SCI_EFORMAT
 * when ROOT/ids.json is unreadable (the daemon will not guess ids it may already have given out). */
int scicapd_store_open(scicapd_store **out, const char *root, int fsync_on, const sci_log *log,
                       scicapd_store_recovery *rec, sci_error *err);
void scicapd_store_close(scicapd_store *s);
const char *scicapd_store_root(const scicapd_store *s);
/* 1 when files are fsync'd before they count (storage.fsync). */
int scicapd_store_fsync_on(const scicapd_store *s);

/* Give s the next capture id (s->capture_id), after making the high-water mark durable when the id passes it
 * (may block on fsync, once per STORE_ID_BLOCK ids). Thread-safe. -errno when the mark cannot be written: no id
 * is handed out then. */
int scicapd_store_reserve_id(scicapd_store *st, scicapd_snapshot *s, sci_error *err);
/* The same before the snapshot exists: the id into id (n bytes, "c000042"), its number into *num (may be NULL).
 * For the simulated bench, whose scene time follows the capture number (daemon/capture.c). */
int scicapd_store_take_id(scicapd_store *st, char *id, size_t n, unsigned long *num, sci_error *err);
/* Give back capture number `num` when it is still the last one handed out (the snapshot it was taken for
 * failed); otherwise it stays unused, a gap as after a crash. Thread-safe. */
void scicapd_store_give_back_id(scicapd_store *st, unsigned long num);
/* Previews (preview_*.png, preview_truth.gif) in the folders written from now on (storage.previews). */
void scicapd_store_set_previews(scicapd_store *st, int on);
/* Write one snapshot as a capture folder (reserves an id unless s has one; sets s->dir). Blocks on file I/O.
 * s->job may be NULL (imports). */
int scicapd_store_write_capture(scicapd_store *st, scicapd_snapshot *s, sci_error *err);
/* ROOT/captures/<id> into buf if it is a complete capture; -ENOENT otherwise. */
int scicapd_store_capture_dir(const scicapd_store *st, const char *id, char *buf, size_t n, sci_error *err);

/* Write a calibration folder (kind "dark": `data` is the dark frame in counts; "masks": the measured mask
 * stack) and make it current for `key` ("dark" or "masks-<set>"). `record` is stored as calibration.json with
 * "folder" and "id" added; *record_out (may be NULL) receives a new reference to the final record. */
int scicapd_store_write_calibration(scicapd_store *st, const char *key, const sci_cube *data, const json_t *record,
                                    json_t **record_out, sci_error *err);
/* Load the current calibration for `key`: *data (counts for dark, the measured masks for masks) and *record.
 * -ENOENT when there is none. */
int scicapd_store_load_calibration(scicapd_store *st, const char *key, sci_cube **data, json_t **record,
                                   sci_error *err);

/* The writer threads (1..16): each pops snapshots from q until it is closed and empty, writes each (its time
 * counted under SCICAPD_STAGE_STORE in `timing`, which may be NULL), then calls on_stored (on that writer
 * thread, so on_stored must be thread-safe) with rc and err; on_stored takes ownership of the snapshot. On
 * failure the threads already started keep running: call scicapd_store_stop. Process-wide side effect: OpenEXR's
 * compression pool is turned off (sci_image_exr_threads(-1)): each EXR is compressed by the thread writing it,
 * which is then the whole of its cost in the stage's CPU time. */
typedef void (*scicapd_stored_fn)(void *user, scicapd_snapshot *s, int rc, const sci_error *err);
int scicapd_store_start(scicapd_store *st, scicapd_queue *q, int writers, scicapd_stored_fn on_stored, void *user,
                        scicapd_timing *timing, sci_error *err);
/* Waits for the queue (closed by the caller) to drain and the threads to end. */
void scicapd_store_stop(scicapd_store *st);

#endif
