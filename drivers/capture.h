/* drivers/capture.h — one snapshot through the camera, the trigger and the DMD, for a given sync mode.
 *
 * The acquisition thread of the daemon calls capture_snapshot_take once per snapshot. It:
 *   1. drains frames already waiting (exposed before this snapshot; counted as stale) and stale GPIO edges;
 *   2. starts the sequence the mode's way:
 *        host master   — one trigger_pulse starts both the DMD sequence and the camera exposure;
 *        DMD master    — the DMD is started (params.dmd_start, or the trigger output wired to the DMD's trigger
 *                        input when NULL); the DMD's own trigger output starts the camera;
 *        camera master — the DMD is armed (params.dmd; NULL for a dark frame) after the drain, and the first
 *                        strobe of the free-running camera after the arm starts it; the snapshot is the frame
 *                        whose exposure began after the arm (one that began during the arm call only if the DMD's
 *                        first edge followed it);
 *   3. waits for the frame that belongs to the start (timestamps after it), then keeps reading GPIO edges until
 *      the planned end of the DMD sequence plus params.settle_ns;
 *   4. builds the exposure window (from the strobe edges when wired, else estimated from the frame timestamp,
 *      the exposure setting and params.readout_ns) and the sync report.
 * The camera must be streaming (camera_start) and set to the external-trigger mode that the sync mode needs
 * (host and DMD master) or free run (camera master).
 *
 * The DMD side: the DMD enters as (a) the timeline of patterns it was told to play (sync_timeline, built from its
 * dmd_timing by capture_timeline_from_dmd; this function places it in time) and (b) in DMD- and camera-master
 * mode, the dmd handle to start or arm (drivers/dmd.h). Uploading masks, setting the timing (external trigger for host and camera
 * master) and stopping stay with the caller.
 *
 * Return: 0 with a complete snapshot (check out->report.broken: a broken sync is flagged, never hidden), or a
 * negative code with err naming the device: -ETIMEDOUT (no frame after the start: the camera missed its trigger;
 * out->report then carries SYNC_FLAG_NO_FRAME and the edges that were seen), or whatever the camera or trigger
 * returned (-ENODEV from the camera, out->dmd_failed 0: call camera_recover). Blocks for about exposure + settle time. Not thread-safe per camera.
 */
#ifndef SCICAP_DRIVERS_CAPTURE_H
#define SCICAP_DRIVERS_CAPTURE_H

#include <jansson.h>
#include <stdint.h>

#include "base/error.h"
#include "drivers/camera.h"
#include "drivers/dmd.h"
#include "drivers/sync.h"
#include "drivers/trigger.h"


#define CAPTURE_MAX_EVENTS 4096

typedef struct capture_params {
    enum sync_mode mode;
    const sync_timeline *timeline; /* patterns as the DMD was told to play them; start_ns is ignored (borrowed) */
    int64_t dmd_latency_ns;   /* expected delay from the start (pulse, DMD start call, or strobe) to pattern 0 */
    uint32_t pulse_width_us;  /* trigger output pulse; 0: 10 µs */
    int64_t frame_timeout_ns; /* from the start (the arm call's end) to the frame; 0: exposure + sequence + 1 s */
    int64_t settle_ns;        /* after the sequence end, how long edges may still arrive; 0: 1 ms */
    int64_t readout_ns;       /* exposure end to EOF timestamp, for the estimated window (no strobe) */
    sync_tolerance tolerance;
    dmd *dmd;                 /* DMD master: dmd_start() starts the sequence; NULL: trigger_pulse (the output
                                 wired to the DMD's trigger input). Camera master: dmd_start() arms the DMD after
                                 the stale frames are drained, so the next strobe starts it; NULL: nothing armed
                                 here (a dark frame). Host master: unused (arm before the call). Borrowed. */
} capture_params;

/* Defaults above, with sync_tolerance_default(). */
capture_params capture_params_default(void);

typedef struct capture_snapshot {
    camera_frame frame;        /* owned: reuse the snapshot across calls, free with capture_snapshot_release */
    sync_report report;
    sync_timeline plan;        /* the timeline as placed in time (start_ns = start + dmd_latency_ns) */
    enum sync_mode mode;
    int64_t start_ns;          /* host's start (pulse or DMD start); camera master: the kept exposure's start (the
                                  strobe's rising edge, else estimated), the arm when no frame came */
    int dmd_failed;            /* the error came from starting or arming the DMD, not from the camera */
    uint32_t stale_frames;     /* frames drained before the start, or that ended before it */
    int dmd_edges, strobe_edges; /* rising edges seen on each input */
    uint64_t lost_events;      /* GPIO edges lost (line_seqno gaps) during this snapshot */
    camera_identity camera_id;
    trigger_identity trigger_id;
} capture_snapshot;

void capture_snapshot_release(capture_snapshot *s);

/* The DMD's timing as a sync timeline of `count` patterns (per-pattern arrays win over the scalars).
 * -EINVAL for a count outside 1..SYNC_MAX_PATTERNS or a zero exposure. */
int capture_timeline_from_dmd(const dmd_timing *t, int count, sync_timeline *out, sci_error *err);

int capture_snapshot_take(camera *cam, trigger *trig, const capture_params *p, capture_snapshot *out, sci_error *err);

/* Per-snapshot metadata for meta.json: mode, start, frame metadata (exposure, gain, timestamp, sequence, drops),
 * sync report, device identities. New reference; NULL on ENOMEM. */
json_t *capture_snapshot_meta_json(const capture_snapshot *s);

#endif
