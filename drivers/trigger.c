#include "drivers/trigger.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

struct trigger {
    const trigger_ops *ops;
    void *state;
    trigger_identity id;
    trigger_stats stats;
    uint32_t last_seqno[TRIGGER_ROLE_COUNT];
    int seen[TRIGGER_ROLE_COUNT];
};

const char *trigger_role_name(enum trigger_role r)
{
    return r == TRIGGER_ROLE_DMD ? "dmd" : r == TRIGGER_ROLE_STROBE ? "strobe" : "unknown";
}

trigger_config trigger_config_default(void)
{
    trigger_config c;
    memset(&c, 0, sizeof c);
    c.output.offset = -1;
    for (int r = 0; r < TRIGGER_ROLE_COUNT; r++)
        c.inputs[r].offset = -1;
    return c;
}

int trigger_open(trigger **out, const trigger_ops *ops, const trigger_config *cfg, sci_error *err)
{
    *out = NULL;
    trigger *t = calloc(1, sizeof *t);
    if (!t)
        return sci_error_set(err, -ENOMEM, "trigger: out of memory");
    t->ops = ops;
    int rc = ops->open(&t->state, cfg, err);
    if (rc < 0) {
        free(t);
        return rc;
    }
    ops->identity(t->state, &t->id);
    *out = t;
    return 0;
}

void trigger_close(trigger *t)
{
    if (!t)
        return;
    t->ops->close(t->state);
    free(t);
}

void trigger_identity_get(const trigger *t, trigger_identity *out) { *out = t->id; }
void trigger_stats_get(const trigger *t, trigger_stats *out) { *out = t->stats; }
void *trigger_backend_state(trigger *t, const trigger_ops *ops) { return (t && t->ops == ops) ? t->state : NULL; }

int trigger_pulse(trigger *t, uint32_t width_us, int64_t *t_ns, sci_error *err)
{
    if (t->id.output_offset < 0)
        return sci_error_set(err, -ENOTCONN, "%s: no trigger output line is configured", t->id.chip);
    int rc = t->ops->pulse(t->state, width_us, t_ns, err);
    if (rc == 0)
        t->stats.pulses++;
    return rc;
}

int trigger_read_events(trigger *t, int64_t timeout_ns, trigger_event *ev, int max, int *count, sci_error *err)
{
    *count = 0;
    int rc = t->ops->read_events(t->state, timeout_ns < 0 ? 0 : timeout_ns, ev, max, count, err);
    if (rc < 0)
        return rc;
    for (int i = 0; i < *count; i++) {
        enum trigger_role r = ev[i].role;
        if ((int)r < 0 || r >= TRIGGER_ROLE_COUNT)
            continue;
        t->stats.events[r]++;
        /* line_seqno gaps mean the kernel queue overflowed (uAPI v2). Backends without kernel seqnos number
         * events themselves, so they never show a gap. */
        if (t->seen[r] && ev[i].line_seqno - t->last_seqno[r] > 1 && ev[i].line_seqno - t->last_seqno[r] < 0x80000000u)
            t->stats.lost_events += ev[i].line_seqno - t->last_seqno[r] - 1;
        t->last_seqno[r] = ev[i].line_seqno;
        t->seen[r] = 1;
    }
    return 0;
}

int trigger_flush(trigger *t, sci_error *err)
{
    /* flushed edges are numbered by the kernel but never seen here: restart the gap tracking */
    memset(t->seen, 0, sizeof t->seen);
    return t->ops->flush(t->state, err);
}

json_t *trigger_identity_json(const trigger_identity *id)
{
    return json_pack("{s:s, s:s, s:s, s:i, s:i, s:i}", "backend", id->backend, "chip", id->chip, "label", id->label,
                     "output_line", id->output_offset, "dmd_input_line", id->input_offset[TRIGGER_ROLE_DMD],
                     "strobe_input_line", id->input_offset[TRIGGER_ROLE_STROBE]);
}

static int line_from_json(const json_t *v, const char *where, const char *key, trigger_line_config *out,
                          sci_error *err)
{
    if (!v)
        return 0;
    const json_t *line = v, *al = NULL;
    if (json_is_object(v)) {
        line = json_object_get(v, "line");
        al = json_object_get(v, "active_low");
        if (al && !json_is_boolean(al))
            return sci_error_set(err, SCI_ECONFIG, "%s.%s.active_low: must be true or false", where, key);
        const char *k;
        const json_t *x;
        json_object_foreach((json_t *)v, k, x) if (strcmp(k, "line") != 0 && strcmp(k, "active_low") != 0) return
            sci_error_set(err, SCI_ECONFIG, "%s.%s.%s: unknown key", where, key, k);
    }
    if (json_is_integer(line) && json_integer_value(line) >= 0 && json_integer_value(line) < 65536) {
        out->offset = (int)json_integer_value(line);
        out->name = NULL;
    } else if (json_is_string(line)) {
        out->offset = -1;
        out->name = json_string_value(line);
    } else
        return sci_error_set(err, SCI_ECONFIG, "%s.%s: must be a line offset (0..65535), a line name, or "
                             "{\"line\": ..., \"active_low\": bool}", where, key);
    out->active_low = al ? json_is_true(al) : 0;
    return 0;
}

int trigger_config_from_json(const json_t *obj, const char *where, trigger_config *out, sci_error *err)
{
    *out = trigger_config_default();
    if (!json_is_object(obj))
        return sci_error_set(err, SCI_ECONFIG, "%s: must be an object", where);
    const char *k;
    const json_t *v;
    json_object_foreach((json_t *)obj, k, v) {
        if (strcmp(k, "chip") && strcmp(k, "consumer") && strcmp(k, "output") && strcmp(k, "dmd_input") &&
            strcmp(k, "strobe_input"))
            return sci_error_set(err, SCI_ECONFIG, "%s.%s: unknown key", where, k);
    }
    const json_t *chip = json_object_get(obj, "chip"), *cons = json_object_get(obj, "consumer");
    if (!json_is_string(chip))
        return sci_error_set(err, SCI_ECONFIG, "%s.chip: required, a path, chip name or label", where);
    out->chip = json_string_value(chip);
    if (cons && !json_is_string(cons))
        return sci_error_set(err, SCI_ECONFIG, "%s.consumer: must be a string", where);
    out->consumer = cons ? json_string_value(cons) : NULL;
    int rc;
    if ((rc = line_from_json(json_object_get(obj, "output"), where, "output", &out->output, err)) < 0 ||
        (rc = line_from_json(json_object_get(obj, "dmd_input"), where, "dmd_input", &out->inputs[TRIGGER_ROLE_DMD],
                             err)) < 0 ||
        (rc = line_from_json(json_object_get(obj, "strobe_input"), where, "strobe_input",
                             &out->inputs[TRIGGER_ROLE_STROBE], err)) < 0)
        return rc;
    return 0;
}
