/* drivers/dmd.h — the DMD device interface (docs/architecture.md, Contracts: Devices).
 *
 * A DMD shows N binary masks per camera exposure. A backend is a const dmd_ops table; an open device is the opaque
 * `dmd` handle (the table plus the backend's state), used through the dmd_* calls below, never the table directly —
 * the same shape as camera.h and trigger.h. Backends: "dlpc900" (drivers/dmd_dlpc900.c, TI DLPC900 over USB HID,
 * or its in-process emulator) and "sim" (sim/dmd_sim.h). The caller picks the table by its name at run time
 * (dmd_backend_find, drivers/backends.h, with sim/'s tables passed in by the layer that knows both).
 *
 *     dmd *dev;
 *     dmd_config cfg = dmd_config_default();
 *     cfg.serial = "A1B2C3";                  // NULL: the first device found
 *     if (dmd_open(&dev, dmd_backend_find("dlpc900", NULL, &err), &cfg, &err) < 0) ...
 *     dmd_upload(dev, masks, &err);           // w×h×N cube of 0/1, once per mask set
 *     dmd_set_timing(dev, &(dmd_timing){.exposure_us = 500, .dark_us = 0, .trigger = DMD_TRIGGER_INTERNAL}, &err);
 *     dmd_start(dev, &err);  ...  dmd_stop(dev, &err);
 *     dmd_close(dev);
 *
 * Masks: a `const sci_cube *` (base/cube.h) of w×h×N with N ≤ identity.max_masks; a value ≥ 0.5 turns the mirror
 * on (towards the sensor), below 0.5 off; NaN/Inf are refused. w×h must equal the DMD size. Mask k is shown k-th.
 * Timing: per-pattern exposure and dark time in µs; arrays (borrowed, N values) override the scalar values.
 * Order of calls: upload and set_timing in either order (upload uses the timing set so far, set_timing after an
 * upload reprograms the pattern table without re-uploading images); start needs an upload; stop is always safe.
 *
 * Errors: 0 or a negative code with a message naming the device (model and serial) and, for device errors
 * (SCI_EDEVICE), the command, the device's error code and its text. -ENODEV: the device is unplugged (calls fail
 * fast until it returns; the backend re-opens it by serial and reports DMD_EVENT_CONNECTED, after which masks must
 * be uploaded again). -ETIMEDOUT: no answer. On any error during upload or start the backend leaves the device
 * stopped.
 *
 * Events: `on_event` is called from inside dmd_poll (and from any call that notices an unplug), on the caller's
 * thread, never from another thread. Threads: a dmd handle is used by one thread at a time.
 */
#ifndef SCICAP_DRIVERS_DMD_H
#define SCICAP_DRIVERS_DMD_H

#include <stdint.h>

#include "base/cube.h"
#include "base/error.h"
#include "base/log.h"

typedef enum dmd_trigger_mode {
    DMD_TRIGGER_INTERNAL = 0, /* the DMD's own timer advances patterns */
    DMD_TRIGGER_EXTERNAL = 1, /* each pattern waits for a rising (or falling) edge on trigger-in */
} dmd_trigger_mode;

typedef enum dmd_event {
    DMD_EVENT_DISCONNECTED = 1, /* unplugged or stopped answering: masks are lost */
    DMD_EVENT_CONNECTED = 2,    /* (re)opened: upload again before start */
} dmd_event;

/* `serial` is borrowed for the duration of the call. */
typedef void (*dmd_event_fn)(void *user, dmd_event ev, const char *serial);

typedef struct dmd_config {
    const char *serial;       /* device to open (borrowed during open); NULL = the first one found */
    int timeout_ms;           /* per reply; 0 = 1000 */
    dmd_event_fn on_event;    /* may be NULL */
    void *event_user;
    const sci_log *log;       /* may be NULL; borrowed for the life of the device */
    void *emulator;           /* dlpc900 only: a dlpc900_emu * to drive instead of USB (borrowed; outlives the dmd) */
    int width, height;        /* sim only: DMD size (0 = 1920×1080) */
    const void *backend_options; /* backend-specific, borrowed during open (a wrapper's own state, e.g.) */
} dmd_config;

/* timeout_ms 1000, everything else zero / NULL. */
dmd_config dmd_config_default(void);

typedef struct dmd_identity {
    char backend[16];   /* "dlpc900", "sim" */
    char model[32];     /* "DLP6500" */
    char serial[64];
    char firmware[32];  /* "6.0.0" */
    int width, height;  /* mirrors */
    int max_masks;      /* 1-bit patterns the device holds */
    int min_exposure_us;
} dmd_identity;

typedef struct dmd_timing {
    uint32_t exposure_us;        /* per pattern, ≥ identity.min_exposure_us */
    uint32_t dark_us;            /* after each pattern */
    const uint32_t *exposure_us_each; /* N values or NULL (borrowed during the call) */
    const uint32_t *dark_us_each;     /* N values or NULL */
    dmd_trigger_mode trigger;
    uint32_t trigger_delay_us;   /* external: delay after the edge; 0 = device default (105 µs) */
    int trigger_falling;         /* external: advance on the falling edge */
    uint32_t passes;             /* times the sequence is shown per start; 0 = repeat until stop */
} dmd_timing;

typedef struct dmd_status {
    int connected;
    int running;
    int loaded_masks;      /* masks on the device, 0 after a reconnect */
    int error_code;        /* device error code (0 = none); backend-specific meaning */
    char error_text[128];  /* "" when none */
} dmd_status;

typedef struct dmd_ops {
    const char *name;
    int (*open)(void **state, const dmd_config *cfg, sci_error *err);
    void (*close)(void *state);
    int (*identify)(void *state, dmd_identity *id, sci_error *err);
    int (*upload)(void *state, const sci_cube *masks, sci_error *err);
    int (*set_timing)(void *state, const dmd_timing *t, sci_error *err);
    int (*start)(void *state, sci_error *err);
    int (*stop)(void *state, sci_error *err);
    int (*status)(void *state, dmd_status *st, sci_error *err);
    /* Process hotplug notifications for up to timeout_ms (0 = do not wait); calls on_event. */
    int (*poll)(void *state, int timeout_ms, sci_error *err);
} dmd_ops;

/* An open DMD: the backend's table and its state, behind the dmd_* calls (opaque, like camera and trigger). */
typedef struct dmd dmd;

/* Backends: this one here; every one by name through drivers/backends.h. */
extern const dmd_ops dmd_dlpc900_ops;

/* Open `ops` into *out (NULL on failure: nothing is left open). */
int dmd_open(dmd **out, const dmd_ops *ops, const dmd_config *cfg, sci_error *err);
/* Stops the sequence (best effort) and releases the device. NULL is harmless. */
void dmd_close(dmd *d);
int dmd_identify(dmd *d, dmd_identity *id, sci_error *err);
int dmd_upload(dmd *d, const sci_cube *masks, sci_error *err);
int dmd_set_timing(dmd *d, const dmd_timing *t, sci_error *err);
int dmd_start(dmd *d, sci_error *err);
int dmd_stop(dmd *d, sci_error *err);
int dmd_status_get(dmd *d, dmd_status *st, sci_error *err);
/* Hotplug notifications for up to timeout_ms (0 = do not wait); on_event is called from here. */
int dmd_poll(dmd *d, int timeout_ms, sci_error *err);
/* The backend's table (its `name` is the config's spelling). */
const dmd_ops *dmd_backend(const dmd *d);
/* The backend's state if d runs on `ops`, else NULL: how sim/ reaches its simulator-only queries. */
void *dmd_backend_state(const dmd *d, const dmd_ops *ops);

#endif
