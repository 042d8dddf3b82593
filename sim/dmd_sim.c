#include "sim/dmd_sim.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"

typedef struct sim_dmd {
    dlpc900_emu *emu;
    dmd *inner;        /* the dlpc900 backend driving emu */
    int64_t started_ns;
} sim_dmd;

static void sim_close(void *state)
{
    sim_dmd *s = state;
    if (!s)
        return;
    dmd_close(s->inner); /* before the emulator it talks to */
    dlpc900_emu_free(s->emu);
    free(s);
}

static int sim_open(void **state, const dmd_config *cfg, sci_error *err)
{
    sim_dmd *s = calloc(1, sizeof *s);
    if (!s)
        return sci_error_set(err, -ENOMEM, "sim DMD: out of memory");
    const char *serial = cfg->serial ? cfg->serial : "SIM0001";
    dlpc900_emu_config ec = {.serial = serial, .width = cfg->width, .height = cfg->height};
    int rc = dlpc900_emu_new(&s->emu, &ec, err);
    if (rc < 0) {
        free(s);
        return rc;
    }
    dmd_config inner = *cfg;
    inner.serial = serial;
    inner.emulator = s->emu;
    if ((rc = dmd_open(&s->inner, &dmd_dlpc900_ops, &inner, err)) < 0) {
        sim_close(s);
        return rc;
    }
    *state = s;
    return 0;
}

static int sim_identify(void *state, dmd_identity *id, sci_error *err)
{
    sim_dmd *s = state;
    int rc = dmd_identify(s->inner, id, err);
    if (rc == 0)
        strcpy(id->backend, "sim");
    return rc;
}

static int sim_upload(void *state, const sci_cube *m, sci_error *err) { return dmd_upload(((sim_dmd *)state)->inner, m, err); }
static int sim_set_timing(void *state, const dmd_timing *t, sci_error *err)
{
    return dmd_set_timing(((sim_dmd *)state)->inner, t, err);
}

static int sim_start(void *state, sci_error *err)
{
    sim_dmd *s = state;
    int rc = dmd_start(s->inner, err);
    if (rc == 0)
        s->started_ns = sci_clock_mono_ns();
    return rc;
}

static int sim_stop(void *state, sci_error *err) { return dmd_stop(((sim_dmd *)state)->inner, err); }
static int sim_status(void *state, dmd_status *st, sci_error *err) { return dmd_status_get(((sim_dmd *)state)->inner, st, err); }
static int sim_poll(void *state, int timeout_ms, sci_error *err) { return dmd_poll(((sim_dmd *)state)->inner, timeout_ms, err); }

const dmd_ops dmd_sim_ops = {
    .name = "sim",
    .open = sim_open,
    .close = sim_close,
    .identify = sim_identify,
    .upload = sim_upload,
    .set_timing = sim_set_timing,
    .start = sim_start,
    .stop = sim_stop,
    .status = sim_status,
    .poll = sim_poll,
};

static sim_dmd *as_sim(const dmd *d) { return dmd_backend_state(d, &dmd_sim_ops); }

int dmd_sim_displayed_at(const dmd *d, int64_t t_ns)
{
    sim_dmd *s = as_sim(d);
    return s ? dlpc900_emu_displayed_at(s->emu, t_ns, NULL) : -EINVAL;
}

int64_t dmd_sim_started_ns(const dmd *d)
{
    sim_dmd *s = as_sim(d);
    return s ? s->started_ns : 0;
}

int dmd_sim_mask(const dmd *d, int index, uint8_t *out)
{
    sim_dmd *s = as_sim(d);
    return s ? dlpc900_emu_mask(s->emu, index, out) : -EINVAL;
}

dlpc900_emu *dmd_sim_emulator(const dmd *d)
{
    sim_dmd *s = as_sim(d);
    return s ? s->emu : NULL;
}
