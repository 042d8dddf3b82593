/* daemon/acquire.h — the acquisition thread: it owns the rig (daemon/rig.h: the devices as jobs use them) and
 * runs the jobs that use it, one at a time, in the order they were queued, through a table from job kind to run
 * function (scicapd_acquire_kind_get):
 *   capture jobs    daemon/capture.h: program the DMD, take snapshots, package each (daemon/package.h) and hand
 *                   it to the writer queue; it never waits for a reconstruction;
 *   calibrate jobs  daemon/calibrate.h: a dark frame, or each mask of a set on a white target.
 * While idle it polls the DMD for hotplug, applies injected faults, re-opens devices after a reload and retries
 * devices that failed to open (daemon/devices.h).
 * The flow is one-way: this file calls the jobs, the jobs call the rig, the rig calls the devices; nothing
 * below calls up. Events go to the mailbox; job state to the job table. Devices are opened by
 * scicapd_acquire_new (a device that fails to open is reported, not fatal: the daemon serves and says which
 * device is missing) and used only by the thread afterwards.
 */
#ifndef SCICAP_DAEMON_ACQUIRE_H
#define SCICAP_DAEMON_ACQUIRE_H

#include <jansson.h>
#include <stdint.h>

#include "daemon/config.h"
#include "daemon/jobs.h"
#include "daemon/rig.h"

typedef struct scicapd_acquire scicapd_acquire;
typedef scicapd_rig_env scicapd_acquire_env;

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
void scicapd_acquire_free(scicapd_acquire *a); /* closes the devices; NULL is harmless */

/* Queue a fault for the thread to apply (-ENOTSUP when the devices as configured cannot take it). */
int scicapd_acquire_fault(scicapd_acquire *a, const scicapd_simulate_args *f, sci_error *err);
/* Device identities and connection state (new reference). Thread-safe. */
json_t *scicapd_acquire_devices_json(scicapd_acquire *a);
/* CLOCK_MONOTONIC time of the thread's last sign of life (for the watchdog). */
int64_t scicapd_acquire_heartbeat_ns(scicapd_acquire *a);
/* 1 while the DMD is connected. */
int scicapd_acquire_dmd_connected(scicapd_acquire *a);

/* One row of the job kind table: how the thread runs a kind, and the event that says a job of it was canceled
 * before it ran (or at a stop). */
typedef struct scicapd_acquire_kind {
    void (*run)(scicapd_rig *r, scicapd_job *j); /* runs j to its end: state, events, outputs */
    const char *canceled_event;
} scicapd_acquire_kind;

/* The row for kind k, or NULL for the kinds the acquisition thread does not run (reconstruct, import). */
const scicapd_acquire_kind *scicapd_acquire_kind_get(scicapd_job_kind k);

#endif
