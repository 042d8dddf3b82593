/* daemon/backends.c — the camera backend table (see the header). */
#include "daemon/backends.h"

#include <string.h>

#include "drivers/camera_v4l2.h"

static int parse_v4l2(const json_t *obj, const char *where, camera_config *cfg, scicapd_camera_opts *opts,
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

static const scicapd_camera_backend backends[] = {
    {.ops = &camera_v4l2_ops, .parse = parse_v4l2,
     .locate_hint = "the v4l2 camera needs \"device\" (best a /dev/v4l/by-id/... path), or \"card\" and/or "
                    "\"bus_info\" to find it"},
    {.ops = &camera_aravis_ops, .parse = parse_aravis,
     .locate_hint = "the aravis camera needs \"device\" (the Aravis device id, e.g. \"Basler-21234567\", or a "
                    "GigE Vision camera's IP address), or \"card\" (model) and/or \"bus_info\" (serial)"},
};

const scicapd_camera_backend *scicapd_camera_backend_find(const char *name)
{
    for (size_t i = 0; name && i < sizeof backends / sizeof backends[0]; i++)
        if (strcmp(backends[i].ops->name, name) == 0) /* the table's own name is the config's spelling */
            return &backends[i];
    return NULL;
}

int scicapd_camera_is_fake(const scicapd_camera_backend *b, const camera_config *cfg)
{
    /* "Fake_1" is the only id that enables Aravis's in-process fake (drivers/camera_aravis.h) */
    return b && b->ops == &camera_aravis_ops && cfg->device && strcmp(cfg->device, "Fake_1") == 0;
}

int scicapd_camera_software_trigger(const scicapd_camera_backend *b, const scicapd_camera_opts *opts)
{
    return b && b->ops == &camera_aravis_ops && opts->aravis.trigger == CAMERA_ARAVIS_TRIGGER_SOFTWARE;
}
