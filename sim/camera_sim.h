/* sim/camera_sim.h — a simulated camera behind the same camera_ops interface as the V4L2 backend.
 *
 * It behaves like a V4L2 capture device seen through drivers/camera.h: it offers formats and sizes, negotiates
 * through the same choice functions as the V4L2 backend (drivers/v4l2_util.h), streams into a small ring of
 * buffers (frames that find every buffer full are dropped and their sequence numbers skipped, as a V4L2 driver
 * does), stamps frames with CLOCK_MONOTONIC timestamps (end of frame by default) and a 32-bit sequence, and packs
 * every frame into the negotiated wire format so that the capture path unpacks it exactly as it would a real
 * buffer.
 *
 * Timing is real time, computed lazily: nothing runs between calls; camera_wait_frame works out which exposures
 * have finished by now and sleeps until the next one (or the timeout). Two exposure schedules:
 *   - free run (control "trigger_mode" = 0, the default): exposure k starts at stream start + k · frame interval;
 *   - external trigger ("trigger_mode" = 1): each camera_sim_trigger(t) starts an exposure at t + trigger latency;
 *     a trigger that comes while the sensor is still exposing or reading out is ignored, as sensors do.
 *
 * Images come from a frame-source callback (a scene renderer integrating what the simulated DMD showed during
 * [start_ns, end_ns]); without one, a fixed ramp is packed once and reused (so a benchmark measures the capture
 * path, not the renderer). Exposures are announced to a strobe callback (start and end of each exposure), which a
 * test wires to the simulated trigger's strobe input.
 *
 * Faults on demand: drop frames (sequence gap), stall (exposures that never happen: a missed trigger, the caller
 * sees a timeout), corrupt frames (error flag), disconnect (every call fails with -ENODEV until camera_recover
 * succeeds, which it does once camera_sim_replug is called).
 *
 * Threads: like every camera, one thread at a time; the callbacks run on the caller's thread, inside
 * camera_wait_frame or camera_sim_trigger.
 */
#ifndef SCICAP_SIM_CAMERA_SIM_H
#define SCICAP_SIM_CAMERA_SIM_H

#include <stdint.h>

#include "drivers/camera.h"

extern const camera_ops camera_sim_ops;

typedef struct camera_sim camera_sim;

/* One exposure, as the frame source and the strobe see it. */
typedef struct camera_sim_exposure {
    uint32_t sequence;
    int64_t start_ns, end_ns; /* CLOCK_MONOTONIC */
    uint32_t exposure_us;
    int32_t gain;
} camera_sim_exposure;

/* Fill w*h samples (values below 2^bits) for exposure e. Return 0, or a negative code with err set (the frame is
 * then reported to the caller as that error). */
typedef int (*camera_sim_source_fn)(void *arg, const camera_sim_exposure *e, uint16_t *samples, uint32_t w,
                                    uint32_t h, int bits, sci_error *err);
/* An exposure happened (or is scheduled to happen: timestamps may lie in the future). */
typedef void (*camera_sim_strobe_fn)(void *arg, const camera_sim_exposure *e);

typedef struct camera_sim_options {
    const char *card;            /* identity card name; NULL: "scicap simulated camera" */
    uint32_t max_width, max_height; /* 0: 4096 x 3072 */
    const enum pixfmt *formats;  /* offered formats; NULL: all five */
    int format_count;
    int64_t readout_ns;          /* exposure end to frame ready (the EOF timestamp); default 0 */
    int64_t trigger_latency_ns;  /* external trigger to exposure start */
    int timestamp_soe;           /* 1: timestamps mark the start of exposure instead of end of frame */
    uint32_t first_sequence;     /* sequence of the first frame after start (test the 32-bit wrap) */
    int unpaced;                 /* free run only: a frame is always ready at once (throughput benchmarks) */
    camera_sim_source_fn source;
    void *source_arg;
    camera_sim_strobe_fn strobe;
    void *strobe_arg;
} camera_sim_options;

enum camera_sim_fault {
    CAMERA_SIM_FAULT_DROP = 0,   /* the next n frames are exposed, numbered and lost (a sequence gap) */
    CAMERA_SIM_FAULT_STALL,      /* the next n exposures do not happen at all (missed trigger; waits time out) */
    CAMERA_SIM_FAULT_CORRUPT,    /* the next n frames carry the error flag */
    CAMERA_SIM_FAULT_DISCONNECT, /* unplugged now (n ignored) */
};

/* The simulator behind `cam`, or NULL if cam is not a simulated camera. Borrowed, lives as long as cam. */
camera_sim *camera_sim_from(camera *cam);
void camera_sim_fault(camera_sim *s, enum camera_sim_fault fault, int n);
/* Plug the device back in: the next camera_recover succeeds. */
void camera_sim_replug(camera_sim *s);
/* An edge on the external trigger input at t_ns. Returns 1 if it started an exposure, 0 if ignored (not in
 * trigger mode, not streaming, busy, or stalled by a fault). */
int camera_sim_trigger(camera_sim *s, int64_t t_ns);

typedef struct camera_sim_counters {
    uint64_t exposures;  /* exposures that happened */
    uint64_t dropped;    /* numbered but lost (fault or full ring) */
    uint64_t ignored_triggers;
} camera_sim_counters;
void camera_sim_counters_get(const camera_sim *s, camera_sim_counters *out);

#endif
