#include "sim/camera_sim.h"

#include <errno.h>
#include <linux/videodev2.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "drivers/v4l2_util.h"

#define SIM_MAX_SCHEDULED 64
#define SIM_DEFAULT_W 640
#define SIM_DEFAULT_H 480

typedef struct sim_slot {
    camera_sim_exposure e;
    int64_t ready_ns;
    int corrupt;
} sim_slot;

struct camera_sim {
    camera_sim_options opt;
    char card[64], path[128];
    enum pixfmt formats[PIXFMT_COUNT];
    int nformats;
    camera_format fmt;
    uint32_t exposure_us;
    int32_t gain;
    int trigger_mode;
    int buffers;
    int streaming, unplugged, replugged;
    uint32_t next_seq;
    int64_t run_t0;    /* free run: start of exposure 0 */
    uint64_t run_k;    /* free run: next exposure index */
    int64_t busy_until; /* trigger mode: sensor exposing or reading out until then */
    sim_slot sched[SIM_MAX_SCHEDULED]; /* trigger mode: exposures scheduled, ascending ready time */
    int nsched;
    sim_slot ring[CAMERA_MAX_BUFFERS];
    int rhead, rn;
    int drop_n, stall_n, corrupt_n;
    camera_sim_counters counters;
    uint8_t *raw;          /* the "DMA buffer" in the wire format */
    size_t raw_cap;
    uint16_t *render;      /* the frame source's output before packing */
    size_t render_cap;
    int template_valid;    /* raw holds the default ramp for the current format */
};

static int sim_gone(const camera_sim *s, sci_error *err)
{
    return sci_error_set(err, -ENODEV, "%s: simulated camera is disconnected", s->path);
}

static int sim_open(void **state, const camera_config *cfg, sci_error *err)
{
    camera_sim *s = calloc(1, sizeof *s);
    if (!s)
        return sci_error_set(err, -ENOMEM, "sim camera: out of memory");
    if (cfg->backend_options)
        s->opt = *(const camera_sim_options *)cfg->backend_options;
    snprintf(s->card, sizeof s->card, "%s", s->opt.card ? s->opt.card : "scicap simulated camera");
    snprintf(s->path, sizeof s->path, "%s", cfg->device ? cfg->device : "sim-camera");
    if (!s->opt.max_width)
        s->opt.max_width = 4096;
    if (!s->opt.max_height)
        s->opt.max_height = 3072;
    if (s->opt.formats) {
        for (int i = 0; i < s->opt.format_count && i < PIXFMT_COUNT; i++)
            s->formats[s->nformats++] = s->opt.formats[i];
    } else {
        for (int f = PIXFMT_NONE + 1; f < PIXFMT_COUNT; f++)
            s->formats[s->nformats++] = (enum pixfmt)f;
    }
    s->opt.formats = NULL; /* borrowed pointers are not kept */
    s->opt.card = NULL;
    s->buffers = cfg->buffer_count ? cfg->buffer_count : 4;
    if (s->buffers < 2 || s->buffers > CAMERA_MAX_BUFFERS) {
        int n = s->buffers;
        free(s);
        return sci_error_set(err, -EINVAL, "%s: buffer count %d is outside 2..%d", cfg->device ? cfg->device : "sim",
                             n, CAMERA_MAX_BUFFERS);
    }
    s->fmt.width = SIM_DEFAULT_W;
    s->fmt.height = SIM_DEFAULT_H;
    s->fmt.interval_num = 1;
    s->fmt.interval_den = 30;
    s->exposure_us = 10000;
    s->gain = 100;
    s->next_seq = s->opt.first_sequence;
    for (int i = 0; i < cfg->trigger_profile_count; i++) {
        const camera_control *c = &cfg->trigger_profile[i];
        if (c->name && v4l2_util_ctrl_name_eq(c->name, "trigger_mode") && (c->value == 0 || c->value == 1)) {
            s->trigger_mode = (int)c->value;
            continue;
        }
        int rc = sci_error_set(err, -ENOTSUP, "%s: no control \"%s\" with value %lld (trigger profile \"%s\"; the "
                               "simulator knows trigger_mode 0 or 1)", s->path, c->name ? c->name : "(null)",
                               (long long)c->value, cfg->trigger_profile_name ? cfg->trigger_profile_name : "unnamed");
        free(s);
        return rc;
    }
    *state = s;
    return 0;
}

static void sim_close(void *state)
{
    camera_sim *s = state;
    if (!s)
        return;
    free(s->raw);
    free(s->render);
    free(s);
}

static void sim_identity(void *state, camera_identity *out)
{
    camera_sim *s = state;
    memset(out, 0, sizeof *out);
    snprintf(out->backend, sizeof out->backend, "sim");
    snprintf(out->driver, sizeof out->driver, "camera_sim");
    snprintf(out->card, sizeof out->card, "%s", s->card);
    snprintf(out->bus_info, sizeof out->bus_info, "sim:%s", s->path);
    snprintf(out->path, sizeof out->path, "%s", s->path);
}

static int sim_set_format(void *state, const camera_config *want, camera_format *out, sci_error *err)
{
    camera_sim *s = state;
    if (s->unplugged)
        return sim_gone(s, err);
    v4l2_util_fmtdesc offered[PIXFMT_COUNT];
    for (int i = 0; i < s->nformats; i++)
        offered[i] = (v4l2_util_fmtdesc){.fourcc = pixfmt_info_get(s->formats[i])->fourcc};
    enum pixfmt pf;
    int rc = v4l2_util_choose_format(offered, s->nformats, want->pixfmt, s->path, &pf, err);
    if (rc < 0)
        return rc;
    uint32_t w = s->fmt.width, h = s->fmt.height;
    if (want->width || want->height) {
        v4l2_util_framesize range = {.min_w = 1, .max_w = s->opt.max_width, .step_w = 1,
                                     .min_h = 1, .max_h = s->opt.max_height, .step_h = 1};
        if ((rc = v4l2_util_choose_size(&range, 1, want->width, want->height, s->path, &w, &h, err)) < 0)
            return rc;
    }
    if ((want->interval_num == 0) != (want->interval_den == 0))
        return sci_error_set(err, -EINVAL, "%s: frame interval %u/%u s: give both parts", s->path, want->interval_num,
                             want->interval_den);
    size_t stride = (pixfmt_min_stride(pf, w) + 31) / 32 * 32; /* padded rows, as many drivers do */
    size_t size = stride * h;
    if (size > s->raw_cap) {
        uint8_t *r = realloc(s->raw, size);
        if (!r)
            return sci_error_set(err, -ENOMEM, "%s: no memory for a %zu-byte buffer", s->path, size);
        s->raw = r;
        s->raw_cap = size;
    }
    s->fmt.width = w;
    s->fmt.height = h;
    s->fmt.pixfmt = pf;
    s->fmt.bits_per_sample = pixfmt_info_get(pf)->bits_per_sample;
    s->fmt.bytesperline = (uint32_t)stride;
    s->fmt.sizeimage = (uint32_t)size;
    if (want->interval_num) {
        s->fmt.interval_num = want->interval_num;
        s->fmt.interval_den = want->interval_den;
    }
    s->template_valid = 0;
    *out = s->fmt;
    return 0;
}

static int sim_set_exposure(void *state, uint32_t *exposure_us, sci_error *err)
{
    camera_sim *s = state;
    if (s->unplugged)
        return sim_gone(s, err);
    if (*exposure_us < 1 || *exposure_us > 10000000)
        return sci_error_set(err, -ERANGE, "%s: exposure %u us is outside 1..10000000", s->path, *exposure_us);
    s->exposure_us = *exposure_us;
    return 0;
}

static int sim_set_gain(void *state, int32_t *gain, sci_error *err)
{
    camera_sim *s = state;
    if (s->unplugged)
        return sim_gone(s, err);
    if (*gain < 0 || *gain > 1600)
        return sci_error_set(err, -ERANGE, "%s: gain %d is outside 0..1600", s->path, (int)*gain);
    s->gain = *gain;
    return 0;
}

static void sim_reset_stream(camera_sim *s)
{
    s->rn = s->rhead = 0;
    s->nsched = 0;
    s->run_t0 = sci_clock_mono_ns();
    s->run_k = 0;
    s->busy_until = 0;
    s->next_seq = s->opt.first_sequence;
}

static int sim_start(void *state, sci_error *err)
{
    camera_sim *s = state;
    if (s->unplugged)
        return sim_gone(s, err);
    sim_reset_stream(s);
    s->streaming = 1;
    return 0;
}

static int sim_stop(void *state, sci_error *err)
{
    camera_sim *s = state;
    s->streaming = 0;
    s->rn = s->nsched = 0;
    return s->unplugged ? sim_gone(s, err) : 0;
}

static int64_t sim_period_ns(const camera_sim *s)
{
    int64_t p = (int64_t)s->fmt.interval_num * 1000000000LL / (s->fmt.interval_den ? s->fmt.interval_den : 1);
    int64_t e = (int64_t)s->exposure_us * 1000;
    return p > e ? p : e; /* the exposure cannot outlast the frame period: the frame rate drops instead */
}

/* An exposure finished (its frame is ready): number it, then lose it or queue it. */
static void sim_complete(camera_sim *s, camera_sim_exposure e, int64_t ready_ns)
{
    e.sequence = s->next_seq++;
    s->counters.exposures++;
    if (s->drop_n > 0 || s->rn == s->buffers) { /* a fault, or every buffer full: the driver drops it */
        if (s->drop_n > 0)
            s->drop_n--;
        s->counters.dropped++;
        return;
    }
    sim_slot *slot = &s->ring[(s->rhead + s->rn) % CAMERA_MAX_BUFFERS];
    slot->e = e;
    slot->ready_ns = ready_ns;
    slot->corrupt = s->corrupt_n > 0;
    if (s->corrupt_n > 0)
        s->corrupt_n--;
    s->rn++;
}

/* Free run: exposure k of the current stream. */
static camera_sim_exposure sim_run_exposure(const camera_sim *s, uint64_t k)
{
    camera_sim_exposure e = {.exposure_us = s->exposure_us, .gain = s->gain};
    e.start_ns = s->run_t0 + (int64_t)k * sim_period_ns(s);
    e.end_ns = e.start_ns + (int64_t)s->exposure_us * 1000;
    return e;
}

/* Bring the simulation up to `now`: every exposure whose frame is ready by then completes. */
static void sim_produce(camera_sim *s, int64_t now)
{
    if (s->trigger_mode) {
        int done = 0;
        while (done < s->nsched && s->sched[done].ready_ns <= now) {
            sim_complete(s, s->sched[done].e, s->sched[done].ready_ns);
            done++;
        }
        memmove(s->sched, s->sched + done, (size_t)(s->nsched - done) * sizeof s->sched[0]);
        s->nsched -= done;
        return;
    }
    if (s->opt.unpaced) {
        while (s->rn == 0) { /* dropped frames (a fault) are numbered and skipped; each pass consumes one */
            camera_sim_exposure e = {.exposure_us = s->exposure_us, .gain = s->gain,
                                     .start_ns = now - (int64_t)s->exposure_us * 1000, .end_ns = now};
            if (s->opt.strobe)
                s->opt.strobe(s->opt.strobe_arg, &e);
            sim_complete(s, e, now);
        }
        return;
    }
    int64_t period = sim_period_ns(s);
    int64_t lag = (int64_t)s->exposure_us * 1000 + s->opt.readout_ns; /* exposure start to frame ready */
    while (s->run_t0 + (int64_t)s->run_k * period + lag <= now) {
        if (s->rn == s->buffers) {
            /* Every buffer full: all frames ready by now are lost. Counted in bulk (no strobe callbacks for
             * them) so that a consumer that paused for minutes does not cost a loop per missed frame. */
            uint64_t last = (uint64_t)((now - lag - s->run_t0) / period);
            uint64_t n = last - s->run_k + 1;
            s->next_seq += (uint32_t)n;
            s->counters.exposures += n;
            s->counters.dropped += n;
            s->run_k = last + 1;
            break;
        }
        camera_sim_exposure e = sim_run_exposure(s, s->run_k);
        s->run_k++;
        if (s->stall_n > 0) { /* the exposure never happened */
            s->stall_n--;
            continue;
        }
        if (s->opt.strobe)
            s->opt.strobe(s->opt.strobe_arg, &e);
        sim_complete(s, e, e.end_ns + s->opt.readout_ns);
    }
}

/* When the next frame will be ready, INT64_MAX if none is coming. */
static int64_t sim_next_ready(const camera_sim *s, int64_t now)
{
    if (s->trigger_mode)
        return s->nsched ? s->sched[0].ready_ns : INT64_MAX;
    if (s->opt.unpaced)
        return now;
    return s->run_t0 + (int64_t)s->run_k * sim_period_ns(s) + (int64_t)s->exposure_us * 1000 + s->opt.readout_ns;
}

int camera_sim_trigger(camera_sim *s, int64_t t_ns)
{
    if (!s->trigger_mode || !s->streaming || s->unplugged || t_ns < s->busy_until || s->nsched == SIM_MAX_SCHEDULED) {
        s->counters.ignored_triggers++;
        return 0;
    }
    if (s->stall_n > 0) {
        s->stall_n--;
        s->counters.ignored_triggers++;
        return 0;
    }
    sim_slot *slot = &s->sched[s->nsched++];
    slot->e = (camera_sim_exposure){.exposure_us = s->exposure_us, .gain = s->gain};
    slot->e.start_ns = t_ns + s->opt.trigger_latency_ns;
    slot->e.end_ns = slot->e.start_ns + (int64_t)s->exposure_us * 1000;
    slot->ready_ns = slot->e.end_ns + s->opt.readout_ns;
    slot->corrupt = 0;
    s->busy_until = slot->ready_ns;
    if (s->opt.strobe)
        s->opt.strobe(s->opt.strobe_arg, &slot->e);
    return 1;
}

static void sim_sleep_until(int64_t t_ns)
{
    struct timespec ts = {.tv_sec = t_ns / 1000000000LL, .tv_nsec = t_ns % 1000000000LL};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR)
        ;
}

static void sim_fill_template(camera_sim *s)
{
    /* a ramp over the full range, so every bit of the container is exercised */
    uint32_t w = s->fmt.width, h = s->fmt.height;
    uint32_t max = (1u << s->fmt.bits_per_sample) - 1u;
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++)
            s->render[(size_t)y * w + x] = (uint16_t)((uint64_t)(x + 2 * y) * max / (w + 2 * h));
}

static int sim_render(camera_sim *s, const camera_sim_exposure *e, sci_error *err)
{
    size_t n = (size_t)s->fmt.width * s->fmt.height;
    if (n > s->render_cap) {
        uint16_t *r = realloc(s->render, n * sizeof *r);
        if (!r)
            return sci_error_set(err, -ENOMEM, "%s: no memory to render a frame", s->path);
        s->render = r;
        s->render_cap = n;
    }
    if (!s->opt.source) {
        if (s->template_valid)
            return 0;
        sim_fill_template(s);
    } else {
        int rc = s->opt.source(s->opt.source_arg, e, s->render, s->fmt.width, s->fmt.height, s->fmt.bits_per_sample,
                               err);
        if (rc < 0)
            return rc;
    }
    int rc = pixfmt_pack(s->fmt.pixfmt, s->render, s->fmt.width, s->fmt.height, s->raw, s->fmt.sizeimage,
                         s->fmt.bytesperline, err);
    s->template_valid = rc == 0 && !s->opt.source;
    return rc;
}

static int sim_wait_frame(void *state, int64_t timeout_ns, camera_frame *out, sci_error *err)
{
    camera_sim *s = state;
    int64_t now = sci_clock_mono_ns(), deadline = now + timeout_ns;
    for (;;) {
        if (s->unplugged)
            return sim_gone(s, err);
        sim_produce(s, now);
        if (s->rn > 0)
            break;
        if (now >= deadline)
            return sci_error_set(err, -ETIMEDOUT, "%s: no frame within %.3f ms", s->path, (double)timeout_ns * 1e-6);
        int64_t next = sim_next_ready(s, now);
        sim_sleep_until(next < deadline ? next : deadline);
        now = sci_clock_mono_ns();
    }
    sim_slot slot = s->ring[s->rhead];
    s->rhead = (s->rhead + 1) % CAMERA_MAX_BUFFERS;
    s->rn--;
    int rc = sim_render(s, &slot.e, err);
    if (rc < 0)
        return rc;
    /* the capture path proper: unpack the wire format, as from a V4L2 mmap buffer */
    if ((rc = camera_frame_unpack(out, &s->fmt, s->raw, s->fmt.sizeimage, s->fmt.bytesperline, err)) < 0)
        return rc;
    out->sequence = slot.e.sequence;
    out->ts_source = s->opt.timestamp_soe ? CAMERA_TS_SOE : CAMERA_TS_EOF;
    out->timestamp_ns = s->opt.timestamp_soe ? slot.e.start_ns : slot.ready_ns;
    out->corrupt = slot.corrupt;
    out->exposure_us = slot.e.exposure_us;
    out->gain = slot.e.gain;
    return 0;
}

static int sim_recover(void *state, sci_error *err)
{
    camera_sim *s = state;
    if (s->unplugged && !s->replugged)
        return sci_error_set(err, -ENODEV, "%s: simulated camera is still disconnected", s->path);
    s->unplugged = s->replugged = 0;
    sim_reset_stream(s);
    return 0;
}

const camera_ops camera_sim_ops = {
    .name = "sim",
    .open = sim_open,
    .close = sim_close,
    .identity = sim_identity,
    .set_format = sim_set_format,
    .set_exposure_us = sim_set_exposure,
    .set_gain = sim_set_gain,
    .start = sim_start,
    .stop = sim_stop,
    .wait_frame = sim_wait_frame,
    .recover = sim_recover,
};

camera_sim *camera_sim_from(camera *cam) { return camera_backend_state(cam, &camera_sim_ops); }

void camera_sim_fault(camera_sim *s, enum camera_sim_fault fault, int n)
{
    switch (fault) {
    case CAMERA_SIM_FAULT_DROP: s->drop_n += n; break;
    case CAMERA_SIM_FAULT_STALL: s->stall_n += n; break;
    case CAMERA_SIM_FAULT_CORRUPT: s->corrupt_n += n; break;
    case CAMERA_SIM_FAULT_DISCONNECT:
        s->unplugged = 1;
        s->replugged = 0;
        break;
    }
}

void camera_sim_replug(camera_sim *s) { s->replugged = 1; }

void camera_sim_counters_get(const camera_sim *s, camera_sim_counters *out) { *out = s->counters; }
