/* drivers/backends.h — each device kind's backends, looked up by the name in their ops table.
 *
 * A backend is a const ops table (camera_ops, trigger_ops, dmd_ops) whose `name` is the spelling a configuration
 * uses: "v4l2", "aravis", "gpiod", "dlpc900", "sim". The drivers layer lists its own hardware backends here.
 * Backends of a higher layer — the simulated devices of sim/ — cannot be named by drivers (docs/architecture.md,
 * Layers), so whoever knows both layers (the daemon) passes them as `extra`: a NULL-terminated list searched after
 * the drivers' own.
 *
 *     static const dmd_ops *const sim_dmds[] = {&dmd_sim_ops, NULL};
 *     const dmd_ops *ops = dmd_backend_find(cfg_backend, sim_dmds, &err);
 *     if (!ops) ...   // SCI_ECONFIG: dmd backend "dlp" is unknown (known: dlpc900, sim)
 *     char known[128];
 *     dmd_backend_names(sim_dmds, known, sizeof known);   // "dlpc900, sim", for --help and messages
 *
 * Names match exactly (case-sensitive, like every config key). `extra` may be NULL. The first table of a name
 * wins, the drivers' own first. Const tables, no state: thread-safe.
 */
#ifndef SCICAP_DRIVERS_BACKENDS_H
#define SCICAP_DRIVERS_BACKENDS_H

#include <stddef.h>

#include "base/error.h"
#include "drivers/camera.h"
#include "drivers/dmd.h"
#include "drivers/trigger.h"

/* The drivers' own backends, NULL-terminated (borrowed, static): cameras v4l2, aravis; triggers gpiod; DMDs
 * dlpc900. (camera_skeleton_ops is a template, not a backend: it is not listed.) */
const camera_ops *const *camera_backends_builtin(void);
const trigger_ops *const *trigger_backends_builtin(void);
const dmd_ops *const *dmd_backends_builtin(void);

/* The table named `name` among the drivers' own backends, then `extra`. NULL when none is: err gets SCI_ECONFIG
 * "<kind> backend \"<name>\" is unknown (known: <every name>)" (a NULL name: "... no backend given (known: ...)"). */
const camera_ops *camera_backend_find(const char *name, const camera_ops *const *extra, sci_error *err);
const trigger_ops *trigger_backend_find(const char *name, const trigger_ops *const *extra, sci_error *err);
const dmd_ops *dmd_backend_find(const char *name, const dmd_ops *const *extra, sci_error *err);

/* Every name, drivers' own then `extra`, as "a, b, c" in buf (truncated to size - 1 bytes; always terminated when
 * size > 0). Returns buf. */
const char *camera_backend_names(const camera_ops *const *extra, char *buf, size_t size);
const char *trigger_backend_names(const trigger_ops *const *extra, char *buf, size_t size);
const char *dmd_backend_names(const dmd_ops *const *extra, char *buf, size_t size);

#endif
