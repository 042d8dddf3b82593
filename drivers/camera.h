/* drivers/camera.h — the camera interface: one monochrome frame at a time, with the metadata a measurement needs.
 *
 * A camera is a backend (a const camera_ops table: camera_v4l2_ops here, camera_sim_ops in sim/, the template in
 * camera_skeleton.c) plus its opaque state, held together by the opaque `camera` handle. Callers use the
 * camera_* functions below, never the table directly: they also keep the counters every backend shares (frames
 * lost from sequence gaps, timeouts, error-flagged frames).
 *
 *     camera_config cfg = camera_config_default();
 *     cfg.device = "/dev/v4l/by-id/usb-...-video-index0";
 *     cfg.width = 1920; cfg.height = 1080; cfg.pixfmt = PIXFMT_Y16; cfg.exposure_us = 5000;
 *     camera *cam;
 *     if (camera_open(&cam, &camera_v4l2_ops, &cfg, &err) < 0) ...
 *     camera_start(cam, &err);
 *     camera_frame fr = {0};
 *     while (camera_wait_frame(cam, 100 * 1000000LL, &fr, &err) == 0) ... fr.data, fr.sequence, fr.timestamp_ns
 *     camera_frame_release(&fr);
 *     camera_close(cam);
 *
 * Units: exposure in µs, timestamps in ns of CLOCK_MONOTONIC, frame interval as a fraction of a second, gain in
 * the device's own units (V4L2_CID_GAIN or V4L2_CID_ANALOGUE_GAIN value; the simulator scales counts by gain/100).
 *
 * Errors: 0 or a negative code with a message naming the device. Codes with a meaning of their own:
 * -ETIMEDOUT (no frame within the timeout: the trigger stalled or was missed), -ENODEV (the device is gone:
 * call camera_recover), -ENOTSUP (format or control the device lacks, or one scicap refuses), -EBUSY (the
 * device is streaming for someone else), -ENOTTY (the node is not a capture device).
 *
 * Threads: a camera is used by one thread at a time (the acquisition thread); different cameras are
 * independent. Backends never print and never exit.
 */
#ifndef SCICAP_DRIVERS_CAMERA_H
#define SCICAP_DRIVERS_CAMERA_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "drivers/pixfmt.h"
#include "drivers/seqgap.h"

#define CAMERA_MAX_CONTROLS 16
#define CAMERA_MAX_BUFFERS 32

/* A named control and the value to give it: one entry of a per-sensor trigger profile. Names match the
 * device's control names case-insensitively with spaces and underscores treated alike, so both
 * "Trigger Mode" and "trigger_mode" (v4l2-ctl's spelling) work. */
typedef struct camera_control {
    const char *name; /* borrowed for the duration of camera_open */
    int64_t value;
} camera_control;

/* Everything a backend needs to open a camera. Strings are borrowed for the duration of camera_open (the
 * backend copies what it keeps). Zero / NULL fields mean "leave as the device has it" unless stated. */
typedef struct camera_config {
    const char *device;   /* node path: "/dev/video0" or better "/dev/v4l/by-id/..."; NULL: find by card/bus */
    const char *card;     /* match VIDIOC_QUERYCAP card (exact) when device is NULL */
    const char *bus_info; /* match VIDIOC_QUERYCAP bus_info (exact) when device is NULL */
    uint32_t width, height;         /* pixels; 0: keep the device's */
    enum pixfmt pixfmt;             /* PIXFMT_NONE: first measurable format the device offers */
    uint32_t interval_num, interval_den; /* frame interval in s = num/den; 0/0: keep */
    uint32_t exposure_us;           /* manual exposure; 0: leave exposure alone (auto stays as it is) */
    int32_t gain;                   /* device units; -1: leave alone */
    int buffer_count;               /* mmap buffers, 2..CAMERA_MAX_BUFFERS; 0: 4 */
    const char *trigger_profile_name;      /* for messages ("imx296-ext"); may be NULL */
    camera_control trigger_profile[CAMERA_MAX_CONTROLS]; /* set in order right after opening */
    int trigger_profile_count;
    const void *backend_options;    /* backend-specific, borrowed (sim: const camera_sim_options *) */
} camera_config;

/* All fields zero except gain = -1 (leave alone). */
camera_config camera_config_default(void);

/* Parse a camera config object:
 *   {"device": "/dev/video0" | "card": "...", "bus_info": "...", "width": 1920, "height": 1080,
 *    "format": "Y16", "fps": 30 | "interval": [1, 30], "exposure_us": 5000, "gain": 0, "buffers": 4,
 *    "trigger_profile": {"name": "imx296-ext", "controls": {"trigger_mode": 1}}}
 * Strings point into `root` (borrowed: keep the document alive until camera_open returns). Errors are
 * SCI_ECONFIG naming the key; unknown keys are refused. `where` names the object in messages ("camera"). */
int camera_config_from_json(const json_t *obj, const char *where, camera_config *out, sci_error *err);

/* Who the camera is, for metadata. */
typedef struct camera_identity {
    char backend[16];   /* "v4l2", "sim" */
    char driver[32];    /* VIDIOC_QUERYCAP driver */
    char card[64];      /* VIDIOC_QUERYCAP card */
    char bus_info[64];  /* VIDIOC_QUERYCAP bus_info */
    char path[256];     /* the node that was opened */
    uint32_t version;   /* driver version, KERNEL_VERSION-encoded; 0 if unknown */
} camera_identity;

/* The negotiated format (what the device accepted, which may differ from what was asked). */
typedef struct camera_format {
    uint32_t width, height;
    enum pixfmt pixfmt;
    int bits_per_sample;
    uint32_t bytesperline;  /* driver row stride in bytes (rows may be padded) */
    uint32_t sizeimage;     /* bytes per frame buffer */
    uint32_t interval_num, interval_den; /* 0/0 if the device does not say */
} camera_format;

enum camera_ts_source { CAMERA_TS_UNKNOWN = 0, CAMERA_TS_EOF, CAMERA_TS_SOE };

/* One frame. `data` is owned by the frame: camera_wait_frame (re)allocates it as needed, so reuse one frame for
 * a whole stream and free it once with camera_frame_release. */
typedef struct camera_frame {
    uint16_t *data;         /* width*height samples, row-major, unpadded, unscaled counts */
    size_t capacity;        /* samples allocated */
    uint32_t width, height;
    int bits_per_sample;    /* 8, 10, 12 or 16 */
    enum pixfmt pixfmt;     /* the wire format it came in */
    uint32_t sequence;      /* driver frame counter (counts dropped frames too) */
    int64_t timestamp_ns;   /* kernel timestamp, CLOCK_MONOTONIC */
    enum camera_ts_source ts_source; /* what instant timestamp_ns marks */
    uint32_t lost_before;   /* frames lost just before this one (sequence gap) */
    uint64_t lost_total;    /* frames lost since camera_start */
    int corrupt;            /* the driver flagged the buffer (V4L2_BUF_FLAG_ERROR): data may be damaged */
    uint32_t exposure_us;   /* exposure in force when the frame was taken */
    int32_t gain;           /* gain in force, -1 if unknown */
} camera_frame;

void camera_frame_release(camera_frame *f);

/* Counters since camera_open (not reset by start/stop or recover). */
typedef struct camera_stats {
    uint64_t frames;      /* delivered */
    uint64_t lost;        /* from sequence gaps */
    uint64_t corrupt;     /* error-flagged frames delivered */
    uint64_t timeouts;    /* camera_wait_frame that timed out */
    uint64_t errors;      /* other failures of camera_wait_frame */
    uint64_t recoveries;  /* successful camera_recover */
} camera_stats;

/* What a backend provides. `state` is the backend's own object, created by open. Each function returns 0 or a
 * negative code and fills err naming the device. wait_frame fills every camera_frame field except lost_before
 * and lost_total (the front end counts those from the sequence numbers). */
typedef struct camera_ops {
    const char *name;
    int (*open)(void **state, const camera_config *cfg, sci_error *err);
    void (*close)(void *state);
    void (*identity)(void *state, camera_identity *out);
    /* Negotiate width/height/pixfmt/interval (zero fields: keep); fills *out with what the device accepted.
     * Not while streaming (-EBUSY). */
    int (*set_format)(void *state, const camera_config *want, camera_format *out, sci_error *err);
    /* Manual exposure; *exposure_us is updated to the value the device applied. */
    int (*set_exposure_us)(void *state, uint32_t *exposure_us, sci_error *err);
    int (*set_gain)(void *state, int32_t *gain, sci_error *err);
    int (*start)(void *state, sci_error *err);
    int (*stop)(void *state, sci_error *err);
    int (*wait_frame)(void *state, int64_t timeout_ns, camera_frame *out, sci_error *err);
    /* After -ENODEV or -EIO: reopen the device, reapply format and controls, restart streaming if it was on. */
    int (*recover)(void *state, sci_error *err);
} camera_ops;

typedef struct camera camera;

/* The template backend (drivers/camera_skeleton.c): open always fails with -ENOTSUP. */
extern const camera_ops camera_skeleton_ops;

/* Open through `ops`, then apply format, exposure, gain and trigger profile from cfg. On failure nothing is
 * left open. The camera is not streaming afterwards. */
int camera_open(camera **out, const camera_ops *ops, const camera_config *cfg, sci_error *err);
/* Stop streaming if needed and release everything. NULL is harmless. */
void camera_close(camera *cam);

void camera_identity_get(const camera *cam, camera_identity *out);
/* The format in force (after the last set_format or open). */
void camera_format_get(const camera *cam, camera_format *out);
void camera_stats_get(const camera *cam, camera_stats *out);
/* The backend's state if `cam` runs on `ops`, else NULL: how sim/ reaches its simulator-only controls. */
void *camera_backend_state(camera *cam, const camera_ops *ops);

int camera_set_format(camera *cam, const camera_config *want, sci_error *err);
int camera_set_exposure_us(camera *cam, uint32_t *exposure_us, sci_error *err);
int camera_set_gain(camera *cam, int32_t *gain, sci_error *err);
uint32_t camera_exposure_us(const camera *cam);
int32_t camera_gain(const camera *cam);

/* Start streaming; resets the sequence-gap tracker (the driver restarts its count). */
int camera_start(camera *cam, sci_error *err);
int camera_stop(camera *cam, sci_error *err);
int camera_is_streaming(const camera *cam);

/* Wait up to timeout_ns (0: only take a frame already there) for the next frame and unpack it into *out.
 * Blocks. -ETIMEDOUT when none came; -ENODEV when the device went away. */
int camera_wait_frame(camera *cam, int64_t timeout_ns, camera_frame *out, sci_error *err);
/* Reconnect after -ENODEV / -EIO (see camera_ops.recover). */
int camera_recover(camera *cam, sci_error *err);

/* The frame's metadata (not the pixels) as a JSON object for meta.json; new reference, NULL on ENOMEM. */
json_t *camera_frame_meta_json(const camera_frame *f);
json_t *camera_identity_json(const camera_identity *id);

/* Make sure f->data holds at least w*h samples. -ENOMEM (f unchanged) or -EOVERFLOW. For backends. */
int camera_frame_reserve(camera_frame *f, uint32_t w, uint32_t h, sci_error *err);

/* For backends' wait_frame, the one conversion path from the wire: unpack a buffer of `len` bytes, rows `stride`
 * bytes apart, in the negotiated format `fmt` into f (data reserved as needed, samples unscaled) and set the
 * format fields (width, height, bits_per_sample, pixfmt). The backend fills the rest (sequence, timestamp,
 * ts_source, corrupt, exposure_us, gain). Errors as camera_frame_reserve and pixfmt_unpack; the format fields are
 * left as they were then. */
int camera_frame_unpack(camera_frame *f, const camera_format *fmt, const void *src, size_t len, size_t stride,
                        sci_error *err);

/* For backends' set_format: what to keep of a request so that recover can ask again — the negotiated width,
 * height and pixfmt and the frame interval asked for; every other field default (no borrowed string survives). */
camera_config camera_config_format_request(uint32_t width, uint32_t height, enum pixfmt pixfmt,
                                           const camera_config *want);

/* For backends' recover, once reconnected with profile and format back: put the manual exposure back (0: none was
 * set), then the gain (-1: none was set), through `ops` on `state`, and start streaming again if it was on. */
int camera_recover_controls(const camera_ops *ops, void *state, uint32_t exposure_us, int32_t gain,
                            int was_streaming, sci_error *err);

#endif
