/* daemon/calibrate.c — calibrate jobs (see the header). */
#include "daemon/calibrate.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "daemon/timestamp.h"

/* ---- the job ---- */

static int average(scicapd_rig *a, int n, int frames, uint32_t exposure, int dark, sci_cube *acc,
                   sci_error *err)
{
    memset(acc->data, 0, sci_cube_count(acc) * sizeof(float));
    for (int f = 0; f < frames; f++) {
        int rc = scicapd_rig_take(a, n, exposure, SYNC_MODE_HOST_MASTER, dark, err);
        if (rc < 0)
            return rc;
        const camera_frame *fr = &scicapd_rig_shot(a)->frame;
        if ((int)fr->width != acc->w || (int)fr->height != acc->h)
            return sci_error_set(err, SCI_ESHAPE, "calibration: frame %ux%u, expected %dx%d", fr->width, fr->height,
                                 acc->w, acc->h);
        for (size_t i = 0; i < sci_cube_frame_size(acc); i++)
            acc->data[i] += (float)fr->data[i] / (float)frames;
    }
    return 0;
}

/* A dark calibration: the DMD is not started, so no light reaches the sensor through the masks. The average of
 * the frames into *acc, written to the store and made current as "dark" (which then owns *acc: set to NULL);
 * *rec is its record. */
static int calibrate_dark(scicapd_rig *a, scicapd_job *j, const sci_cube *masks, uint32_t lat, sci_cube **acc,
                          json_t **rec, sci_error *err)
{
    const scicapd_calib_args *c = &j->calib;
    const scicapd_rig_env *env = scicapd_rig_env_get(a);
    int rc;
    uint32_t e = c->exposure_us ? c->exposure_us
                                : scicapd_auto_exposure_us(masks->n, c->pattern_us, c->dark_us, lat);
    scicapd_rig_post(a, j, "calibrate.started", json_pack("{s:s, s:i}", "kind", "dark", "frames", c->average));
    if ((rc = scicapd_rig_program(a, c->mask_set.name, masks, c->pattern_us, c->dark_us, SYNC_MODE_HOST_MASTER,
                                  err)) < 0 ||
        (rc = average(a, masks->n, c->average, e, 1, *acc, err)) < 0)
        return rc;
    double mean = 0;
    for (size_t i = 0; i < sci_cube_count(*acc); i++)
        mean += (*acc)->data[i];
    mean /= (double)sci_cube_count(*acc);
    *rec = json_pack("{s:s, s:I, s:i, s:f, s:o}", "kind", "dark", "exposure_us", (json_int_t)e, "frames",
                     c->average, "mean_counts", mean, "time", scicapd_time_json(sci_clock_mono_ns()));
    json_t *final = NULL;
    if ((rc = scicapd_store_write_calibration(env->store, "dark", *acc, *rec, &final, err)) < 0)
        return rc;
    scicapd_calibs_set(scicapd_rig_calibs(a), "dark", *acc, json_incref(final), 0);
    *acc = NULL;
    json_decref(*rec);
    *rec = final;
    return 0;
}

/* One mask's averaged frame acc, minus the dark (the dark frame, else dark_level), into dst; its white pixels
 * added to *white_sum and *white_n: the pixels the mask opens, known when a mirror maps to a pixel (ideal), else
 * the pixels brighter than half the brightest. */
static void calibrate_mask_frame(const sci_cube *acc, const scicapd_calib *dark, double dark_level,
                                 const float *ideal, float *dst, double *white_sum, double *white_n)
{
    float hi = 0;
    for (size_t i = 0; i < sci_cube_frame_size(acc); i++) {
        dst[i] = acc->data[i] - (dark ? dark->data->data[i] : (float)dark_level);
        hi = dst[i] > hi ? dst[i] : hi;
    }
    for (size_t i = 0; i < sci_cube_frame_size(acc); i++)
        if (ideal ? ideal[i] >= 0.5f : dst[i] > 0.5f * hi) {
            *white_sum += dst[i];
            (*white_n)++;
        }
}

/* Each mask alone on the white target (up only during this call), averaged at exposure e into acc, its frame of
 * result made by calibrate_mask_frame, progress posted; *white is the mean white level (0 with no white pixel). */
static int calibrate_masks_measure(scicapd_rig *a, scicapd_job *j, const sci_cube *masks, uint32_t e,
                                   const scicapd_calib *dark, double dark_level, sci_cube *acc, sci_cube *result,
                                   double *white, sci_error *err)
{
    const scicapd_calib_args *c = &j->calib;
    scicapd_devices *dev = scicapd_rig_devices(a);
    sci_cube *one;
    int rc;
    if ((rc = sci_cube_new(&one, masks->w, masks->h, 1, err)) < 0)
        return rc;
    scicapd_devices_white_target(dev, 1);
    double white_sum = 0, white_n = 0;
    for (int k = 0; k < masks->n && rc == 0; k++) {
        if (scicapd_rig_canceled(a, j)) {
            rc = SCI_ECANCELED;
            sci_error_set(err, rc, "canceled");
            break;
        }
        memcpy(one->data, sci_cube_frame(masks, k), sci_cube_frame_size(one) * sizeof(float));
        scicapd_rig_forget_upload(a);
        char tag[80];
        snprintf(tag, sizeof tag, ".calib-%d", k);
        if ((rc = scicapd_rig_program(a, tag, one, c->pattern_us, c->dark_us, SYNC_MODE_HOST_MASTER, err)) < 0 ||
            (rc = average(a, 1, c->average, e, 0, acc, err)) < 0)
            break;
        const float *ideal = masks->w == acc->w && masks->h == acc->h ? sci_cube_frame(masks, k) : NULL;
        calibrate_mask_frame(acc, dark, dark_level, ideal, sci_cube_frame(result, k), &white_sum, &white_n);
        scicapd_job_set_progress(scicapd_rig_env_get(a)->jobs, j, k + 1, masks->n, NAN);
        scicapd_rig_post(a, j, "calibrate.progress", json_pack("{s:i, s:i}", "mask", k + 1, "of", masks->n));
    }
    scicapd_devices_white_target(dev, 0);
    scicapd_rig_forget_upload(a);
    sci_cube_free(one);
    *white = white_n > 0 ? white_sum / white_n : 0;
    return rc;
}

/* A masks calibration: each mask alone on a white target, minus the dark calibration when it has the sensor's
 * size (else the configured dark level), divided by the white level, into *result; written to the store and made
 * current as "masks-<set>" (which then owns *result: set to NULL); *rec is its record. */
static int calibrate_masks(scicapd_rig *a, scicapd_job *j, const sci_cube *masks, uint32_t lat, sci_cube *acc,
                           sci_cube **result, json_t **rec, sci_error *err)
{
    const scicapd_calib_args *c = &j->calib;
    scicapd_calibs *calibs = scicapd_rig_calibs(a);
    const scicapd_calib *dark = scicapd_calibs_get(calibs, "dark");
    double unit, dark_level; /* without a dark frame: the configured level */
    scicapd_rig_scale(a, &unit, &dark_level);
    if (dark && !sci_cube_same_shape(dark->data, acc))
        dark = NULL;
    int rc;
    if ((rc = sci_cube_new(result, acc->w, acc->h, masks->n, err)) < 0)
        return rc;
    uint32_t e = c->exposure_us ? c->exposure_us : scicapd_auto_exposure_us(1, c->pattern_us, c->dark_us, lat);
    scicapd_rig_post(a, j, "calibrate.started", json_pack("{s:s, s:s, s:i}", "kind", "masks", "mask_set",
                                                          c->mask_set.name, "masks", masks->n));
    double white;
    if ((rc = calibrate_masks_measure(a, j, masks, e, dark, dark_level, acc, *result, &white, err)) < 0)
        return rc;
    if (!(white > 1))
        return sci_error_set(err, SCI_EDEVICE, "calibration: no light on the white target (mean %.1f counts)",
                             white);
    for (size_t i = 0; i < sci_cube_count(*result); i++)
        (*result)->data[i] /= (float)white;
    *rec = json_pack("{s:s, s:s, s:i, s:f, s:I, s:i, s:b, s:o}", "kind", "masks", "mask_set", c->mask_set.name,
                     "masks", masks->n, "counts_per_unit", white, "exposure_us", (json_int_t)e, "frames",
                     c->average, "dark_subtracted", dark != NULL, "time", scicapd_time_json(sci_clock_mono_ns()));
    char key[96];
    snprintf(key, sizeof key, "masks-%s", c->mask_set.name);
    json_t *final = NULL;
    if ((rc = scicapd_store_write_calibration(scicapd_rig_env_get(a)->store, key, *result, *rec, &final, err)) < 0)
        return rc;
    scicapd_calibs_set(calibs, key, *result, json_incref(final), white);
    *result = NULL;
    json_decref(*rec);
    *rec = final;
    return 0;
}

/* The job's end: its state and calibrate.done (with the record rec) or .failed / .canceled. */
static void calibrate_finish(scicapd_rig *a, scicapd_job *j, int rc, json_t *rec, const sci_error *err)
{
    const scicapd_rig_env *env = scicapd_rig_env_get(a);
    if (rc < 0) {
        scicapd_job_set_state(env->jobs, j, rc == SCI_ECANCELED ? SCICAPD_JOB_CANCELED : SCICAPD_JOB_FAILED, err->msg);
        scicapd_rig_post(a, j, rc == SCI_ECANCELED ? "calibrate.canceled" : "calibrate.failed",
                         json_pack("{s:s}", "error", err->msg));
    } else {
        scicapd_job_add_output(env->jobs, j, json_string_value(json_object_get(rec, "id")));
        scicapd_job_set_state(env->jobs, j, SCICAPD_JOB_DONE, NULL);
        scicapd_rig_post(a, j, "calibrate.done", json_incref(rec));
    }
}

void scicapd_calibrate_run(scicapd_rig *a, scicapd_job *j)
{
    const scicapd_calib_args *c = &j->calib;
    sci_error err = {0};
    scicapd_job_set_state(scicapd_rig_env_get(a)->jobs, j, SCICAPD_JOB_RUNNING, NULL);
    int rc = 0;
    json_t *rec = NULL;
    sci_cube *acc = NULL, *result = NULL;
    camera_format cf;
    uint32_t lat = (uint32_t)(scicapd_devices_dmd_latency_ns(scicapd_rig_devices(a)) / 1000);
    const sci_cube *masks = NULL;
    if ((rc = scicapd_rig_bind(a, SYNC_MODE_HOST_MASTER, &err)) < 0)
        goto done;
    camera_format_get(scicapd_rig_camera(a), &cf);
    if (!(masks = scicapd_rig_mask_set(a, &c->mask_set, &err))) {
        rc = err.code;
        goto done;
    }
    if ((rc = sci_cube_new(&acc, (int)cf.width, (int)cf.height, 1, &err)) < 0)
        goto done;
    if (c->kind == SCICAPD_CALIB_DARK)
        rc = calibrate_dark(a, j, masks, lat, &acc, &rec, &err);
    else
        rc = calibrate_masks(a, j, masks, lat, acc, &result, &rec, &err);
done:
    calibrate_finish(a, j, rc, rec, &err);
    json_decref(rec);
    sci_cube_free(acc);
    sci_cube_free(result);
}
