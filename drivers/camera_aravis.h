/* drivers/camera_aravis.h — the GenICam camera backend (GigE Vision, USB3 Vision) on Aravis 0.8.
 *
 * Behind the same camera_ops table as V4L2: camera_open(&cam, &camera_aravis_ops, &cfg, &err). What the
 * camera_config fields mean here:
 *
 *   device     Aravis device id ("Basler-21234567", "Aravis-Fake-GV01", as arv-camera-test-0.8 prints it), or a
 *              GigE Vision camera's IP address ("192.168.2.10", "127.0.0.1"). "Fake_1" is Aravis's in-process
 *              simulated camera: naming it enables Aravis's "Fake" interface (off by default), nothing else does.
 *              NULL: the first camera whose model equals `card` and/or serial number equals `bus_info`, or with
 *              neither given, the first camera found.
 *   width, height   the Width/Height features (0: keep); outside the camera's bounds or off its increment is
 *              -ENOTSUP naming the bounds.
 *   pixfmt     GenICam PixelFormat: GREY = Mono8, Y10 = Mono10, Y12 = Mono12, Y16 = Mono16 (unpacked, little-endian
 *              16-bit containers) and the Bayer formats SRGGB8 = BayerRG8, SGRBG8 = BayerGR8, SGBRG8 = BayerGB8,
 *              SBGGR8 = BayerBG8 and the same for 10, 12 and 16 bits. Packed GenICam formats (Mono10p, Mono12Packed,
 *              ...) are not taken (their bit order is not MIPI's Y10P); Y10P is -ENOTSUP. PIXFMT_NONE: the best
 *              the camera offers — Mono16, Mono12, Mono10, Mono8, then Bayer 16, 12, 10, 8 — -ENOTSUP listing the
 *              offered formats when none is measurable. Frames of Bayer formats stay raw mosaics.
 *   interval   AcquisitionFrameRate = den/num (Aravis clamps to the camera's bounds; the rate in force is read
 *              back into camera_format.interval_*, as 1000/round(fps*1000) s).
 *   exposure_us  ExposureTime (or ExposureTimeAbs), auto exposure off first when the camera has it; the applied
 *              value is read back (rounded to µs). Outside the bounds: -ERANGE naming them.
 *   gain       Gain (or GainRaw) in the camera's own units (dB for most "Gain" features), rounded to an integer;
 *              auto gain off first; read back. Outside the bounds: -ERANGE.
 *   buffer_count   buffers in the stream's pool (2..CAMERA_MAX_BUFFERS, 0: 4), each one payload in size.
 *   trigger_profile  GenICam features set in order after opening, by exact feature name: Integer, Enumeration
 *              (by its integer value), Boolean (0/1) or Float (the integer as a float) — TriggerDelay, LineSelector,
 *              ... A feature the camera lacks is -ENOTSUP naming it and the profile.
 *   backend_options  NULL or a const camera_aravis_options * (trigger, below; packet size).
 *
 * Trigger (camera_aravis_options.trigger), applied at every camera_start, after the format (Aravis's frame-rate
 * setter switches triggers off, so the order matters):
 *   FREE_RUN  every TriggerMode Off: the camera runs at its frame rate.
 *   SOFTWARE  TriggerSelector FrameStart, TriggerMode On, TriggerSource Software: one frame per
 *             camera_aravis_trigger_software().
 *   LINE      the same with TriggerSource = trigger_line ("Line0" if NULL) and TriggerActivation =
 *             trigger_activation when given ("RisingEdge", "FallingEdge"): the DMD's or a GPIO's pulse starts
 *             each exposure. Tests drive this path with the camera's software trigger (tests/aravis-gv/run).
 *
 * Streaming: camera_start creates the stream (GigE Vision: packet size negotiated, or options.packet_size),
 * pushes buffer_count buffers, and starts acquisition (Continuous). camera_wait_frame pops one completed buffer
 * (arv_stream_timeout_pop_buffer: blocks up to the timeout), unpacks it with pixfmt_unpack into the caller's frame
 * and pushes it back at once. Buffers that completed with an error status (missing packets, timeout, size
 * mismatch) are pushed back and counted as lost, never delivered.
 *
 * Frame metadata:
 *   sequence      a count of the frames the camera produced since camera_start, lost ones included, so that the
 *                 front end's sequence-gap counter (drivers/seqgap.h) sees every loss. GigE / USB3 Vision cameras
 *                 number every frame they send (the GenICam frame or block id; 16-bit ids wrap from 65535 to 1, 0
 *                 being invalid), so the gaps in the ids of delivered frames are the losses: frames that found no
 *                 free buffer (the caller did not keep up), frames lost on the wire, damaged ones. Aravis's
 *                 in-process fake numbers only the frames it filled: there the losses are Aravis's buffer
 *                 underruns, attributed to the frame that follows them, plus the discarded damaged buffers.
 *   timestamp_ns  host time at which Aravis received the frame (GigE Vision: its first packet, right after the
 *                 sensor's readout starts), CLOCK_REALTIME mapped to CLOCK_MONOTONIC at camera_wait_frame (the
 *                 mapping moves if the wall clock is stepped between reception and the call); ts_source EOF.
 *   corrupt       always 0 (damaged frames are dropped and counted instead).
 *
 * Errors: -ENOENT no such camera; -ENOTSUP format, size or feature the camera lacks; -ERANGE exposure or gain out
 * of bounds; -EBUSY format change while streaming, or another controller holds the camera (GigE Vision
 * privilege); -ETIMEDOUT no frame within the timeout; -ENODEV the camera stopped answering (GigE Vision
 * heartbeat / control lost): camera_recover reopens the same device id and reapplies format, exposure, gain,
 * profile and trigger, and restarts streaming if it was on. Every message names the device id.
 *
 * Threads: one thread per camera, as camera.h says. Aravis runs its own stream thread; the backend shares only
 * Aravis's queues and an atomic "control lost" flag with it. Backends never print; Aravis's own warnings go to
 * GLib's log (arv_debug_enable, ARV_DEBUG environment variable).
 */
#ifndef SCICAP_DRIVERS_CAMERA_ARAVIS_H
#define SCICAP_DRIVERS_CAMERA_ARAVIS_H

#include <jansson.h>
#include <stdint.h>

#include "drivers/camera.h"

extern const camera_ops camera_aravis_ops;

enum camera_aravis_trigger {
    CAMERA_ARAVIS_TRIGGER_FREE_RUN = 0,
    CAMERA_ARAVIS_TRIGGER_SOFTWARE,
    CAMERA_ARAVIS_TRIGGER_LINE
};

/* Backend options (camera_config.backend_options). Strings are borrowed for the duration of camera_open. */
typedef struct camera_aravis_options {
    enum camera_aravis_trigger trigger;
    const char *trigger_line;       /* TriggerSource for TRIGGER_LINE; NULL: "Line0" */
    const char *trigger_activation; /* TriggerActivation for TRIGGER_LINE ("RisingEdge"...); NULL: leave */
    uint32_t packet_size;           /* GigE Vision stream packet size in bytes; 0: negotiate the largest that passes */
} camera_aravis_options;

/* Parse the Aravis-specific keys of a camera config object:
 *   {"trigger": "free-run" | "software" | "line", "trigger_line": "Line1", "trigger_activation": "RisingEdge",
 *    "packet_size": 1500}
 * Absent keys keep the defaults (free run, Line0, leave activation, negotiate). Other keys are ignored (they are
 * camera_config_from_json's). Strings point into `obj` (borrowed). Errors: SCI_ECONFIG naming where.key. */
int camera_aravis_options_from_json(const json_t *obj, const char *where, camera_aravis_options *out, sci_error *err);

/* Parse a whole "aravis" camera object: the keys above and camera_config_from_json's, into both structs, and
 * point cfg->backend_options at *opt. Strings point into `obj`; keep obj, cfg and opt alive until camera_open
 * returns. Unknown keys are refused (SCI_ECONFIG naming them). */
int camera_aravis_config_from_json(const json_t *obj, const char *where, camera_config *cfg,
                                   camera_aravis_options *opt, sci_error *err);

/* Fire the camera's software trigger (TriggerSoftware command): one frame in SOFTWARE mode. -EINVAL if `cam` is
 * not an Aravis camera; -ENOTSUP if it has no TriggerSoftware; -ENODEV after control was lost. Does not block on
 * the frame. */
int camera_aravis_trigger_software(camera *cam, sci_error *err);

/* What Aravis reported for the current stream (zeros when not streaming): for diagnostics and tests. */
typedef struct camera_aravis_stream_stats {
    uint64_t completed;     /* buffers Aravis completed successfully */
    uint64_t failures;      /* buffers completed with an error status (discarded by the backend) */
    uint64_t underruns;     /* frames that found no free buffer */
    uint64_t id_gaps;       /* frames missing from the frame-id sequence of delivered frames */
    uint64_t last_frame_id; /* GenICam frame (block) id of the last delivered frame */
} camera_aravis_stream_stats;

/* -EINVAL if `cam` is not an Aravis camera. */
int camera_aravis_stream_stats_get(camera *cam, camera_aravis_stream_stats *out);

/* The ArvCamera underneath (borrowed: lives until camera_close or camera_recover), for features the interface
 * lacks and for tests (the fake camera's fill pattern). Do not start or stop acquisition or touch the stream
 * through it. NULL if `cam` is not an Aravis camera. */
struct _ArvCamera;
struct _ArvCamera *camera_aravis_arv_camera(camera *cam);

#endif
