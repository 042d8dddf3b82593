/* sim/trigger_sim.h — a simulated GPIO trigger behind the same trigger_ops interface as the libgpiod backend.
 *
 * Output: trigger_pulse() "drives" the output line. The simulated edge happens at the call time plus a latency
 * and a seeded random jitter (uniform in [0, jitter_ns]); the simulator hands it to an output callback, which a
 * test or the bench wiring connects to whatever the line starts (camera_sim_trigger, a simulated DMD).
 * A pulse can be missed on demand (trigger_sim_miss_next) or at random (miss_probability): the edge never
 * reaches the callback, as with a loose wire.
 *
 * Inputs: other simulated devices inject edges with their own timestamps (trigger_sim_inject); an edge becomes
 * readable once CLOCK_MONOTONIC has passed its timestamp, so a reader never sees the future. trigger_sim_play
 * injects the per-pattern trigger output of a DMD running a sync_timeline (the stand-in for the simulated DMD
 * until that one drives this input itself).
 *
 * The event queue holds queue_size events (default 1024); on overflow the newest edge is discarded and counted,
 * as the kernel does.
 *
 * Deterministic for a given seed and call sequence. One thread at a time.
 */
#ifndef SCICAP_SIM_TRIGGER_SIM_H
#define SCICAP_SIM_TRIGGER_SIM_H

#include <stdint.h>

#include "drivers/sync.h"
#include "drivers/trigger.h"

extern const trigger_ops trigger_sim_ops;

typedef struct trigger_sim trigger_sim;

/* The output line went active at t_ns for width_us. */
typedef void (*trigger_sim_output_fn)(void *arg, int64_t t_ns, uint32_t width_us);

typedef struct trigger_sim_options {
    uint64_t seed;             /* rng seed (stream 0x7219) */
    int64_t latency_ns;        /* call to edge */
    int64_t jitter_ns;         /* extra uniform delay in [0, jitter_ns] */
    double miss_probability;   /* chance that a pulse never arrives */
    int queue_size;            /* input events held; 0: 1024 */
    trigger_sim_output_fn on_output;
    void *on_output_arg;
} trigger_sim_options;

/* The simulator behind `t`, or NULL if it is not simulated. Borrowed, lives as long as t. */
trigger_sim *trigger_sim_from(trigger *t);
/* The next n pulses are lost. */
void trigger_sim_miss_next(trigger_sim *s, int n);
/* An edge on an input line at t_ns (may lie in the future). -ENOTCONN if that input is not wired (not given in
 * the config), -ENOSPC if the queue is full (the edge is counted as lost). */
int trigger_sim_inject(trigger_sim *s, enum trigger_role role, int64_t t_ns, int rising);
/* A DMD playing `tl` from start_ns: a rising edge at each pattern start (plus uniform jitter in [0, jitter_ns])
 * and a falling edge pulse_us later, on the DMD input. Returns the number of edges injected or a negative code. */
int trigger_sim_play(trigger_sim *s, const sync_timeline *tl, int64_t start_ns, int64_t jitter_ns, uint32_t pulse_us);

typedef struct trigger_sim_counters {
    uint64_t pulses, missed, injected, overflowed;
} trigger_sim_counters;
void trigger_sim_counters_get(const trigger_sim *s, trigger_sim_counters *out);

#endif
