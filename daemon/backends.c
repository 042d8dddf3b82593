/* daemon/backends.c — the device tables of scicapd (see the header). */
#include "daemon/backends.h"

#include <stdio.h>
#include <string.h>

#include "drivers/backends.h"
#include "drivers/camera_v4l2.h"
#include "sim/camera_sim.h"
#include "sim/dmd_sim.h"
#include "sim/trigger_sim.h"

/* The backends of the layer above drivers, searched after the drivers' own (drivers/backends.h). */
static const dmd_ops *const sim_dmds[] = {&dmd_sim_ops, NULL};
static const camera_ops *const sim_cameras[] = {&camera_sim_ops, NULL};
static const trigger_ops *const sim_triggers[] = {&trigger_sim_ops, NULL};

static int parse_generic(const json_t *obj, const char *where, camera_config *cfg, scicapd_camera_opts *opts,
                         sci_error *err)
{
    (void)opts;
    return camera_config_from_json(obj, where, cfg, err);
}

static int parse_aravis(const json_t *obj, const char *where, camera_config *cfg, scicapd_camera_opts *opts,
                        sci_error *err)
{
    return camera_aravis_config_from_json(obj, where, cfg, &opts->aravis, err);
}

/* Cameras whose parsing or message differs from the generic one. */
static const scicapd_camera_backend cameras[] = {
    {.ops = &camera_v4l2_ops, .parse = parse_generic,
     .locate_hint = "the v4l2 camera needs \"device\" (best a /dev/v4l/by-id/... path), or \"card\" and/or "
                    "\"bus_info\" to find it"},
    {.ops = &camera_aravis_ops, .parse = parse_aravis,
     .locate_hint = "the aravis camera needs \"device\" (the Aravis device id, e.g. \"Basler-21234567\", or a "
                    "GigE Vision camera's IP address), or \"card\" (model) and/or \"bus_info\" (serial)"},
    {.ops = &camera_sim_ops, .parse = NULL, .simulated = 1},
};

int scicapd_camera_backend_get(const char *name, scicapd_camera_backend *out, sci_error *err)
{
    const camera_ops *ops = camera_backend_find(name, sim_cameras, err);
    if (!ops)
        return err ? err->code : SCI_ECONFIG;
    for (size_t i = 0; i < sizeof cameras / sizeof cameras[0]; i++)
        if (cameras[i].ops == ops) {
            *out = cameras[i];
            return 0;
        }
    *out = (scicapd_camera_backend){.ops = ops, .parse = parse_generic,
                                    .locate_hint = "the camera needs \"device\", or \"card\" and/or \"bus_info\" "
                                                   "to find it"};
    return 0;
}

const trigger_ops *scicapd_trigger_backend_find(const char *name, sci_error *err)
{
    return trigger_backend_find(name, sim_triggers, err);
}

const dmd_ops *scicapd_dmd_backend_find(const char *name, sci_error *err)
{
    return dmd_backend_find(name, sim_dmds, err);
}

int scicapd_trigger_simulated(const trigger_ops *ops) { return ops == &trigger_sim_ops; }
int scicapd_dmd_is_dlpc900(const dmd_ops *ops) { return ops == &dmd_dlpc900_ops; }

int scicapd_camera_is_fake(const scicapd_camera_backend *b, const camera_config *cfg)
{
    /* "Fake_1" is the only id that enables Aravis's in-process fake (drivers/camera_aravis.h) */
    return b && b->ops == &camera_aravis_ops && cfg->device && strcmp(cfg->device, "Fake_1") == 0;
}

int scicapd_camera_software_trigger(const scicapd_camera_backend *b, const scicapd_camera_opts *opts)
{
    return b && b->ops == &camera_aravis_ops && opts->aravis.trigger == CAMERA_ARAVIS_TRIGGER_SOFTWARE;
}
