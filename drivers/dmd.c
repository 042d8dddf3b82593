/* drivers/dmd.c — the DMD front end: every call goes through the backend's ops table (see the header). */
#include "drivers/dmd.h"

#include <errno.h>

dmd_config dmd_config_default(void) { return (dmd_config){.timeout_ms = 1000}; }

int dmd_open(dmd *d, const dmd_ops *ops, const dmd_config *cfg, sci_error *err)
{
    d->ops = ops;
    d->state = 0;
    int rc = ops->open(&d->state, cfg, err);
    if (rc < 0)
        d->ops = 0;
    return rc;
}

void dmd_close(dmd *d)
{
    if (!d)
        return;
    if (d->ops)
        d->ops->close(d->state);
    d->ops = 0;
    d->state = 0;
}

int dmd_identify(dmd *d, dmd_identity *id, sci_error *err) { return d->ops->identify(d->state, id, err); }
int dmd_upload(dmd *d, const sci_cube *masks, sci_error *err) { return d->ops->upload(d->state, masks, err); }
int dmd_set_timing(dmd *d, const dmd_timing *t, sci_error *err) { return d->ops->set_timing(d->state, t, err); }
int dmd_start(dmd *d, sci_error *err) { return d->ops->start(d->state, err); }
int dmd_stop(dmd *d, sci_error *err) { return d->ops->stop(d->state, err); }
int dmd_status_get(dmd *d, dmd_status *st, sci_error *err) { return d->ops->status(d->state, st, err); }
int dmd_poll(dmd *d, int timeout_ms, sci_error *err) { return d->ops->poll(d->state, timeout_ms, err); }

void *dmd_backend_state(const dmd *d, const dmd_ops *ops) { return d && d->ops == ops ? d->state : NULL; }
