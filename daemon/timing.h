/* daemon/timing.h — where the daemon's time goes: per-stage counters, always on, read by `status`.
 *
 * Each stage (acquire, store, recon_read, recon_solve, recon_write) accumulates how many times it ran, its wall
 * time and the CPU time of the thread that ran it (CLOCK_THREAD_CPUTIME_ID: the stage's own cost, not the other
 * threads' that shared the cores meanwhile). Work a library hands to its own threads would not be in it; OpenEXR's
 * compression pool was such work until scicapd_store_start turned the pool off, so EXR compression is now counted
 * in the stage that writes. Reading two clocks costs well under a microsecond, so the counters stay on in
 * production; `scicap status --json` shows them under "timing" and bench/bench_daemon reports them.
 *
 *     scicapd_span sp;
 *     scicapd_span_begin(&sp);
 *     ... the work ...
 *     scicapd_timing_add(t, SCICAPD_STAGE_STORE, &sp);
 *
 * Thread-safe (atomics); no allocation after scicapd_timing_new.
 */
#ifndef SCICAP_DAEMON_TIMING_H
#define SCICAP_DAEMON_TIMING_H

#include <jansson.h>
#include <stdint.h>

typedef enum scicapd_stage {
    SCICAPD_STAGE_ACQUIRE,     /* one snapshot: masks shown, frame read, calibrated (acquisition thread) */
    SCICAPD_STAGE_STORE,       /* one capture folder written and published (a writer thread) */
    SCICAPD_STAGE_RECON_READ,  /* a reconstruction's input: read from its capture folder, or handed over */
    SCICAPD_STAGE_RECON_SOLVE, /* the solver */
    SCICAPD_STAGE_RECON_WRITE, /* recon/<method>/ written and published */
    SCICAPD_STAGE_COUNT
} scicapd_stage;

typedef struct scicapd_timing scicapd_timing;

/* A started measurement (both clocks), on the thread that will end it. */
typedef struct scicapd_span {
    int64_t wall_ns, cpu_ns;
} scicapd_span;

/* -ENOMEM. */
int scicapd_timing_new(scicapd_timing **out);
void scicapd_timing_free(scicapd_timing *t);
void scicapd_span_begin(scicapd_span *sp);
/* Add the time since scicapd_span_begin(sp) to `stage` (t may be NULL: nothing is counted). */
void scicapd_timing_add(scicapd_timing *t, scicapd_stage stage, const scicapd_span *sp);
/* {"acquire": {"count": n, "wall_ms": mean, "cpu_ms": mean, "wall_s_total": s, "cpu_s_total": s}, ...}
 * (new reference). */
json_t *scicapd_timing_json(scicapd_timing *t);

#endif
