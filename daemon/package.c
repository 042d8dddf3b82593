/* daemon/package.c — a frame taken becomes a stored snapshot (see the header). */
#include "daemon/package.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>

#include "daemon/timestamp.h"

static int frame_cube(const camera_frame *f, sci_cube **out, sci_error *err)
{
    int rc = sci_cube_new(out, (int)f->width, (int)f->height, 1, err);
    if (rc < 0)
        return rc;
    size_t np = (size_t)f->width * f->height;
    for (size_t i = 0; i < np; i++)
        (*out)->data[i] = (float)f->data[i];
    return 0;
}

int scicapd_package_snapshot(const scicapd_package_in *in, scicapd_snapshot **out, sci_error *err)
{
    const scicapd_job *j = in->job;
    const scicapd_capture_args *c = &j->capture;
    const sci_cube *ideal = in->dmd_masks;
    scicapd_snapshot *s = calloc(1, sizeof *s);
    sci_problem *p = calloc(1, sizeof *p);
    int rc = -ENOMEM;
    if (!s || !p) {
        free(s);
        free(p);
        return sci_error_set(err, -ENOMEM, "acquire: out of memory");
    }
    s->problem = p;
    s->index = in->index;
    if ((rc = frame_cube(&in->shot->frame, &s->raw, err)) < 0 || (rc = sci_cube_clone(&s->dmd_masks, ideal, err)) < 0 ||
        (rc = sci_cube_new(&p->meas, s->raw->w, s->raw->h, 1, err)) < 0)
        goto fail;
    char key[96];
    snprintf(key, sizeof key, "masks-%s", c->mask_set.name);
    const scicapd_calib *dark = scicapd_calibs_get(in->calibs, "dark"), *cm = scicapd_calibs_get(in->calibs, key);
    if (dark && !sci_cube_same_shape(dark->data, s->raw))
        dark = NULL;
    if (cm && (cm->data->w != s->raw->w || cm->data->h != s->raw->h || cm->data->n != ideal->n))
        cm = NULL; /* measured masks are at the sensor's size, one per mask of the set */
    double cpu = cm && cm->counts_per_unit > 0 ? cm->counts_per_unit : in->counts_per_unit;
    double level = dark ? 0 : in->dark_level;
    for (size_t i = 0; i < sci_cube_count(s->raw); i++)
        p->meas->data[i] = (float)((s->raw->data[i] - (dark ? dark->data->data[i] : level)) / cpu);
    if (cm)
        rc = sci_cube_clone(&p->mask, cm->data, err);
    else if ((rc = scicapd_devices_camera_masks(in->dev, ideal, s->raw->w, s->raw->h, &p->mask, err)) == 0)
        rc = sci_error_set(err, SCI_ESHAPE, "the DMD is %d×%d and the camera %d×%d: without measured masks the "
                           "snapshot cannot be reconstructed; run `scicap calibrate --masks --mask-set %s` first",
                           ideal->w, ideal->h, s->raw->w, s->raw->h, c->mask_set.name);
    if (rc < 0)
        goto fail;
    if (dark && (rc = sci_cube_clone(&s->dark, dark->data, err)) < 0)
        goto fail;
    if ((rc = scicapd_devices_truth(in->dev, ideal->n, &p->truth, err)) < 0)
        goto fail;
    p->peak = 1;
    json_t *cal = json_object();
    if (dark)
        json_object_set(cal, "dark", dark->record);
    if (cm)
        json_object_set(cal, "masks", cm->record);
    json_object_set_new(cal, "kind", json_string(cm ? "measured-masks" : dark ? "dark-only" : "none"));
    s->calibration = cal;
    s->broken = in->shot->report.broken;
    json_t *m = capture_snapshot_meta_json(in->shot);
    if (!m) {
        rc = sci_error_set(err, -ENOMEM, "acquire: out of memory");
        goto fail;
    }
    json_object_set_new(m, "format", json_string("scicap-capture"));
    json_object_set_new(m, "version", json_integer(1));
    json_object_set_new(m, "software", json_pack("{s:s, s:s}", "name", "scicapd", "version", SCICAP_VERSION));
    json_object_set_new(m, "job", json_integer((json_int_t)j->id));
    json_object_set_new(m, "snapshot_index", json_integer(in->index));
    json_object_set_new(m, "settings",
                        json_pack("{s:s, s:i, s:I, s:I, s:I, s:s, s:f, s:f, s:s}", "mask_set", c->mask_set.name,
                                  "mask_count", ideal->n, "pattern_us", (json_int_t)c->pattern_us, "dark_us",
                                  (json_int_t)c->dark_us, "exposure_us", (json_int_t)in->exposure_us,
                                  "sync_mode", sync_mode_name(c->sync), "counts_per_unit", cpu, "dark_level_counts",
                                  level, "calibration", cm ? "measured-masks" : dark ? "dark-only" : "none"));
    json_object_set_new(m, "devices", scicapd_devices_json(in->dev));
    json_object_set_new(m, "requested", json_pack("{s:I}", "mono_ns", (json_int_t)j->submitted_ns));
    json_object_set_new(m, "captured", scicapd_time_json(in->shot->start_ns));
    scicapd_devices_snapshot_meta(in->dev, ideal->n, m); /* camera_trigger, simulated */
    s->meta = m;
    *out = s;
    return 0;
fail:
    scicapd_snapshot_free(in->jobs, s);
    return rc;
}
