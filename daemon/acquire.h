/* daemon/acquire.h — the acquisition thread: it owns the DMD, the camera and the trigger.
 *
 * Per capture job: make the mask set (sim/masks.h kinds, at the DMD's size; cached), upload it once (again after
 * a DMD reconnect), program the timing, then per snapshot arm the sync, take the snapshot (drivers/capture.h),
 * stop the DMD, check the sync report (a broken sync is stored but flagged, never hidden), convert counts to the
 * reconstruction's scale with the current calibration, and hand the snapshot to the writer queue. It never
 * waits for a reconstruction. Calibrate jobs record a dark frame, or each mask of a set shown on a white target.
 * While idle it polls the DMD for hotplug, applies injected faults (simulated devices only), re-opens devices
 * after a reload and retries devices that failed to open (daemon/devices.h).
 * Events go to the mailbox; job state to the job table. Devices are opened by scicapd_acquire_new (a device that
 * fails to open is reported, not fatal: the daemon serves and says which device is missing) and used only by
 * the thread afterwards.
 */
#ifndef SCICAP_DAEMON_ACQUIRE_H
#define SCICAP_DAEMON_ACQUIRE_H

#include <jansson.h>
#include <stdint.h>

#include "base/log.h"
#include "daemon/config.h"
#include "daemon/jobs.h"
#include "daemon/mailbox.h"
#include "daemon/queue.h"
#include "daemon/store.h"
#include "daemon/timing.h"

typedef struct scicapd_acquire scicapd_acquire;

typedef struct scicapd_acquire_env {
    scicapd_jobs *jobs;       /* borrowed, outlive the acquire object */
    scicapd_mailbox *mailbox;
    scicapd_store *store;
    scicapd_queue *in;        /* capture and calibrate jobs (references) */
    scicapd_queue *out;       /* snapshots for the writer */
    scicapd_timing *timing;   /* SCICAPD_STAGE_ACQUIRE per snapshot; may be NULL */
    const sci_log *log;
} scicapd_acquire_env;

/* Open the devices named in cfg (copied what is needed). Fails only for -ENOMEM. */
int scicapd_acquire_new(scicapd_acquire **out, const scicapd_config *cfg, const scicapd_acquire_env *env,
                        sci_error *err);
int scicapd_acquire_start(scicapd_acquire *a, sci_error *err);
/* A reloaded configuration (copied): the thread re-opens the devices between jobs when their settings changed,
 * and retries devices that failed to open in any case. Event-loop thread. -ENOMEM. */
int scicapd_acquire_reconfigure(scicapd_acquire *a, const scicapd_config *cfg, sci_error *err);
/* Ask the thread to end after the current snapshot and wait for it. The caller closes env->in first so that no
 * new job arrives; jobs still queued are canceled. */
void scicapd_acquire_stop(scicapd_acquire *a);
void scicapd_acquire_free(scicapd_acquire *a); /* closes the devices */

/* Queue a fault for the thread to apply (simulated bench only; -ENOTSUP otherwise). */
int scicapd_acquire_fault(scicapd_acquire *a, const scicapd_simulate_args *f, sci_error *err);
/* Device identities and connection state (new reference). Thread-safe. */
json_t *scicapd_acquire_devices_json(scicapd_acquire *a);
/* CLOCK_MONOTONIC time of the thread's last sign of life (for the watchdog). */
int64_t scicapd_acquire_heartbeat_ns(scicapd_acquire *a);
/* 1 while the DMD is connected. */
int scicapd_acquire_dmd_connected(scicapd_acquire *a);

#endif
