/* drivers/trigger.h — the trigger interface: one GPIO output that starts things, GPIO inputs that record when
 * things really happened.
 *
 * The output line starts the DMD sequence and/or the camera exposure (which one depends on the sync mode,
 * drivers/sync.h). Two input lines watch the bench: the DMD's per-pattern trigger output (one rising edge per
 * pattern) and the camera's strobe (rising at exposure start, falling at exposure end). Their edges come back
 * with kernel timestamps, so the sync report measures what happened, not what was asked.
 *
 * Backends: trigger_gpiod_ops (libgpiod 1.6 or 2.x, picked at build time by SCICAP_GPIOD_MAJOR), trigger_sim_ops
 * in sim/. Used through the trigger_* functions below.
 *
 *     trigger_config tc = trigger_config_default();
 *     tc.chip = "/dev/gpiochip0"; tc.output.offset = 17; tc.dmd_input.offset = 22; tc.strobe_input.offset = 27;
 *     trigger *tr;
 *     if (trigger_open(&tr, &trigger_gpiod_ops, &tc, &err) < 0) ...
 *     trigger_flush(tr);
 *     int64_t t; trigger_pulse(tr, 10, &t, &err);
 *     trigger_event ev[64]; int n; trigger_read_events(tr, 5000000, ev, 64, &n, &err);
 *
 * Units: pulse width in µs, timestamps in ns of CLOCK_MONOTONIC (the kernel's event clock; GPIO uAPI v1 used
 * REALTIME before Linux 5.7 — unsupported), timeouts in ns.
 * Errors: 0 or negative, with a message naming the chip and line: -ENOENT (no such chip, or no line of that
 * name), -EINVAL (offset beyond the chip), -EBUSY (line held by another consumer, named when known), -EACCES.
 * Threads: one thread at a time per trigger. Backends never print or exit.
 */
#ifndef SCICAP_DRIVERS_TRIGGER_H
#define SCICAP_DRIVERS_TRIGGER_H

#include <jansson.h>
#include <stdint.h>

#include "base/error.h"

/* Which input an event came from. */
enum trigger_role { TRIGGER_ROLE_DMD = 0, TRIGGER_ROLE_STROBE = 1, TRIGGER_ROLE_COUNT };
const char *trigger_role_name(enum trigger_role r); /* "dmd", "strobe" */

/* A line by offset (>= 0) or by name (offset -1, name set). Neither: not wired. */
typedef struct trigger_line_config {
    int offset;
    const char *name;  /* borrowed during trigger_open */
    int active_low;    /* 1: the electrical low level is "active"; edges are reported in active terms */
} trigger_line_config;

typedef struct trigger_config {
    const char *chip;       /* "/dev/gpiochip0", "gpiochip0", or the chip's label ("pinctrl-bcm2711") */
    const char *consumer;   /* label shown by gpioinfo; NULL: "scicap" */
    trigger_line_config output;
    trigger_line_config inputs[TRIGGER_ROLE_COUNT]; /* indexed by enum trigger_role */
    const void *backend_options; /* backend-specific, borrowed (sim: const trigger_sim_options *) */
} trigger_config;

/* No chip, every line unwired (offset -1). */
trigger_config trigger_config_default(void);

/* {"chip": "gpiochip0", "consumer": "scicap", "output": 17 | "NAME" | {"line": 17, "active_low": true},
 *  "dmd_input": ..., "strobe_input": ...}. Strings borrowed from obj. SCI_ECONFIG naming the key. */
int trigger_config_from_json(const json_t *obj, const char *where, trigger_config *out, sci_error *err);

typedef struct trigger_event {
    int64_t timestamp_ns;   /* kernel timestamp, CLOCK_MONOTONIC */
    enum trigger_role role;
    int rising;             /* 1: became active; 0: became inactive */
    uint32_t line_seqno;    /* per-line event number from the kernel (uAPI v2), or counted by scicap (v1) */
} trigger_event;

typedef struct trigger_identity {
    char backend[16];
    char chip[64];        /* chip name, "gpiochip0" */
    char label[64];       /* chip label */
    int output_offset;    /* resolved offsets, -1 if not wired */
    int input_offset[TRIGGER_ROLE_COUNT];
} trigger_identity;

typedef struct trigger_stats {
    uint64_t pulses;
    uint64_t events[TRIGGER_ROLE_COUNT];
    uint64_t lost_events;   /* gaps in line_seqno (uAPI v2 only; v1 drops silently) */
} trigger_stats;

typedef struct trigger_ops {
    const char *name;
    int (*open)(void **state, const trigger_config *cfg, sci_error *err);
    void (*close)(void *state);
    void (*identity)(void *state, trigger_identity *out);
    /* Drive the output active for width_us, then inactive. *t_ns: host time just before the line went active
     * (CLOCK_MONOTONIC; the sim reports when its simulated edge happened). Blocks for width_us. */
    int (*pulse)(void *state, uint32_t width_us, int64_t *t_ns, sci_error *err);
    /* Wait up to timeout_ns for events and return up to max of them, oldest first. *count 0 on timeout. */
    int (*read_events)(void *state, int64_t timeout_ns, trigger_event *ev, int max, int *count, sci_error *err);
    /* Discard queued events (stale edges from before a snapshot). */
    int (*flush)(void *state, sci_error *err);
} trigger_ops;

typedef struct trigger trigger;

int trigger_open(trigger **out, const trigger_ops *ops, const trigger_config *cfg, sci_error *err);
void trigger_close(trigger *t); /* NULL is harmless; releases the lines */
void trigger_identity_get(const trigger *t, trigger_identity *out);
void trigger_stats_get(const trigger *t, trigger_stats *out);
void *trigger_backend_state(trigger *t, const trigger_ops *ops);
/* -ENOTCONN if no output line is wired. */
int trigger_pulse(trigger *t, uint32_t width_us, int64_t *t_ns, sci_error *err);
int trigger_read_events(trigger *t, int64_t timeout_ns, trigger_event *ev, int max, int *count, sci_error *err);
int trigger_flush(trigger *t, sci_error *err);
json_t *trigger_identity_json(const trigger_identity *id);

#endif
