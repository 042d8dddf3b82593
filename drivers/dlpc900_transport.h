/* drivers/dlpc900_transport.h — how DLPC900 reports reach a device: a small ops table plus its state.
 *
 * Two implementations: hidapi/hidraw (drivers/dlpc900_hid.h) for hardware and the in-process emulator
 * (drivers/dlpc900_emu.h). The control layer (drivers/dlpc900_ctl.h) only sees this interface, so every test
 * of command order and error handling runs against the emulator with the code that drives hardware.
 *
 * Reports are 64 bytes without the report-ID byte (the hid transport adds it).
 * Return values: write → 0; read → bytes received (0 … 64); both → -ETIMEDOUT when nothing moved within
 * timeout_ms, -ENODEV when the device is gone (unplugged), -EIO for other failures, with a message in err.
 * A transport is used by one thread at a time.
 */
#ifndef SCICAP_DRIVERS_DLPC900_TRANSPORT_H
#define SCICAP_DRIVERS_DLPC900_TRANSPORT_H

#include <stdint.h>

#include "base/error.h"
#include "drivers/dlpc900_proto.h"

typedef struct dlpc900_transport_ops {
    const char *name; /* "hidraw", "emulator" */
    int (*write)(void *ctx, const uint8_t report[DLPC900_REPORT_SIZE], int timeout_ms, sci_error *err);
    int (*read)(void *ctx, uint8_t report[DLPC900_REPORT_SIZE], int timeout_ms, sci_error *err);
    void (*close)(void *ctx); /* releases ctx; may be NULL when ctx is borrowed */
} dlpc900_transport_ops;

typedef struct dlpc900_transport {
    const dlpc900_transport_ops *ops; /* NULL = not connected */
    void *ctx;
} dlpc900_transport;

static inline void dlpc900_transport_close(dlpc900_transport *t)
{
    if (t->ops && t->ops->close)
        t->ops->close(t->ctx);
    t->ops = 0;
    t->ctx = 0;
}

#endif
