/* daemon/rig.h — the devices as the acquisition jobs use them: the low-level context under capture and calibrate
 * jobs (daemon/capture.h, daemon/calibrate.h), which the acquisition thread (daemon/acquire.h) owns and hands
 * to them. It calls nothing above it: jobs call down into it, never the other way.
 *
 * What it holds: the devices (daemon/devices.h) and the three bound for the current job, the mask sets made at
 * the DMD's size (cached, up to 8), what the DMD holds (a set is uploaded once, again after a reconnect or a
 * reload), the DMD timing last programmed, the last frame taken, the calibrations in use (daemon/calibs.h), the
 * faults queued for it, the thread's heartbeat and stop flag, and the borrowed environment the jobs report to
 * (job table, mailbox, store, writer queue, timing, log).
 *
 *     scicapd_rig_bind(r, SYNC_MODE_HOST_MASTER, &err);
 *     const sci_cube *m = scicapd_rig_mask_set(r, &set, &err);
 *     scicapd_rig_program(r, set.name, m, pattern_us, dark_us, SYNC_MODE_HOST_MASTER, &err);
 *     scicapd_rig_take(r, m->n, exposure_us, SYNC_MODE_HOST_MASTER, 0, &err);
 *     const capture_snapshot *shot = scicapd_rig_shot(r);
 *
 * Threads: everything is for the acquisition thread only, except where a function says thread-safe.
 * Errors: 0 or a negative code with err set naming the device, set or value.
 */
#ifndef SCICAP_DAEMON_RIG_H
#define SCICAP_DAEMON_RIG_H

#include <jansson.h>
#include <stdint.h>

#include "base/log.h"
#include "daemon/calibs.h"
#include "daemon/config.h"
#include "daemon/devices.h"
#include "daemon/jobs.h"
#include "daemon/mailbox.h"
#include "daemon/queue.h"
#include "daemon/store.h"
#include "daemon/timing.h"
#include "drivers/capture.h"

typedef struct scicapd_rig scicapd_rig;

typedef struct scicapd_rig_env {
    scicapd_jobs *jobs;       /* borrowed, outlive the rig */
    scicapd_mailbox *mailbox;
    scicapd_store *store;
    scicapd_queue *in;        /* capture and calibrate jobs (references): read by the acquisition thread */
    scicapd_queue *out;       /* snapshots for the writer */
    scicapd_timing *timing;   /* SCICAPD_STAGE_ACQUIRE per snapshot; may be NULL */
    const sci_log *log;
} scicapd_rig_env;

/* Open the devices named in cfg (copied what is needed; env copied, its pointers borrowed). A device that fails
 * to open is kept, shown and retried (daemon/devices.h), not an error. Fails only for -ENOMEM. */
int scicapd_rig_new(scicapd_rig **out, const scicapd_config *cfg, const scicapd_rig_env *env, sci_error *err);
void scicapd_rig_free(scicapd_rig *r); /* closes the devices; NULL is harmless */

/* ---- thread-safe ---- */

/* Keep a reloaded configuration (copied) for scicapd_rig_apply_config. -ENOMEM. */
int scicapd_rig_reconfigure(scicapd_rig *r, const scicapd_config *cfg, sci_error *err);
/* Queue a fault for scicapd_rig_apply_faults (-ENOTSUP when the devices as configured cannot take it,
 * SCI_EBUSY with 16 pending). */
int scicapd_rig_fault(scicapd_rig *r, const scicapd_simulate_args *f, sci_error *err);
json_t *scicapd_rig_devices_json(scicapd_rig *r);  /* identities and connection state (new reference) */
int64_t scicapd_rig_heartbeat_ns(scicapd_rig *r);  /* CLOCK_MONOTONIC time of the last sign of life */
int scicapd_rig_dmd_connected(scicapd_rig *r);     /* 1 while the DMD is connected */
void scicapd_rig_stop_request(scicapd_rig *r);      /* jobs end after the current frame (scicapd_rig_canceled) */
int scicapd_rig_stopping(const scicapd_rig *r);
/* An event for j's client (j NULL: for every client). Takes the reference to data. */
void scicapd_rig_post(scicapd_rig *r, const scicapd_job *j, const char *name, json_t *data);

/* ---- between jobs ---- */

/* Apply the configuration kept by scicapd_rig_reconfigure, if any: re-open the devices when their settings
 * changed (the mask cache is dropped: the DMD may have another size), else retry the missing ones now. */
void scicapd_rig_apply_config(scicapd_rig *r);
/* Idle housekeeping: retry devices that failed to open (every 5 s) and poll the DMD for hotplug. */
void scicapd_rig_idle(scicapd_rig *r);

/* ---- for the jobs ---- */

const scicapd_rig_env *scicapd_rig_env_get(const scicapd_rig *r); /* borrowed */
scicapd_devices *scicapd_rig_devices(scicapd_rig *r);              /* borrowed */
scicapd_calibs *scicapd_rig_calibs(scicapd_rig *r);                /* borrowed */
/* 1 when j was canceled or the thread is asked to stop: the job ends after the current frame. */
int scicapd_rig_canceled(scicapd_rig *r, const scicapd_job *j);
void scicapd_rig_beat(scicapd_rig *r);           /* a sign of life for the watchdog */
void scicapd_rig_apply_faults(scicapd_rig *r);   /* the queued faults, applied now (between snapshots) */
void scicapd_rig_injected_delay(scicapd_rig *r); /* sleep the "acquire-delay" fault's per-snapshot delay, if any */
/* The scale without measured masks: counts per unit and dark level in counts (daemon/config.h). */
void scicapd_rig_scale(const scicapd_rig *r, double *counts_per_unit, double *dark_level);

/* Bind the devices for a job in sync mode `mode` (scicapd_devices_prepare): all three open, or an error naming
 * the one that is not. The handles below are valid until the job ends. */
int scicapd_rig_bind(scicapd_rig *r, enum sync_mode mode, sci_error *err);
const dmd_identity *scicapd_rig_dmd_identity(const scicapd_rig *r);
camera *scicapd_rig_camera(scicapd_rig *r);
/* Mask set ms at the DMD's size (made on first use, cached; borrowed until the devices are re-opened). NULL on
 * error, with the set's name in the message. */
const sci_cube *scicapd_rig_mask_set(scicapd_rig *r, const scicapd_mask_set *ms, sci_error *err);
/* Put `masks` on the DMD under `set_name` (uploaded only when another set is there) and program its timing for
 * `mode`: pattern_us exposure and dark_us dark time per mask, in µs. */
int scicapd_rig_program(scicapd_rig *r, const char *set_name, const sci_cube *masks, uint32_t pattern_us,
                        uint32_t dark_us, enum sync_mode mode, sci_error *err);
/* The DMD holds no known set any more (the next program uploads). */
void scicapd_rig_forget_upload(scicapd_rig *r);
/* Arm the sync, take one frame of exposure_us (n masks in the sequence; dark: the DMD is not started), stop the
 * DMD. Blocks for the exposure (plus 0.5 s at most waiting for the frame). The frame and its sync report are in
 * scicapd_rig_shot until the next take. */
int scicapd_rig_take(scicapd_rig *r, int n, uint32_t exposure_us, enum sync_mode mode, int dark, sci_error *err);
const capture_snapshot *scicapd_rig_shot(const scicapd_rig *r);

#endif
