/* drivers/camera_skeleton.c — the template for a new camera backend. Copy it to camera_<name>.c, rename the
 * skel_ prefix, fill each function, declare `extern const camera_ops camera_<name>_ops;` in camera_<name>.h and
 * list it in drivers/backends.c (the config then finds it by its `name`).
 *
 * Rules every backend keeps (drivers/camera.h has the full contract):
 *   - all state lives in the object that open() allocates; no statics, no globals;
 *   - never print, never exit: return 0 or a negative code and fill err naming the device;
 *   - set_format reports what the device accepted, and refuses (-ENOTSUP) rather than silently changing it;
 *   - exposure in µs, timestamps in ns of CLOCK_MONOTONIC, samples unscaled with bits_per_sample set;
 *   - wait_frame fills every camera_frame field except lost_before/lost_total (the front end counts those from
 *     the sequence numbers, so a backend must pass the device's own frame counter through untouched); the pixels
 *     go through camera_frame_unpack, the one conversion from the wire every backend shares;
 *   - recover reopens after -ENODEV/-EIO and restores format, then camera_recover_controls puts exposure, gain
 *     and streaming back.
 * This skeleton opens nothing and refuses everything, so it is safe to link. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/camera.h"

typedef struct skel_cam {
    char path[128];
    camera_format fmt;
    uint32_t exposure_us;
    int32_t gain;
    int streaming;
} skel_cam;

static int skel_open(void **state, const camera_config *cfg, sci_error *err)
{
    /* A real backend opens cfg->device (or finds cfg->card / cfg->bus_info), checks it is a capture device and
     * applies cfg->trigger_profile here. */
    return sci_error_set(err, -ENOTSUP, "%s: the skeleton camera backend is a template, not a device",
                         cfg->device ? cfg->device : "skeleton");
}

static void skel_close(void *state) { free(state); }

static void skel_identity(void *state, camera_identity *out)
{
    skel_cam *c = state;
    memset(out, 0, sizeof *out);
    snprintf(out->backend, sizeof out->backend, "skeleton");
    snprintf(out->path, sizeof out->path, "%s", c->path);
}

static int skel_set_format(void *state, const camera_config *want, camera_format *out, sci_error *err)
{
    skel_cam *c = state;
    return sci_error_set(err, -ENOTSUP, "%s: set_format not implemented", c->path);
}

static int skel_set_exposure(void *state, uint32_t *exposure_us, sci_error *err)
{
    skel_cam *c = state;
    return sci_error_set(err, -ENOTSUP, "%s: set_exposure_us not implemented", c->path);
}

static int skel_set_gain(void *state, int32_t *gain, sci_error *err)
{
    skel_cam *c = state;
    return sci_error_set(err, -ENOTSUP, "%s: set_gain not implemented", c->path);
}

static int skel_start(void *state, sci_error *err)
{
    skel_cam *c = state;
    return sci_error_set(err, -ENOTSUP, "%s: start not implemented", c->path);
}

static int skel_stop(void *state, sci_error *err)
{
    skel_cam *c = state;
    c->streaming = 0;
    return 0;
}

static int skel_wait_frame(void *state, int64_t timeout_ns, camera_frame *out, sci_error *err)
{
    /* A real backend waits for a buffer, then camera_frame_unpack(out, &c->fmt, buf, bytesused, stride, err),
     * gives the buffer back, and sets sequence, timestamp_ns, ts_source, corrupt, exposure_us and gain. */
    skel_cam *c = state;
    return sci_error_set(err, -ENOTSUP, "%s: wait_frame not implemented", c->path);
}

static int skel_recover(void *state, sci_error *err)
{
    /* A real backend reopens, re-applies its trigger profile and c->fmt, then ends with
     * camera_recover_controls(&camera_<name>_ops, c, c->exposure_us, c->gain, was_streaming, err). */
    skel_cam *c = state;
    return sci_error_set(err, -ENOTSUP, "%s: recover not implemented", c->path);
}

const camera_ops camera_skeleton_ops = {
    .name = "skeleton",
    .open = skel_open,
    .close = skel_close,
    .identity = skel_identity,
    .set_format = skel_set_format,
    .set_exposure_us = skel_set_exposure,
    .set_gain = skel_set_gain,
    .start = skel_start,
    .stop = skel_stop,
    .wait_frame = skel_wait_frame,
    .recover = skel_recover,
};
