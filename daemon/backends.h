/* daemon/backends.h — the camera backends scicapd can open, as one table looked up by name.
 *
 * The configuration (daemon/config.c) validates a camera object with the backend's own parser at load time;
 * the devices (daemon/devices.c) parse it again and open it through the same entry, so the two never disagree
 * about which parser or ops table a backend name means. "sim" is not here: the simulated camera belongs to
 * the simulated bench (daemon/simbench.h), which opens it with its trigger.
 *
 *     scicapd_camera_opts opts;               // the backend's options, filled by parse; keep until camera_open
 *     camera_config cc;
 *     const scicapd_camera_backend *b = scicapd_camera_backend_find("aravis");
 *     if (b && b->parse(obj, "devices.camera", &cc, &opts, &err) == 0) camera_open(&cam, b->ops, &cc, &err);
 *
 * Strings in the parsed camera_config and options point into the JSON object (borrowed): keep it, the config
 * and the options alive until camera_open returns. Const table, no state: thread-safe.
 */
#ifndef SCICAP_DAEMON_BACKENDS_H
#define SCICAP_DAEMON_BACKENDS_H

#include <jansson.h>

#include "base/error.h"
#include "drivers/camera.h"
#include "drivers/camera_aravis.h"

/* Room for any backend's options (camera_config.backend_options points into it after parse). */
typedef union scicapd_camera_opts {
    camera_aravis_options aravis;
} scicapd_camera_opts;

typedef struct scicapd_camera_backend {
    const camera_ops *ops;    /* ops->name is the config's devices.camera.backend */
    /* Parse the camera object (daemon keys already removed) into cfg and opts; SCI_ECONFIG naming where.key. */
    int (*parse)(const json_t *obj, const char *where, camera_config *cfg, scicapd_camera_opts *opts,
                 sci_error *err);
    const char *locate_hint;  /* what the message says when nothing names the camera to open */
} scicapd_camera_backend;

/* The entry for `name`, or NULL ("sim" and unknown names). */
const scicapd_camera_backend *scicapd_camera_backend_find(const char *name);

/* 1 when the parsed camera is itself simulated inside the process (Aravis's "Fake_1"): such a camera may pair
 * with the simulated trigger (docs/config.md, Devices). */
int scicapd_camera_is_fake(const scicapd_camera_backend *b, const camera_config *cfg);

/* 1 when the parsed camera waits for the host's software trigger (aravis "trigger": "software"): the daemon fires
 * it where the exposure starts (daemon/devices.c wraps the trigger so that its pulse does). */
int scicapd_camera_software_trigger(const scicapd_camera_backend *b, const scicapd_camera_opts *opts);

#endif
