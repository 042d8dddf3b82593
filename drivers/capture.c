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

/* The times one snapshot waits for, fixed before it starts (ns). */
typedef struct snapshot_times {
    int64_t seq_ns;     /* the DMD sequence's length */
    int64_t settle_ns;  /* margin after the sequence (and after the frame) for the last edges */
    int64_t timeout_ns; /* from the start to the frame's deadline */
} snapshot_times;

/* Where the frame's exposure lay: the strobe pulse nearest its estimated start, else the estimate. */
typedef struct snapshot_window {
    int64_t a_ns, b_ns;
    int measured; /* 1 when a and b are the strobe's edges */
} snapshot_window;

/* The parameters checked and out's identities and counters set; the camera must be streaming. */
static int snapshot_check(camera *cam, trigger *trig, const capture_params *p, capture_snapshot *out,
                          sci_error *err)
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
    out->dmd_failed = 0;
    out->dmd_edges = out->strobe_edges = 0;
    return 0;
}

/* Phase 1: what is already queued was exposed before this snapshot (counted as stale), and old edges go. */
static int snapshot_drain(camera *cam, trigger *trig, capture_snapshot *out, sci_error *err)
{
    int rc = 0;
    while (out->stale_frames < 4 * CAMERA_MAX_BUFFERS && (rc = camera_wait_frame(cam, 0, &out->frame, err)) == 0)
        out->stale_frames++;
    if (rc < 0 && rc != -ETIMEDOUT)
        return rc;
    return trigger_flush(trig, err);
}

/* When a snapshot started (monotonic ns): t0 before the start call, t1 after it. Only in camera master, where
 * the call arms a DMD that the next strobe starts, do they differ by more than a read of the clock. */
typedef struct snapshot_start_times {
    int64_t t0, t1;
} snapshot_start_times;

/* Phase 2: the start as the sync mode has it. */
static int snapshot_start(trigger *trig, const capture_params *p, snapshot_start_times *st, sci_error *err)
{
    int rc = 0;
    switch (p->mode) {
    case SYNC_MODE_HOST_MASTER:
        rc = trigger_pulse(trig, p->pulse_width_us ? p->pulse_width_us : 10, &st->t0, err);
        break;
    case SYNC_MODE_DMD_MASTER:
        if (p->dmd) {
            st->t0 = sci_clock_mono_ns();
            rc = dmd_start(p->dmd, err);
        } else {
            rc = trigger_pulse(trig, p->pulse_width_us ? p->pulse_width_us : 10, &st->t0, err);
        }
        break;
    default:
        /* camera master: armed after the drain, so no exposure between the arm and now was thrown away */
        st->t0 = sci_clock_mono_ns();
        if (p->dmd)
            rc = dmd_start(p->dmd, err);
        st->t1 = sci_clock_mono_ns();
        return rc;
    }
    st->t1 = st->t0;
    return rc;
}

/* Camera master, a frame whose exposure began during the arm call: the DMD may have been armed before or after
 * its strobe. It is the snapshot's frame only if the DMD's first edge came by its start plus the latency. */
static int snapshot_started_by(trigger *trig, const capture_params *p, int64_t t0, int64_t a, int64_t settle_ns,
                               edge_log *log, int *yes, sci_error *err)
{
    int64_t until = a + p->dmd_latency_ns + settle_ns;
    int rc = collect_until(trig, log, until, err);
    *yes = 0;
    for (int i = 0; rc == 0 && i < log->n && !*yes; i++)
        *yes = log->ev[i].role == TRIGGER_ROLE_DMD && log->ev[i].rising && log->ev[i].timestamp_ns >= t0 &&
               log->ev[i].timestamp_ns <= until;
    return rc;
}

/* Phase 3: the frame that belongs to the start, by deadline_ns, into out->frame (*have_frame = 1); earlier
 * frames are counted as stale. No frame by the deadline is not an error here (0, *have_frame = 0). */
static int snapshot_wait_frame(camera *cam, trigger *trig, const capture_params *p, const snapshot_start_times *st,
                               int64_t deadline_ns, int64_t settle_ns, edge_log *log, capture_snapshot *out,
                               int *have_frame, sci_error *err)
{
    for (;;) {
        int64_t now = sci_clock_mono_ns();
        int rc = camera_wait_frame(cam, deadline_ns > now ? deadline_ns - now : 0, &out->frame, err);
        if (rc == -ETIMEDOUT)
            return 0;
        if (rc < 0)
            return rc;
        int64_t a, b;
        estimate_window(&out->frame, p->readout_ns, &a, &b);
        /* camera master: the exposure must begin after the arm (its strobe starts our DMD sequence);
         * otherwise the frame must at least end after the start. */
        int keep = p->mode == SYNC_MODE_CAMERA_MASTER ? a >= st->t0 : b > st->t0;
        if (keep && p->mode == SYNC_MODE_CAMERA_MASTER && p->dmd && a < st->t1 &&
            (rc = snapshot_started_by(trig, p, st->t0, a, settle_ns, log, &keep, err)) < 0)
            return rc;
        if (keep) {
            *have_frame = 1;
            return 0;
        }
        out->stale_frames++;
    }
}

/* Phase 4's end: when the sequence must be over (monotonic ns), and the frame's timestamp plus settle time. */
static int64_t snapshot_edges_until_ns(const capture_params *p, const snapshot_times *tm,
                                       const capture_snapshot *out, int have_frame, int64_t t0)
{
    int64_t until = t0 + p->dmd_latency_ns + tm->seq_ns + tm->settle_ns;
    if (have_frame && out->frame.timestamp_ns + tm->settle_ns > until)
        until = out->frame.timestamp_ns + tm->settle_ns;
    if (have_frame && p->mode == SYNC_MODE_CAMERA_MASTER) {
        int64_t a, b;
        estimate_window(&out->frame, p->readout_ns, &a, &b);
        until = a + p->dmd_latency_ns + tm->seq_ns + tm->settle_ns;
        if (out->frame.timestamp_ns + tm->settle_ns > until)
            until = out->frame.timestamp_ns + tm->settle_ns;
    }
    return until;
}

/* Phase 5: frame f's exposure window from the logged strobe pulses, else its estimate. */
static snapshot_window snapshot_window_find(const capture_params *p, const edge_log *log, const camera_frame *f)
{
    snapshot_window w = {0};
    estimate_window(f, p->readout_ns, &w.a_ns, &w.b_ns);
    int64_t best_d = INT64_MAX;
    int best = -1;
    for (int i = 0; i < log->n; i++) {
        if (log->ev[i].role != TRIGGER_ROLE_STROBE || !log->ev[i].rising)
            continue;
        int64_t d = log->ev[i].timestamp_ns - w.a_ns;
        d = d < 0 ? -d : d;
        if (d < best_d) {
            best_d = d;
            best = i;
        }
    }
    if (best >= 0)
        for (int j = best + 1; j < log->n; j++)
            if (log->ev[j].role == TRIGGER_ROLE_STROBE && !log->ev[j].rising) {
                w.a_ns = log->ev[best].timestamp_ns;
                w.b_ns = log->ev[j].timestamp_ns;
                w.measured = 1;
                break;
            }
    return w;
}

/* Phase 6: the plan placed in time (from t0, or from the exposure's start in camera master) and compared with
 * the DMD edges of this sequence and the window into out->report. No frame: -ETIMEDOUT with the diagnosis. */
static int snapshot_compare(const capture_params *p, const snapshot_times *tm, const edge_log *log,
                            int have_frame, int64_t t0, const snapshot_window *w, capture_snapshot *out,
                            sci_error *err)
{
    out->plan = *p->timeline;
    int64_t origin = t0;
    if (p->mode == SYNC_MODE_CAMERA_MASTER && have_frame)
        origin = w->a_ns; /* the strobe (or the estimated exposure start) started the DMD */
    out->plan.start_ns = origin + p->dmd_latency_ns;
    /* DMD edges that belong to this sequence: between the start and the planned end plus one settle time
     * (in camera master the next frame's strobe starts the next sequence). */
    int64_t lo = origin, hi = sync_timeline_end_ns(&out->plan) + tm->settle_ns;
    int64_t *edges = malloc(sizeof *edges * (size_t)(log->n ? log->n : 1));
    if (!edges)
        return sci_error_set(err, -ENOMEM, "capture: out of memory");
    int ne = 0;
    for (int i = 0; i < log->n; i++)
        if (log->ev[i].role == TRIGGER_ROLE_DMD && log->ev[i].rising && log->ev[i].timestamp_ns >= lo &&
            log->ev[i].timestamp_ns <= hi)
            edges[ne++] = log->ev[i].timestamp_ns;
    sync_observation obs = {.dmd_edges_ns = edges, .dmd_edge_count = ne, .exposure_start_ns = w->a_ns,
                            .exposure_end_ns = w->b_ns > w->a_ns ? w->b_ns : w->a_ns + 1,
                            .exposure_measured = w->measured};
    sci_error serr = {0};
    int rc = sync_report_compute(&out->plan, have_frame ? &obs : NULL, &p->tolerance, &out->report, &serr);
    free(edges);
    if (rc < 0 && have_frame) /* only a degenerate window can fail here */
        return sci_error_set(err, rc, "capture: %s", serr.msg);
    if (!have_frame) {
        out->report.edges_seen = ne; /* what the DMD did, for the diagnosis */
        return sci_error_set(err, -ETIMEDOUT, "capture: camera %s (%s) gave no frame within %.1f ms of the %s start "
                             "(missed trigger?); DMD edges seen: %d, strobe edges: %d", out->camera_id.path,
                             out->camera_id.card, (double)tm->timeout_ns * 1e-6, sync_mode_name(p->mode),
                             out->dmd_edges, out->strobe_edges);
    }
    return 0;
}

/* Phases 2-6 with the edge log allocated. */
static int snapshot_run(camera *cam, trigger *trig, const capture_params *p, const snapshot_times *tm,
                        edge_log *log, capture_snapshot *out, sci_error *err)
{
    snapshot_start_times st = {0};
    int rc = snapshot_start(trig, p, &st, err);
    if (rc < 0) {
        out->dmd_failed = p->dmd && p->mode != SYNC_MODE_HOST_MASTER; /* only dmd_start can fail there */
        return rc;
    }
    int64_t t0 = st.t0;
    out->start_ns = t0;
    int have_frame = 0;
    if ((rc = snapshot_wait_frame(cam, trig, p, &st, st.t1 + tm->timeout_ns, tm->settle_ns, log, out, &have_frame,
                                  err)) < 0)
        return rc;
    /* phase 4: edges until the sequence must be over */
    if ((rc = collect_until(trig, log, snapshot_edges_until_ns(p, tm, out, have_frame, t0), err)) < 0)
        return rc;
    snapshot_window w = {0};
    if (have_frame)
        w = snapshot_window_find(p, log, &out->frame);
    if (have_frame && p->mode == SYNC_MODE_CAMERA_MASTER)
        out->start_ns = w.a_ns; /* the strobe started the sequence */
    for (int i = 0; i < log->n; i++)
        if (log->ev[i].rising)
            *(log->ev[i].role == TRIGGER_ROLE_DMD ? &out->dmd_edges : &out->strobe_edges) += 1;
    return snapshot_compare(p, tm, log, have_frame, t0, &w, out, err);
}

int capture_snapshot_take(camera *cam, trigger *trig, const capture_params *p, capture_snapshot *out, sci_error *err)
{
    int rc = snapshot_check(cam, trig, p, out, err);
    if (rc < 0)
        return rc;
    trigger_stats ts0, ts1;
    trigger_stats_get(trig, &ts0);
    int64_t exposure_ns = (int64_t)camera_exposure_us(cam) * 1000;
    snapshot_times tm = {.seq_ns = seq_length_ns(p->timeline)};
    tm.settle_ns = p->settle_ns > 0 ? p->settle_ns : 1000000;
    tm.timeout_ns = p->frame_timeout_ns > 0
                        ? p->frame_timeout_ns
                        : exposure_ns + tm.seq_ns + p->dmd_latency_ns + p->readout_ns + 1000000000LL;
    if ((rc = snapshot_drain(cam, trig, out, err)) < 0)
        return rc;
    edge_log log = {.cap = CAPTURE_MAX_EVENTS};
    log.ev = malloc(sizeof *log.ev * (size_t)log.cap);
    if (!log.ev)
        return sci_error_set(err, -ENOMEM, "capture: out of memory");
    rc = snapshot_run(cam, trig, p, &tm, &log, out, err);
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
