#include "drivers/capture.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"

capture_params capture_params_default(void)
{
    capture_params p;
    memset(&p, 0, sizeof p);
    p.mode = SYNC_MODE_HOST_MASTER;
    p.pulse_width_us = 10;
    p.settle_ns = 1000000;
    p.tolerance = sync_tolerance_default();
    return p;
}

void capture_snapshot_release(capture_snapshot *s)
{
    if (s)
        camera_frame_release(&s->frame);
}

int capture_timeline_from_dmd(const dmd_timing *t, int count, sync_timeline *out, sci_error *err)
{
    if (count < 1 || count > SYNC_MAX_PATTERNS)
        return sci_error_set(err, -EINVAL, "capture: pattern count %d is outside 1..%d", count, SYNC_MAX_PATTERNS);
    out->start_ns = 0;
    out->count = count;
    for (int i = 0; i < count; i++) {
        out->exposure_us[i] = t->exposure_us_each ? t->exposure_us_each[i] : t->exposure_us;
        out->dark_us[i] = t->dark_us_each ? t->dark_us_each[i] : t->dark_us;
        if (out->exposure_us[i] == 0)
            return sci_error_set(err, -EINVAL, "capture: DMD pattern %d has a zero exposure", i);
    }
    return 0;
}

/* Exposure window of a frame from its timestamp alone. */
static void estimate_window(const camera_frame *f, int64_t readout_ns, int64_t *a, int64_t *b)
{
    int64_t exp_ns = (int64_t)f->exposure_us * 1000;
    if (f->ts_source == CAMERA_TS_SOE) {
        *a = f->timestamp_ns;
        *b = f->timestamp_ns + exp_ns;
    } else {
        *b = f->timestamp_ns - readout_ns;
        *a = *b - exp_ns;
    }
}

typedef struct edge_log {
    trigger_event *ev;
    int n, cap;
    int overflow;
} edge_log;

static int collect_until(trigger *trig, edge_log *log, int64_t until_ns, sci_error *err)
{
    for (;;) {
        int64_t now = sci_clock_mono_ns();
        int room = log->cap - log->n, got = 0;
        if (room == 0) {
            trigger_event scratch[64]; /* keep draining so the kernel queue does not overflow; count the excess */
            int rc = trigger_read_events(trig, now < until_ns ? until_ns - now : 0, scratch, 64, &got, err);
            if (rc < 0)
                return rc;
            log->overflow += got;
        } else {
            int rc = trigger_read_events(trig, now < until_ns ? until_ns - now : 0, log->ev + log->n, room, &got, err);
            if (rc < 0)
                return rc;
            log->n += got;
        }
        if (got == 0 && sci_clock_mono_ns() >= until_ns)
            return 0;
    }
}

static int64_t seq_length_ns(const sync_timeline *tl)
{
    return sync_timeline_end_ns(tl) - tl->start_ns;
}

int capture_snapshot_take(camera *cam, trigger *trig, const capture_params *p, capture_snapshot *out, sci_error *err)
{
    if (!p->timeline || p->timeline->count < 1 || p->timeline->count > SYNC_MAX_PATTERNS)
        return sci_error_set(err, -EINVAL, "capture: the DMD timeline is missing or has %d patterns",
                             p->timeline ? p->timeline->count : 0);
    if ((int)p->mode < 0 || p->mode >= SYNC_MODE_COUNT)
        return sci_error_set(err, -EINVAL, "capture: sync mode %d is not valid", (int)p->mode);
    camera_identity_get(cam, &out->camera_id);
    trigger_identity_get(trig, &out->trigger_id);
    if (!camera_is_streaming(cam))
        return sci_error_set(err, -EINVAL, "capture: camera %s is not streaming", out->camera_id.path);
    out->mode = p->mode;
    out->stale_frames = 0;
    out->dmd_edges = out->strobe_edges = 0;
    trigger_stats ts0, ts1;
    trigger_stats_get(trig, &ts0);

    int64_t exposure_ns = (int64_t)camera_exposure_us(cam) * 1000;
    int64_t seq_ns = seq_length_ns(p->timeline);
    int64_t settle = p->settle_ns > 0 ? p->settle_ns : 1000000;
    int64_t timeout = p->frame_timeout_ns > 0 ? p->frame_timeout_ns
                                              : exposure_ns + seq_ns + p->dmd_latency_ns + p->readout_ns + 1000000000LL;
    const char *cam_name = out->camera_id.path;

    /* 1. What is already queued was exposed before this snapshot. */
    int rc = 0;
    while (out->stale_frames < 4 * CAMERA_MAX_BUFFERS && (rc = camera_wait_frame(cam, 0, &out->frame, err)) == 0)
        out->stale_frames++;
    if (rc < 0 && rc != -ETIMEDOUT)
        return rc;
    if ((rc = trigger_flush(trig, err)) < 0)
        return rc;

    edge_log log = {.cap = CAPTURE_MAX_EVENTS};
    log.ev = malloc(sizeof *log.ev * (size_t)log.cap);
    if (!log.ev)
        return sci_error_set(err, -ENOMEM, "capture: out of memory");

    /* 2. Start. */
    int64_t t0 = 0;
    switch (p->mode) {
    case SYNC_MODE_HOST_MASTER: rc = trigger_pulse(trig, p->pulse_width_us ? p->pulse_width_us : 10, &t0, err); break;
    case SYNC_MODE_DMD_MASTER:
        if (p->dmd) {
            t0 = sci_clock_mono_ns();
            rc = dmd_start(p->dmd, err);
        } else
            rc = trigger_pulse(trig, p->pulse_width_us ? p->pulse_width_us : 10, &t0, err);
        break;
    default: t0 = sci_clock_mono_ns(); rc = 0; break;
    }
    if (rc < 0)
        goto out;
    out->start_ns = t0;

    /* 3. The frame that belongs to this start. */
    int64_t deadline = t0 + timeout;
    int have_frame = 0;
    for (;;) {
        int64_t now = sci_clock_mono_ns();
        rc = camera_wait_frame(cam, deadline > now ? deadline - now : 0, &out->frame, err);
        if (rc == -ETIMEDOUT)
            break;
        if (rc < 0)
            goto out;
        int64_t a, b;
        estimate_window(&out->frame, p->readout_ns, &a, &b);
        /* camera master: the exposure must begin after the call (its strobe starts our DMD sequence);
         * otherwise the frame must at least end after the start. */
        int stale = p->mode == SYNC_MODE_CAMERA_MASTER ? a < t0 : b <= t0;
        if (!stale) {
            have_frame = 1;
            break;
        }
        out->stale_frames++;
    }

    /* 4. Edges until the sequence must be over. */
    int64_t until = t0 + p->dmd_latency_ns + seq_ns + settle;
    if (have_frame && out->frame.timestamp_ns + settle > until)
        until = out->frame.timestamp_ns + settle;
    if (have_frame && p->mode == SYNC_MODE_CAMERA_MASTER) {
        int64_t a, b;
        estimate_window(&out->frame, p->readout_ns, &a, &b);
        until = a + p->dmd_latency_ns + seq_ns + settle;
        if (out->frame.timestamp_ns + settle > until)
            until = out->frame.timestamp_ns + settle;
    }
    int rc2 = collect_until(trig, &log, until, err);
    if (rc2 < 0) {
        rc = rc2;
        goto out;
    }

    /* 5. The exposure window: the strobe pulse nearest the frame's estimated start, else the estimate. */
    int64_t win_a = 0, win_b = 0;
    int measured = 0;
    if (have_frame) {
        estimate_window(&out->frame, p->readout_ns, &win_a, &win_b);
        int64_t best_d = INT64_MAX;
        int best = -1;
        for (int i = 0; i < log.n; i++) {
            if (log.ev[i].role != TRIGGER_ROLE_STROBE || !log.ev[i].rising)
                continue;
            int64_t d = log.ev[i].timestamp_ns - win_a;
            d = d < 0 ? -d : d;
            if (d < best_d) {
                best_d = d;
                best = i;
            }
        }
        if (best >= 0)
            for (int j = best + 1; j < log.n; j++)
                if (log.ev[j].role == TRIGGER_ROLE_STROBE && !log.ev[j].rising) {
                    win_a = log.ev[best].timestamp_ns;
                    win_b = log.ev[j].timestamp_ns;
                    measured = 1;
                    break;
                }
    }
    for (int i = 0; i < log.n; i++)
        if (log.ev[i].rising)
            *(log.ev[i].role == TRIGGER_ROLE_DMD ? &out->dmd_edges : &out->strobe_edges) += 1;

    /* 6. Place the plan in time and compare. */
    out->plan = *p->timeline;
    int64_t origin = t0;
    if (p->mode == SYNC_MODE_CAMERA_MASTER && have_frame)
        origin = win_a; /* the strobe (or the estimated exposure start) started the DMD */
    out->plan.start_ns = origin + p->dmd_latency_ns;
    /* DMD edges that belong to this sequence: between the start and the planned end plus one settle time
     * (in camera master the next frame's strobe starts the next sequence). */
    int64_t lo = origin, hi = sync_timeline_end_ns(&out->plan) + settle;
    int64_t *edges = malloc(sizeof *edges * (size_t)(log.n ? log.n : 1));
    if (!edges) {
        rc = sci_error_set(err, -ENOMEM, "capture: out of memory");
        goto out;
    }
    int ne = 0;
    for (int i = 0; i < log.n; i++)
        if (log.ev[i].role == TRIGGER_ROLE_DMD && log.ev[i].rising && log.ev[i].timestamp_ns >= lo &&
            log.ev[i].timestamp_ns <= hi)
            edges[ne++] = log.ev[i].timestamp_ns;
    sync_observation obs = {.dmd_edges_ns = edges, .dmd_edge_count = ne, .exposure_start_ns = win_a,
                            .exposure_end_ns = win_b > win_a ? win_b : win_a + 1, .exposure_measured = measured};
    sci_error serr = {0};
    rc2 = sync_report_compute(&out->plan, have_frame ? &obs : NULL, &p->tolerance, &out->report, &serr);
    if (rc2 < 0 && have_frame) { /* only a degenerate window can fail here */
        free(edges);
        rc = sci_error_set(err, rc2, "capture: %s", serr.msg);
        goto out;
    }
    if (!have_frame) {
        out->report.edges_seen = ne; /* what the DMD did, for the diagnosis */
        free(edges);
        rc = sci_error_set(err, -ETIMEDOUT, "capture: camera %s (%s) gave no frame within %.1f ms of the %s start "
                           "(missed trigger?); DMD edges seen: %d, strobe edges: %d", cam_name, out->camera_id.card,
                           (double)timeout * 1e-6, sync_mode_name(p->mode), out->dmd_edges, out->strobe_edges);
        goto out;
    }
    free(edges);
    rc = 0;
out:
    trigger_stats_get(trig, &ts1);
    out->lost_events = ts1.lost_events - ts0.lost_events + (uint64_t)log.overflow;
    free(log.ev);
    return rc;
}

json_t *capture_snapshot_meta_json(const capture_snapshot *s)
{
    json_t *o = json_object();
    if (!o)
        return NULL;
    json_object_set_new(o, "sync_mode", json_string(sync_mode_name(s->mode)));
    json_object_set_new(o, "start_ns", json_integer(s->start_ns));
    json_object_set_new(o, "stale_frames", json_integer(s->stale_frames));
    json_object_set_new(o, "dmd_edges", json_integer(s->dmd_edges));
    json_object_set_new(o, "strobe_edges", json_integer(s->strobe_edges));
    json_object_set_new(o, "lost_gpio_events", json_integer((json_int_t)s->lost_events));
    json_object_set_new(o, "frame", camera_frame_meta_json(&s->frame));
    json_object_set_new(o, "sync", sync_report_to_json(&s->report));
    json_object_set_new(o, "camera", camera_identity_json(&s->camera_id));
    json_object_set_new(o, "trigger", trigger_identity_json(&s->trigger_id));
    return o;
}
