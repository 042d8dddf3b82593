/* daemon/backends.h — the device backends scicapd can open, looked up by the name in their ops table.
 *
 * The daemon is the layer that knows both the drivers' hardware backends (drivers/backends.h) and the simulated
 * devices of sim/ (the "sim" DMD, and the simulated bench's camera and trigger, sim/bench.h), which drivers may
 * not name: so these lookups pass sim/'s tables as the `extra` list of the drivers' lookup, and the configuration
 * (daemon/config.c: validation) and the devices (daemon/devices.c: opening) both ask here. Adding a backend is one
 * row in drivers/backends.c (or in the sim lists of backends.c); a camera whose JSON has keys of its own adds a
 * parser row to the camera table below.
 *
 *     scicapd_camera_backend b;               // how to parse and open the configured camera
 *     if (scicapd_camera_backend_get("aravis", &b, &err) < 0) ...   // SCI_ECONFIG: unknown, naming every known one
 *     scicapd_camera_opts opts;               // the backend's options, filled by parse; keep until camera_open
 *     camera_config cc;
 *     if (b.parse && b.parse(obj, "devices.camera", &cc, &opts, &err) == 0) camera_open(&cam, b.ops, &cc, &err);
 *
 * Strings in the parsed camera_config and options point into the JSON object (borrowed): keep it, the config
 * and the options alive until camera_open returns. Const tables, no state: thread-safe.
 */
#ifndef SCICAP_DAEMON_BACKENDS_H
#define SCICAP_DAEMON_BACKENDS_H

#include <jansson.h>

#include "base/error.h"
#include "drivers/camera.h"
#include "drivers/camera_aravis.h"
#include "drivers/dmd.h"
#include "drivers/trigger.h"

/* Room for any backend's options (camera_config.backend_options points into it after parse). */
typedef union scicapd_camera_opts {
    camera_aravis_options aravis;
} scicapd_camera_opts;

typedef struct scicapd_camera_backend {
    const camera_ops *ops;    /* ops->name is the config's devices.camera.backend */
    /* Parse the camera object (daemon keys already removed) into cfg and opts; SCI_ECONFIG naming where.key.
     * NULL: the backend takes no settings (the simulated camera: its size is the scene's). */
    int (*parse)(const json_t *obj, const char *where, camera_config *cfg, scicapd_camera_opts *opts,
                 sci_error *err);
    const char *locate_hint;  /* what the message says when nothing names the camera to open */
    int simulated;            /* part of the simulated bench (sim/bench.h), opened with the simulated trigger */
} scicapd_camera_backend;

/* The camera backend called `name`: 0 with *out filled (a hardware backend without a row of its own gets the
 * generic parser, camera_config_from_json); SCI_ECONFIG "camera backend \"x\" is unknown (known: ...)". */
int scicapd_camera_backend_get(const char *name, scicapd_camera_backend *out, sci_error *err);
/* The trigger and DMD tables called `name`, or NULL with SCI_ECONFIG naming every known one. */
const trigger_ops *scicapd_trigger_backend_find(const char *name, sci_error *err);
const dmd_ops *scicapd_dmd_backend_find(const char *name, sci_error *err);
/* 1 for the simulated bench's trigger (it takes no settings and pairs with the simulated camera). */
int scicapd_trigger_simulated(const trigger_ops *ops);
/* 1 for a DMD backend whose device may run on the in-process DLPC900 emulator ("emulator": true and the other
 * DLPC900 keys of devices.dmd). */
int scicapd_dmd_is_dlpc900(const dmd_ops *ops);

/* 1 when the parsed camera is itself simulated inside the process (Aravis's "Fake_1"): such a camera may pair
 * with the simulated trigger (docs/config.md, Devices). */
int scicapd_camera_is_fake(const scicapd_camera_backend *b, const camera_config *cfg);

/* 1 when the parsed camera waits for the host's software trigger (aravis "trigger": "software"): the daemon fires
 * it where the exposure starts (daemon/devices.c wraps the trigger so that its pulse does). */
int scicapd_camera_software_trigger(const scicapd_camera_backend *b, const scicapd_camera_opts *opts);

#endif
