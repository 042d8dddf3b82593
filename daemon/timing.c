/* daemon/timing.c — per-stage time counters (see the header). */
#include "daemon/timing.h"

#include <errno.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <time.h>

#include "base/clock.h"

struct scicapd_timing {
    atomic_llong count[SCICAPD_STAGE_COUNT], wall_ns[SCICAPD_STAGE_COUNT], cpu_ns[SCICAPD_STAGE_COUNT];
};

static const char *const stage_names[SCICAPD_STAGE_COUNT] = {"acquire", "store", "recon_read", "recon_solve",
                                                              "recon_write"};

static int64_t thread_cpu_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

int scicapd_timing_new(scicapd_timing **out)
{
    scicapd_timing *t = calloc(1, sizeof *t);
    if (!t)
        return -ENOMEM;
    *out = t;
    return 0;
}

void scicapd_timing_free(scicapd_timing *t) { free(t); }

void scicapd_span_begin(scicapd_span *sp)
{
    sp->wall_ns = sci_clock_mono_ns();
    sp->cpu_ns = thread_cpu_ns();
}

void scicapd_timing_add(scicapd_timing *t, scicapd_stage stage, const scicapd_span *sp)
{
    if (!t || (unsigned)stage >= SCICAPD_STAGE_COUNT)
        return;
    atomic_fetch_add(&t->count[stage], 1);
    atomic_fetch_add(&t->wall_ns[stage], sci_clock_mono_ns() - sp->wall_ns);
    atomic_fetch_add(&t->cpu_ns[stage], thread_cpu_ns() - sp->cpu_ns);
}

json_t *scicapd_timing_json(scicapd_timing *t)
{
    json_t *o = json_object();
    for (int s = 0; t && s < SCICAPD_STAGE_COUNT; s++) {
        long long n = atomic_load(&t->count[s]);
        double wall = (double)atomic_load(&t->wall_ns[s]) * 1e-9, cpu = (double)atomic_load(&t->cpu_ns[s]) * 1e-9;
        json_object_set_new(o, stage_names[s],
                            json_pack("{s:I, s:f, s:f, s:f, s:f}", "count", (json_int_t)n, "wall_ms",
                                      n ? wall * 1e3 / (double)n : 0.0, "cpu_ms", n ? cpu * 1e3 / (double)n : 0.0,
                                      "wall_s_total", wall, "cpu_s_total", cpu));
    }
    return o;
}
