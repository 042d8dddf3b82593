/* daemon/acquire.h — the acquisition thread: it owns the devices (daemon/devices.h) and runs the jobs that use
 * them, one at a time, in the order they were queued:
 *   capture jobs    daemon/capture.h: program the DMD, take snapshots, package each (daemon/package.h) and hand
 *                   it to the writer queue; it never waits for a reconstruction;
 *   calibrate jobs  daemon/calibrate.h: a dark frame, or each mask of a set on a white target.
 * While idle it polls the DMD for hotplug, applies injected faults, re-opens devices after a reload and retries
 * devices that failed to open (daemon/devices.h).
 * Events go to the mailbox; job state to the job table. Devices are opened by scicapd_acquire_new (a device that
 * fails to open is reported, not fatal: the daemon serves and says which device is missing) and used only by
 * the thread afterwards.
 *
 * This file keeps what the jobs share (the second part of this header): the devices bound for a job, the mask
 * sets made at the DMD's size (cached), what the DMD holds (a set is uploaded once, again after a reconnect or a
 * reload), programming its timing, taking one frame, the calibrations in use, and the thread's events, faults and
 * heartbeat.
 */
#ifndef SCICAP_DAEMON_ACQUIRE_H
#define SCICAP_DAEMON_ACQUIRE_H

#include <jansson.h>
#include <stdint.h>

#include "base/log.h"
#include "daemon/config.h"
#include "daemon/devices.h"
#include "daemon/jobs.h"
#include "daemon/mailbox.h"
#include "daemon/queue.h"
#include "daemon/store.h"
#include "daemon/timing.h"
#include "drivers/capture.h"

typedef struct scicapd_acquire scicapd_acquire;
typedef struct scicapd_calibs scicapd_calibs;

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

/* Queue a fault for the thread to apply (-ENOTSUP when the devices as configured cannot take it). */
int scicapd_acquire_fault(scicapd_acquire *a, const scicapd_simulate_args *f, sci_error *err);
/* Device identities and connection state (new reference). Thread-safe. */
json_t *scicapd_acquire_devices_json(scicapd_acquire *a);
/* CLOCK_MONOTONIC time of the thread's last sign of life (for the watchdog). */
int64_t scicapd_acquire_heartbeat_ns(scicapd_acquire *a);
/* 1 while the DMD is connected. */
int scicapd_acquire_dmd_connected(scicapd_acquire *a);

/* ---- what the jobs share (daemon/capture.c, daemon/calibrate.c): acquisition thread only ---- */

const scicapd_acquire_env *scicapd_acquire_env_get(const scicapd_acquire *a); /* borrowed */
scicapd_devices *scicapd_acquire_devices(scicapd_acquire *a);                 /* borrowed */
scicapd_calibs *scicapd_acquire_calibs(scicapd_acquire *a);                   /* borrowed */
/* An event for j's client (j NULL: for every client). Takes the reference to data. */
void scicapd_acquire_post(scicapd_acquire *a, const scicapd_job *j, const char *name, json_t *data);
/* 1 when j was canceled or the thread is asked to stop: the job ends after the current frame. */
int scicapd_acquire_canceled(scicapd_acquire *a, const scicapd_job *j);
/* A sign of life for the watchdog. */
void scicapd_acquire_beat(scicapd_acquire *a);
/* Apply the faults queued by scicapd_acquire_fault (between snapshots). */
void scicapd_acquire_apply_faults(scicapd_acquire *a);
/* Sleep the injected per-snapshot delay, if any (the "acquire-delay" fault). */
void scicapd_acquire_injected_delay(scicapd_acquire *a);
/* The scale without measured masks: counts per unit and dark level (daemon/config.h). */
void scicapd_acquire_scale(const scicapd_acquire *a, double *counts_per_unit, double *dark_level);

/* Bind the devices for a job in sync mode `mode` (scicapd_devices_prepare): all three open, or an error naming
 * the one that is not. The handles below are valid until the job ends. */
int scicapd_acquire_bind(scicapd_acquire *a, enum sync_mode mode, sci_error *err);
const dmd_identity *scicapd_acquire_dmd_identity(const scicapd_acquire *a);
camera *scicapd_acquire_camera(scicapd_acquire *a);
/* Mask set ms at the DMD's size (made on first use, cached; borrowed until the devices are re-opened). NULL on
 * error, with the set's name in the message. */
const sci_cube *scicapd_acquire_mask_set(scicapd_acquire *a, const scicapd_mask_set *ms, sci_error *err);
/* Put `masks` on the DMD under `set_name` (uploaded only when another set is there) and program its timing for
 * `mode`: pattern_us exposure and dark_us dark time per mask, in µs. */
int scicapd_acquire_program(scicapd_acquire *a, const char *set_name, const sci_cube *masks, uint32_t pattern_us,
                            uint32_t dark_us, enum sync_mode mode, sci_error *err);
/* The DMD holds no known set any more (the next program uploads). */
void scicapd_acquire_forget_upload(scicapd_acquire *a);
/* Arm the sync, take one frame of exposure_us (n masks in the sequence; dark: the DMD is not started), stop the
 * DMD. The frame and its sync report are in scicapd_acquire_shot until the next take. */
int scicapd_acquire_take(scicapd_acquire *a, int n, uint32_t exposure_us, enum sync_mode mode, int dark,
                         sci_error *err);
const capture_snapshot *scicapd_acquire_shot(const scicapd_acquire *a);

#endif
