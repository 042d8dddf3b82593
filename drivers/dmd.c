/* drivers/dmd.c — the DMD front end: the opaque handle and every call through the backend's table (see the
 * header). */
#include "drivers/dmd.h"

#include <errno.h>
#include <stdlib.h>

struct dmd {
    const dmd_ops *ops;
    void *state;
};

dmd_config dmd_config_default(void) { return (dmd_config){.timeout_ms = 1000}; }

int dmd_open(dmd **out, const dmd_ops *ops, const dmd_config *cfg, sci_error *err)
{
    *out = NULL;
    if (!ops)
        return sci_error_set(err, -EINVAL, "dmd: no backend");
    dmd *d = calloc(1, sizeof *d);
    if (!d)
        return sci_error_set(err, -ENOMEM, "dmd (%s): out of memory", ops->name);
    d->ops = ops;
    int rc = ops->open(&d->state, cfg, err);
    if (rc < 0) {
        free(d);
        return rc;
    }
    *out = d;
    return 0;
}

void dmd_close(dmd *d)
{
    if (!d)
        return;
    d->ops->close(d->state);
    free(d);
}

int dmd_identify(dmd *d, dmd_identity *id, sci_error *err) { return d->ops->identify(d->state, id, err); }
int dmd_upload(dmd *d, const sci_cube *masks, sci_error *err) { return d->ops->upload(d->state, masks, err); }
int dmd_set_timing(dmd *d, const dmd_timing *t, sci_error *err) { return d->ops->set_timing(d->state, t, err); }
int dmd_start(dmd *d, sci_error *err) { return d->ops->start(d->state, err); }
int dmd_stop(dmd *d, sci_error *err) { return d->ops->stop(d->state, err); }
int dmd_status_get(dmd *d, dmd_status *st, sci_error *err) { return d->ops->status(d->state, st, err); }
int dmd_poll(dmd *d, int timeout_ms, sci_error *err) { return d->ops->poll(d->state, timeout_ms, err); }

const dmd_ops *dmd_backend(const dmd *d) { return d->ops; }
void *dmd_backend_state(const dmd *d, const dmd_ops *ops) { return d && d->ops == ops ? d->state : NULL; }
