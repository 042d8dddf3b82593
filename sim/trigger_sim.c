#include "sim/trigger_sim.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "base/rng.h"

struct trigger_sim {
    trigger_sim_options opt;
    sci_rng rng;
    char chip[64];
    int output_offset;
    int input_offset[TRIGGER_ROLE_COUNT];
    trigger_event *q; /* ascending timestamps */
    int qn, qcap;
    uint32_t seqno[TRIGGER_ROLE_COUNT];        /* numbered on delivery, in time order, as the kernel would */
    uint32_t lost_pending[TRIGGER_ROLE_COUNT]; /* overflowed edges not yet reflected in seqno */
    int miss_n;
    trigger_sim_counters counters;
};

static int tsim_open(void **state, const trigger_config *cfg, sci_error *err)
{
    trigger_sim *s = calloc(1, sizeof *s);
    if (!s)
        return sci_error_set(err, -ENOMEM, "sim trigger: out of memory");
    if (cfg->backend_options)
        s->opt = *(const trigger_sim_options *)cfg->backend_options;
    s->qcap = s->opt.queue_size > 0 ? s->opt.queue_size : 1024;
    s->q = calloc((size_t)s->qcap, sizeof *s->q);
    if (!s->q) {
        free(s);
        return sci_error_set(err, -ENOMEM, "sim trigger: out of memory");
    }
    sci_rng_seed(&s->rng, s->opt.seed, 0x7219);
    snprintf(s->chip, sizeof s->chip, "%s", cfg->chip ? cfg->chip : "sim-gpiochip");
    /* Lines by name have no meaning in the simulator: a name simply wires the line (offset shown as 0). */
    s->output_offset = cfg->output.offset >= 0 ? cfg->output.offset : cfg->output.name ? 0 : -1;
    for (int r = 0; r < TRIGGER_ROLE_COUNT; r++)
        s->input_offset[r] = cfg->inputs[r].offset >= 0 ? cfg->inputs[r].offset : cfg->inputs[r].name ? 0 : -1;
    *state = s;
    return 0;
}

static void tsim_close(void *state)
{
    trigger_sim *s = state;
    if (!s)
        return;
    free(s->q);
    free(s);
}

static void tsim_identity(void *state, trigger_identity *out)
{
    trigger_sim *s = state;
    memset(out, 0, sizeof *out);
    snprintf(out->backend, sizeof out->backend, "sim");
    snprintf(out->chip, sizeof out->chip, "%s", s->chip);
    snprintf(out->label, sizeof out->label, "scicap simulated gpio");
    out->output_offset = s->output_offset;
    for (int r = 0; r < TRIGGER_ROLE_COUNT; r++)
        out->input_offset[r] = s->input_offset[r];
}

static void tsim_sleep_until(int64_t t_ns)
{
    struct timespec ts = {.tv_sec = t_ns / 1000000000LL, .tv_nsec = t_ns % 1000000000LL};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR)
        ;
}

static int tsim_pulse(void *state, uint32_t width_us, int64_t *t_ns, sci_error *err)
{
    trigger_sim *s = state;
    int64_t now = sci_clock_mono_ns();
    int64_t jitter = s->opt.jitter_ns > 0 ? (int64_t)sci_rng_below(&s->rng, (uint64_t)s->opt.jitter_ns + 1) : 0;
    int64_t t = now + s->opt.latency_ns + jitter;
    /* draw the miss decision every time so that the jitter sequence does not depend on miss_probability */
    double u = sci_rng_uniform(&s->rng);
    s->counters.pulses++;
    if (t_ns)
        *t_ns = now;
    if (s->miss_n > 0 || u < s->opt.miss_probability) {
        if (s->miss_n > 0)
            s->miss_n--;
        s->counters.missed++;
    } else if (s->opt.on_output) {
        s->opt.on_output(s->opt.on_output_arg, t, width_us);
    }
    tsim_sleep_until(now + (int64_t)width_us * 1000); /* the pulse blocks for its width, as the hardware one does */
    return 0;
}

static int tsim_read(void *state, int64_t timeout_ns, trigger_event *ev, int max, int *count, sci_error *err)
{
    trigger_sim *s = state;
    int64_t now = sci_clock_mono_ns(), deadline = now + timeout_ns;
    *count = 0;
    for (;;) {
        int n = 0;
        while (n < s->qn && n < max && s->q[n].timestamp_ns <= now)
            n++;
        if (n > 0) {
            memcpy(ev, s->q, (size_t)n * sizeof *ev);
            for (int i = 0; i < n; i++) {
                enum trigger_role r = ev[i].role;
                s->seqno[r] += 1 + s->lost_pending[r];
                s->lost_pending[r] = 0;
                ev[i].line_seqno = s->seqno[r];
            }
            memmove(s->q, s->q + n, (size_t)(s->qn - n) * sizeof *s->q);
            s->qn -= n;
            *count = n;
            return 0;
        }
        if (now >= deadline)
            return 0;
        int64_t next = s->qn ? s->q[0].timestamp_ns : INT64_MAX;
        tsim_sleep_until(next < deadline ? next : deadline);
        now = sci_clock_mono_ns();
    }
}

static int tsim_flush(void *state, sci_error *err)
{
    trigger_sim *s = state;
    /* only what already happened is stale; scheduled future edges stay */
    int64_t now = sci_clock_mono_ns();
    int n = 0;
    while (n < s->qn && s->q[n].timestamp_ns <= now)
        n++;
    memmove(s->q, s->q + n, (size_t)(s->qn - n) * sizeof *s->q);
    s->qn -= n;
    return 0;
}

const trigger_ops trigger_sim_ops = {
    .name = "sim",
    .open = tsim_open,
    .close = tsim_close,
    .identity = tsim_identity,
    .pulse = tsim_pulse,
    .read_events = tsim_read,
    .flush = tsim_flush,
};

trigger_sim *trigger_sim_from(trigger *t) { return trigger_backend_state(t, &trigger_sim_ops); }

void trigger_sim_miss_next(trigger_sim *s, int n) { s->miss_n += n; }

int trigger_sim_inject(trigger_sim *s, enum trigger_role role, int64_t t_ns, int rising)
{
    if ((int)role < 0 || role >= TRIGGER_ROLE_COUNT || s->input_offset[role] < 0)
        return -ENOTCONN;
    if (s->qn == s->qcap) {
        s->counters.overflowed++;
        s->lost_pending[role]++; /* the kernel numbers the lost edge too: the gap shows in line_seqno */
        return -ENOSPC;
    }
    int i = s->qn;
    while (i > 0 && s->q[i - 1].timestamp_ns > t_ns) { /* insertion keeps the queue in time order */
        s->q[i] = s->q[i - 1];
        i--;
    }
    s->q[i] = (trigger_event){.timestamp_ns = t_ns, .role = role, .rising = rising};
    s->qn++;
    s->counters.injected++;
    return 0;
}

int trigger_sim_play(trigger_sim *s, const sync_timeline *tl, int64_t start_ns, int64_t jitter_ns, uint32_t pulse_us)
{
    int n = 0;
    for (int i = 0; i < tl->count; i++) {
        int64_t t = start_ns + (sync_timeline_pattern_start_ns(tl, i) - tl->start_ns);
        if (jitter_ns > 0)
            t += (int64_t)sci_rng_below(&s->rng, (uint64_t)jitter_ns + 1);
        int rc = trigger_sim_inject(s, TRIGGER_ROLE_DMD, t, 1);
        if (rc == -ENOTCONN)
            return rc;
        n += rc == 0;
        rc = trigger_sim_inject(s, TRIGGER_ROLE_DMD, t + (int64_t)pulse_us * 1000, 0);
        n += rc == 0;
    }
    return n;
}

void trigger_sim_counters_get(const trigger_sim *s, trigger_sim_counters *out) { *out = s->counters; }
