#include "drivers/camera.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct camera {
    const camera_ops *ops;
    void *state;
    camera_identity id;
    camera_format fmt;
    uint32_t exposure_us;
    int32_t gain;
    int streaming;
    seqgap gaps;
    camera_stats stats;
};

camera_config camera_config_default(void)
{
    camera_config c;
    memset(&c, 0, sizeof c);
    c.gain = -1;
    return c;
}

void camera_frame_release(camera_frame *f)
{
    if (!f)
        return;
    free(f->data);
    f->data = NULL;
    f->capacity = 0;
}

int camera_frame_reserve(camera_frame *f, uint32_t w, uint32_t h, sci_error *err)
{
    if (w == 0 || h == 0 || (size_t)w > SIZE_MAX / sizeof(uint16_t) / h)
        return sci_error_set(err, -EOVERFLOW, "frame: size %ux%u is not allocatable", w, h);
    size_t n = (size_t)w * h;
    if (n <= f->capacity && f->data)
        return 0;
    uint16_t *d = malloc(n * sizeof *d);
    if (!d)
        return sci_error_set(err, -ENOMEM, "frame: no memory for %ux%u samples", w, h);
    free(f->data);
    f->data = d;
    f->capacity = n;
    return 0;
}

int camera_frame_unpack(camera_frame *f, const camera_format *fmt, const void *src, size_t len, size_t stride,
                        sci_error *err)
{
    int rc = camera_frame_reserve(f, fmt->width, fmt->height, err);
    if (rc == 0)
        rc = pixfmt_unpack(fmt->pixfmt, src, len, stride, fmt->width, fmt->height, f->data, err);
    if (rc < 0)
        return rc;
    f->width = fmt->width;
    f->height = fmt->height;
    f->bits_per_sample = fmt->bits_per_sample;
    f->pixfmt = fmt->pixfmt;
    return 0;
}

camera_config camera_config_format_request(uint32_t width, uint32_t height, enum pixfmt pixfmt,
                                           const camera_config *want)
{
    camera_config c = camera_config_default();
    c.width = width;
    c.height = height;
    c.pixfmt = pixfmt;
    c.interval_num = want->interval_num;
    c.interval_den = want->interval_den;
    return c;
}

int camera_recover_controls(const camera_ops *ops, void *state, uint32_t exposure_us, int32_t gain,
                            int was_streaming, sci_error *err)
{
    int rc;
    if (exposure_us && (rc = ops->set_exposure_us(state, &exposure_us, err)) < 0)
        return rc;
    if (gain >= 0 && (rc = ops->set_gain(state, &gain, err)) < 0)
        return rc;
    return was_streaming ? ops->start(state, err) : 0;
}

int camera_open(camera **out, const camera_ops *ops, const camera_config *cfg, sci_error *err)
{
    *out = NULL;
    camera *cam = calloc(1, sizeof *cam);
    if (!cam)
        return sci_error_set(err, -ENOMEM, "camera: out of memory");
    cam->ops = ops;
    cam->gain = -1;
    int rc = ops->open(&cam->state, cfg, err);
    if (rc < 0)
        goto fail_free;
    ops->identity(cam->state, &cam->id);
    if ((rc = camera_set_format(cam, cfg, err)) < 0)
        goto fail_close;
    if (cfg->exposure_us) {
        uint32_t e = cfg->exposure_us;
        if ((rc = camera_set_exposure_us(cam, &e, err)) < 0)
            goto fail_close;
    }
    if (cfg->gain >= 0) {
        int32_t g = cfg->gain;
        if ((rc = camera_set_gain(cam, &g, err)) < 0)
            goto fail_close;
    }
    *out = cam;
    return 0;
fail_close:
    ops->close(cam->state);
fail_free:
    free(cam);
    return rc;
}

void camera_close(camera *cam)
{
    if (!cam)
        return;
    if (cam->streaming)
        cam->ops->stop(cam->state, NULL);
    cam->ops->close(cam->state);
    free(cam);
}

void camera_identity_get(const camera *cam, camera_identity *out) { *out = cam->id; }
void camera_format_get(const camera *cam, camera_format *out) { *out = cam->fmt; }
void camera_stats_get(const camera *cam, camera_stats *out) { *out = cam->stats; }
uint32_t camera_exposure_us(const camera *cam) { return cam->exposure_us; }
int32_t camera_gain(const camera *cam) { return cam->gain; }
int camera_is_streaming(const camera *cam) { return cam->streaming; }

void *camera_backend_state(camera *cam, const camera_ops *ops)
{
    return (cam && cam->ops == ops) ? cam->state : NULL;
}

int camera_set_format(camera *cam, const camera_config *want, sci_error *err)
{
    if (cam->streaming)
        return sci_error_set(err, -EBUSY, "%s: cannot change the format while streaming", cam->id.path);
    camera_format f;
    memset(&f, 0, sizeof f);
    int rc = cam->ops->set_format(cam->state, want, &f, err);
    if (rc < 0)
        return rc;
    cam->fmt = f;
    return 0;
}

int camera_set_exposure_us(camera *cam, uint32_t *exposure_us, sci_error *err)
{
    if (*exposure_us == 0)
        return sci_error_set(err, -EINVAL, "%s: exposure must be > 0 us", cam->id.path);
    int rc = cam->ops->set_exposure_us(cam->state, exposure_us, err);
    if (rc == 0)
        cam->exposure_us = *exposure_us;
    return rc;
}

int camera_set_gain(camera *cam, int32_t *gain, sci_error *err)
{
    int rc = cam->ops->set_gain(cam->state, gain, err);
    if (rc == 0)
        cam->gain = *gain;
    return rc;
}

int camera_start(camera *cam, sci_error *err)
{
    if (cam->streaming)
        return 0;
    int rc = cam->ops->start(cam->state, err);
    if (rc < 0)
        return rc;
    seqgap_reset(&cam->gaps);
    cam->streaming = 1;
    return 0;
}

int camera_stop(camera *cam, sci_error *err)
{
    if (!cam->streaming)
        return 0;
    cam->streaming = 0; /* even on error: the stream is unusable either way */
    return cam->ops->stop(cam->state, err);
}

int camera_wait_frame(camera *cam, int64_t timeout_ns, camera_frame *out, sci_error *err)
{
    if (!cam->streaming)
        return sci_error_set(err, -EINVAL, "%s: wait for a frame while not streaming", cam->id.path);
    int rc = cam->ops->wait_frame(cam->state, timeout_ns < 0 ? 0 : timeout_ns, out, err);
    if (rc == -ETIMEDOUT) {
        cam->stats.timeouts++;
        return rc;
    }
    if (rc < 0) {
        cam->stats.errors++;
        return rc;
    }
    out->lost_before = seqgap_push(&cam->gaps, out->sequence);
    out->lost_total = cam->gaps.lost;
    cam->stats.frames++;
    cam->stats.lost += out->lost_before;
    if (out->corrupt)
        cam->stats.corrupt++;
    return 0;
}

int camera_recover(camera *cam, sci_error *err)
{
    int rc = cam->ops->recover(cam->state, err);
    if (rc < 0)
        return rc;
    cam->ops->identity(cam->state, &cam->id);
    if (cam->streaming)
        seqgap_reset(&cam->gaps); /* the driver restarted its count with the stream */
    cam->stats.recoveries++;
    return 0;
}

static const char *ts_source_name(enum camera_ts_source s)
{
    return s == CAMERA_TS_EOF ? "end_of_frame" : s == CAMERA_TS_SOE ? "start_of_exposure" : "unknown";
}

json_t *camera_frame_meta_json(const camera_frame *f)
{
    return json_pack("{s:i, s:i, s:s, s:i, s:I, s:I, s:s, s:I, s:I, s:b, s:I, s:I}", "width", (int)f->width,
                     "height", (int)f->height, "pixel_format", pixfmt_name(f->pixfmt), "bits_per_sample",
                     f->bits_per_sample, "sequence", (json_int_t)f->sequence, "timestamp_ns",
                     (json_int_t)f->timestamp_ns, "timestamp_source", ts_source_name(f->ts_source), "lost_before",
                     (json_int_t)f->lost_before, "lost_total", (json_int_t)f->lost_total, "corrupt", f->corrupt,
                     "exposure_us", (json_int_t)f->exposure_us, "gain", (json_int_t)f->gain);
}

json_t *camera_identity_json(const camera_identity *id)
{
    return json_pack("{s:s, s:s, s:s, s:s, s:s, s:I}", "backend", id->backend, "driver", id->driver, "card",
                     id->card, "bus_info", id->bus_info, "path", id->path, "version", (json_int_t)id->version);
}

/* --- config from JSON --- */

static int cfg_fail(sci_error *err, const char *where, const char *key, const char *what)
{
    return sci_error_set(err, SCI_ECONFIG, "%s.%s: %s", where, key, what);
}

static int cfg_uint(const json_t *obj, const char *where, const char *key, long long min, long long max,
                    long long *out, sci_error *err)
{
    const json_t *v = json_object_get(obj, key);
    if (!v)
        return 1;
    if (!json_is_integer(v))
        return cfg_fail(err, where, key, "must be an integer");
    long long x = json_integer_value(v);
    if (x < min || x > max)
        return sci_error_set(err, SCI_ECONFIG, "%s.%s: %lld is outside %lld..%lld", where, key, x, min, max);
    *out = x;
    return 0;
}

static int cfg_str(const json_t *obj, const char *where, const char *key, const char **out, sci_error *err)
{
    const json_t *v = json_object_get(obj, key);
    if (!v)
        return 1;
    if (!json_is_string(v))
        return cfg_fail(err, where, key, "must be a string");
    *out = json_string_value(v);
    return 0;
}

int camera_config_from_json(const json_t *obj, const char *where, camera_config *out, sci_error *err)
{
    static const char *const keys[] = {"device", "card", "bus_info", "width", "height", "format", "fps", "interval",
                                       "exposure_us", "gain", "buffers", "trigger_profile", NULL};
    *out = camera_config_default();
    if (!json_is_object(obj))
        return sci_error_set(err, SCI_ECONFIG, "%s: must be an object", where);
    const char *k;
    const json_t *v;
    json_object_foreach((json_t *)obj, k, v) {
        int known = 0;
        for (int i = 0; keys[i]; i++)
            known |= strcmp(k, keys[i]) == 0;
        if (!known)
            return sci_error_set(err, SCI_ECONFIG, "%s.%s: unknown key", where, k);
    }
    long long x = 0;
    int rc;
    const char *s = NULL;
    if ((rc = cfg_str(obj, where, "device", &out->device, err)) < 0 ||
        (rc = cfg_str(obj, where, "card", &out->card, err)) < 0 ||
        (rc = cfg_str(obj, where, "bus_info", &out->bus_info, err)) < 0)
        return rc;
    if ((rc = cfg_uint(obj, where, "width", 1, 65535, &x, err)) < 0)
        return rc;
    if (rc == 0)
        out->width = (uint32_t)x;
    if ((rc = cfg_uint(obj, where, "height", 1, 65535, &x, err)) < 0)
        return rc;
    if (rc == 0)
        out->height = (uint32_t)x;
    if ((rc = cfg_str(obj, where, "format", &s, err)) < 0)
        return rc;
    if (rc == 0 && pixfmt_from_name(s, &out->pixfmt, NULL) < 0)
        return sci_error_set(err, SCI_ECONFIG, "%s.format: \"%s\" is not one of GREY, Y10, Y12, Y16, Y10P", where, s);
    if ((rc = cfg_uint(obj, where, "fps", 1, 100000, &x, err)) < 0)
        return rc;
    if (rc == 0) {
        out->interval_num = 1;
        out->interval_den = (uint32_t)x;
    }
    const json_t *iv = json_object_get(obj, "interval");
    if (iv) {
        if (!json_is_array(iv) || json_array_size(iv) != 2 || !json_is_integer(json_array_get(iv, 0)) ||
            !json_is_integer(json_array_get(iv, 1)) || json_integer_value(json_array_get(iv, 0)) < 1 ||
            json_integer_value(json_array_get(iv, 1)) < 1)
            return cfg_fail(err, where, "interval", "must be [numerator, denominator] of seconds, both >= 1");
        out->interval_num = (uint32_t)json_integer_value(json_array_get(iv, 0));
        out->interval_den = (uint32_t)json_integer_value(json_array_get(iv, 1));
    }
    if ((rc = cfg_uint(obj, where, "exposure_us", 1, 60000000, &x, err)) < 0)
        return rc;
    if (rc == 0)
        out->exposure_us = (uint32_t)x;
    if ((rc = cfg_uint(obj, where, "gain", 0, INT32_MAX, &x, err)) < 0)
        return rc;
    if (rc == 0)
        out->gain = (int32_t)x;
    if ((rc = cfg_uint(obj, where, "buffers", 2, CAMERA_MAX_BUFFERS, &x, err)) < 0)
        return rc;
    if (rc == 0)
        out->buffer_count = (int)x;
    const json_t *tp = json_object_get(obj, "trigger_profile");
    if (tp) {
        const json_t *name = json_object_get(tp, "name"), *ctrls = json_object_get(tp, "controls");
        if (!json_is_object(tp) || (name && !json_is_string(name)) || !json_is_object(ctrls))
            return cfg_fail(err, where, "trigger_profile", "must be {\"name\": string, \"controls\": {name: integer}}");
        out->trigger_profile_name = name ? json_string_value(name) : NULL;
        json_object_foreach((json_t *)ctrls, k, v) {
            if (!json_is_integer(v) && !json_is_boolean(v))
                return sci_error_set(err, SCI_ECONFIG, "%s.trigger_profile.controls.%s: must be an integer", where, k);
            if (out->trigger_profile_count >= CAMERA_MAX_CONTROLS)
                return sci_error_set(err, SCI_ECONFIG, "%s.trigger_profile.controls: more than %d controls", where,
                                     CAMERA_MAX_CONTROLS);
            camera_control *c = &out->trigger_profile[out->trigger_profile_count++];
            c->name = k;
            c->value = json_is_boolean(v) ? json_is_true(v) : json_integer_value(v);
        }
    }
    return 0;
}
