#include "drivers/sync.h"

#include <errno.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const sync_mode_names[SYNC_MODE_COUNT] = {
    [SYNC_MODE_DMD_MASTER] = "dmd-master",
    [SYNC_MODE_HOST_MASTER] = "host-master",
    [SYNC_MODE_CAMERA_MASTER] = "camera-master",
};

const char *sync_mode_name(enum sync_mode m)
{
    return ((int)m >= 0 && m < SYNC_MODE_COUNT) ? sync_mode_names[m] : "unknown";
}

int sync_mode_from_name(const char *name, enum sync_mode *out, sci_error *err)
{
    for (int m = 0; m < SYNC_MODE_COUNT; m++)
        if (name && strcmp(name, sync_mode_names[m]) == 0) {
            *out = (enum sync_mode)m;
            return 0;
        }
    return sci_error_set(err, -EINVAL, "sync mode \"%s\" is not one of dmd-master, host-master, camera-master",
                         name ? name : "(null)");
}

int sync_timeline_uniform(sync_timeline *tl, int64_t start_ns, int count, uint32_t exposure_us, uint32_t dark_us,
                          sci_error *err)
{
    if (count < 1 || count > SYNC_MAX_PATTERNS)
        return sci_error_set(err, -EINVAL, "timeline: pattern count %d is outside 1..%d", count, SYNC_MAX_PATTERNS);
    if (exposure_us == 0)
        return sci_error_set(err, -EINVAL, "timeline: pattern exposure must be > 0 us");
    tl->start_ns = start_ns;
    tl->count = count;
    for (int i = 0; i < count; i++) {
        tl->exposure_us[i] = exposure_us;
        tl->dark_us[i] = dark_us;
    }
    return 0;
}

int64_t sync_timeline_pattern_start_ns(const sync_timeline *tl, int i)
{
    int64_t t = tl->start_ns;
    for (int j = 0; j < i && j < tl->count; j++)
        t += ((int64_t)tl->exposure_us[j] + tl->dark_us[j]) * 1000;
    return t;
}

int64_t sync_timeline_end_ns(const sync_timeline *tl)
{
    return sync_timeline_pattern_start_ns(tl, tl->count - 1) + (int64_t)tl->exposure_us[tl->count - 1] * 1000;
}

sync_tolerance sync_tolerance_default(void)
{
    return (sync_tolerance){.max_offset_ns = 50000, .max_jitter_ns = 20000, .inside_slack = 0.005};
}

static int64_t i64_abs(int64_t v) { return v < 0 ? -v : v; }

/* Pair DMD edges with patterns. edge_of[i] receives the index of the edge matched to pattern i, or -1.
 * Returns the number of edges matched. */
static int match_edges(const sync_timeline *plan, const int64_t *planned, const sync_observation *obs, int *edge_of)
{
    int n = plan->count, m = obs ? obs->dmd_edge_count : 0;
    for (int i = 0; i < n; i++)
        edge_of[i] = -1;
    if (m == 0)
        return 0;
    if (m == n) { /* one edge per pattern: pair in order, whatever the latency */
        for (int i = 0; i < n; i++)
            edge_of[i] = i;
        return n;
    }
    /* Otherwise: the first edge fixes the offset; each edge goes to the nearest free pattern within half a period. */
    int64_t offset = obs->dmd_edges_ns[0] - planned[0];
    int matched = 0;
    for (int e = 0; e < m; e++) {
        int64_t t = obs->dmd_edges_ns[e] - offset;
        int best = -1;
        int64_t best_d = 0;
        for (int i = 0; i < n; i++) {
            int64_t period = ((int64_t)plan->exposure_us[i] + plan->dark_us[i]) * 1000;
            int64_t d = i64_abs(t - planned[i]);
            if (edge_of[i] < 0 && d * 2 < period && (best < 0 || d < best_d)) {
                best = i;
                best_d = d;
            }
        }
        if (best >= 0) {
            edge_of[best] = e;
            matched++;
        }
    }
    return matched;
}

int sync_report_compute(const sync_timeline *plan, const sync_observation *obs, const sync_tolerance *tol,
                        sync_report *out, sci_error *err)
{
    if (!plan || plan->count < 1 || plan->count > SYNC_MAX_PATTERNS)
        return sci_error_set(err, -EINVAL, "sync: timeline pattern count %d is outside 1..%d", plan ? plan->count : 0,
                             SYNC_MAX_PATTERNS);
    for (int i = 0; i < plan->count; i++)
        if (plan->exposure_us[i] == 0)
            return sci_error_set(err, -EINVAL, "sync: timeline pattern %d has a zero exposure", i);
    if (obs && obs->exposure_end_ns <= obs->exposure_start_ns)
        return sci_error_set(err, -EINVAL, "sync: exposure window [%lld, %lld] ns is empty",
                             (long long)obs->exposure_start_ns, (long long)obs->exposure_end_ns);
    if (obs && (obs->dmd_edge_count < 0 || (obs->dmd_edge_count > 0 && !obs->dmd_edges_ns)))
        return sci_error_set(err, -EINVAL, "sync: %d DMD edges without an array", obs->dmd_edge_count);
    sync_tolerance t = tol ? *tol : sync_tolerance_default();

    int n = plan->count;
    memset(out, 0, offsetof(sync_report, masks));
    out->mask_count = n;
    int64_t planned[SYNC_MAX_PATTERNS];
    int edge_of[SYNC_MAX_PATTERNS];
    int64_t t0 = plan->start_ns;
    for (int i = 0; i < n; i++) {
        planned[i] = t0;
        t0 += ((int64_t)plan->exposure_us[i] + plan->dark_us[i]) * 1000;
    }
    out->edges_seen = obs ? obs->dmd_edge_count : 0;
    out->edges_matched = match_edges(plan, planned, obs, edge_of);

    /* Timing error over matched patterns: mean is the (latency) offset, deviation from it the jitter. */
    double sum = 0;
    for (int i = 0; i < n; i++)
        if (edge_of[i] >= 0)
            sum += (double)(obs->dmd_edges_ns[edge_of[i]] - planned[i]);
    int64_t offset = out->edges_matched ? (int64_t)(sum / out->edges_matched) : 0;
    out->offset_ns = offset;

    for (int i = 0; i < n; i++) {
        sync_mask_result *mr = &out->masks[i];
        memset(mr, 0, sizeof *mr);
        if (edge_of[i] >= 0) {
            mr->measured = 1;
            mr->start_ns = obs->dmd_edges_ns[edge_of[i]];
            mr->error_ns = mr->start_ns - planned[i];
            if (i64_abs(mr->error_ns) > out->max_abs_error_ns)
                out->max_abs_error_ns = i64_abs(mr->error_ns);
            if (i64_abs(mr->error_ns - offset) > out->jitter_ns)
                out->jitter_ns = i64_abs(mr->error_ns - offset);
        } else {
            mr->start_ns = planned[i] + offset;
        }
        int64_t len = (int64_t)plan->exposure_us[i] * 1000;
        mr->end_ns = mr->start_ns + len;
        if (obs) {
            int64_t a = mr->start_ns > obs->exposure_start_ns ? mr->start_ns : obs->exposure_start_ns;
            int64_t b = mr->end_ns < obs->exposure_end_ns ? mr->end_ns : obs->exposure_end_ns;
            mr->overlap = b > a ? (double)(b - a) / (double)len : 0.0;
        }
        if (mr->overlap >= 1.0 - t.inside_slack) {
            mr->state = SYNC_MASK_INSIDE;
            out->inside++;
        } else if (mr->overlap > 0.0) {
            mr->state = SYNC_MASK_PARTIAL;
            out->partial++;
        } else {
            mr->state = SYNC_MASK_OUTSIDE;
            out->outside++;
        }
    }

    if (obs) {
        out->exposure_start_ns = obs->exposure_start_ns;
        out->exposure_end_ns = obs->exposure_end_ns;
        out->exposure_measured = obs->exposure_measured;
        out->lead_ns = out->masks[0].start_ns - obs->exposure_start_ns;
        out->trail_ns = obs->exposure_end_ns - out->masks[n - 1].end_ns;
        if (!obs->exposure_measured)
            out->flags |= SYNC_FLAG_EXPOSURE_ESTIMATED;
    } else {
        out->flags |= SYNC_FLAG_NO_FRAME;
    }
    if (out->edges_seen == 0)
        out->flags |= SYNC_FLAG_NO_DMD_EDGES;
    else {
        if (out->edges_matched < n)
            out->flags |= SYNC_FLAG_MISSING_EDGES;
        if (out->edges_seen > out->edges_matched)
            out->flags |= SYNC_FLAG_EXTRA_EDGES;
    }
    if (out->partial)
        out->flags |= SYNC_FLAG_PARTIAL_MASK;
    if (out->outside)
        out->flags |= SYNC_FLAG_MASK_OUTSIDE;
    if (out->edges_matched && i64_abs(out->offset_ns) > t.max_offset_ns)
        out->flags |= SYNC_FLAG_OFFSET;
    if (out->edges_matched && out->jitter_ns > t.max_jitter_ns)
        out->flags |= SYNC_FLAG_JITTER;
    out->broken = (out->flags & SYNC_FLAGS_BROKEN) != 0;
    return 0;
}

static const char *const sync_flag_names[] = {
    "no_dmd_edges", "missing_edges", "extra_edges", "partial_mask", "mask_outside",
    "offset",       "jitter",        "no_frame",    "exposure_estimated",
};

char *sync_flags_describe(unsigned flags, char *buf, size_t n)
{
    size_t used = 0;
    if (n == 0)
        return buf;
    buf[0] = '\0';
    for (size_t b = 0; b < sizeof sync_flag_names / sizeof sync_flag_names[0]; b++)
        if (flags & (1u << b)) {
            int k = snprintf(buf + used, n - used, "%s%s", used ? "," : "", sync_flag_names[b]);
            if (k < 0 || (size_t)k >= n - used)
                break;
            used += (size_t)k;
        }
    if (used == 0)
        snprintf(buf, n, "ok");
    return buf;
}

json_t *sync_report_to_json(const sync_report *r)
{
    static const char *const state_names[] = {"inside", "partial", "outside"};
    json_t *o = json_object(), *flags = json_array(), *state = json_array(), *overlap = json_array(),
           *error = json_array();
    if (!o || !flags || !state || !overlap || !error)
        goto fail;
    for (size_t b = 0; b < sizeof sync_flag_names / sizeof sync_flag_names[0]; b++)
        if (r->flags & (1u << b))
            json_array_append_new(flags, json_string(sync_flag_names[b]));
    for (int i = 0; i < r->mask_count; i++) {
        json_array_append_new(state, json_string(state_names[r->masks[i].state]));
        json_array_append_new(overlap, json_real(r->masks[i].overlap));
        if (r->masks[i].measured)
            json_array_append_new(error, json_integer(r->masks[i].error_ns));
        else
            json_array_append_new(error, json_null());
    }
    json_object_set_new(o, "broken", json_boolean(r->broken));
    json_object_set_new(o, "flags", flags);
    json_object_set_new(o, "mask_count", json_integer(r->mask_count));
    json_object_set_new(o, "inside", json_integer(r->inside));
    json_object_set_new(o, "partial", json_integer(r->partial));
    json_object_set_new(o, "outside", json_integer(r->outside));
    json_object_set_new(o, "edges_seen", json_integer(r->edges_seen));
    json_object_set_new(o, "edges_matched", json_integer(r->edges_matched));
    json_object_set_new(o, "offset_ns", json_integer(r->offset_ns));
    json_object_set_new(o, "max_abs_error_ns", json_integer(r->max_abs_error_ns));
    json_object_set_new(o, "jitter_ns", json_integer(r->jitter_ns));
    json_object_set_new(o, "exposure_start_ns", json_integer(r->exposure_start_ns));
    json_object_set_new(o, "exposure_end_ns", json_integer(r->exposure_end_ns));
    json_object_set_new(o, "exposure_measured", json_boolean(r->exposure_measured));
    json_object_set_new(o, "lead_ns", json_integer(r->lead_ns));
    json_object_set_new(o, "trail_ns", json_integer(r->trail_ns));
    json_object_set_new(o, "mask_state", state);
    json_object_set_new(o, "mask_overlap", overlap);
    json_object_set_new(o, "mask_error_ns", error);
    return o;
fail:
    json_decref(o);
    json_decref(flags);
    json_decref(state);
    json_decref(overlap);
    json_decref(error);
    return NULL;
}
