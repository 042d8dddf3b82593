/* daemon/swtrigger.c — a trigger that also fires the camera's software trigger (see the header). */
#include "daemon/swtrigger.h"

#include <errno.h>
#include <stdlib.h>

#include "base/clock.h"
#include "drivers/camera_aravis.h"

typedef struct swtrigger {
    trigger *inner;
    camera *cam;
    uint64_t sent;
    int64_t last_ns;
} swtrigger;

static int sw_open(void **state, const trigger_config *cfg, sci_error *err)
{
    const scicapd_swtrigger_options *o = cfg->backend_options;
    if (!o || !o->inner || !o->cam)
        return sci_error_set(err, -EINVAL, "software trigger: needs the wrapped trigger and the camera");
    swtrigger *s = calloc(1, sizeof *s);
    if (!s)
        return sci_error_set(err, -ENOMEM, "software trigger: out of memory");
    s->inner = o->inner;
    s->cam = o->cam;
    *state = s;
    return 0;
}

static void sw_close(void *state)
{
    swtrigger *s = state;
    if (!s)
        return;
    trigger_close(s->inner);
    free(s);
}

static void sw_identity(void *state, trigger_identity *out)
{
    swtrigger *s = state;
    trigger_identity_get(s->inner, out);
}

static int sw_pulse(void *state, uint32_t width_us, int64_t *t_ns, sci_error *err)
{
    swtrigger *s = state;
    /* the DMD first: its sequence then starts no later than the exposure, as with a shared trigger line */
    int rc = trigger_pulse(s->inner, width_us, t_ns, err);
    if (rc < 0)
        return rc;
    int64_t t = sci_clock_mono_ns();
    if ((rc = camera_aravis_trigger_software(s->cam, err)) < 0)
        return rc;
    s->sent++;
    s->last_ns = t;
    return 0;
}

static int sw_read_events(void *state, int64_t timeout_ns, trigger_event *ev, int max, int *count, sci_error *err)
{
    swtrigger *s = state;
    return trigger_read_events(s->inner, timeout_ns, ev, max, count, err);
}

static int sw_flush(void *state, sci_error *err)
{
    swtrigger *s = state;
    return trigger_flush(s->inner, err);
}

const trigger_ops scicapd_swtrigger_ops = {
    .name = "software",
    .open = sw_open,
    .close = sw_close,
    .identity = sw_identity,
    .pulse = sw_pulse,
    .read_events = sw_read_events,
    .flush = sw_flush,
};

int scicapd_swtrigger_stats(trigger *t, uint64_t *sent, int64_t *last_ns)
{
    swtrigger *s = trigger_backend_state(t, &scicapd_swtrigger_ops);
    if (!s)
        return -EINVAL;
    *sent = s->sent;
    *last_ns = s->last_ns;
    return 0;
}
