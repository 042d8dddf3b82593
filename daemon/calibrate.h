/* daemon/calibrate.h — calibrate jobs, and the calibrations in use.
 *
 * A calibrate job (scicapd_calibrate_run, on the acquisition thread, daemon/acquire.h) is one of two kinds:
 *   dark   the camera's frame averaged over `average` exposures with the DMD not started (no light reaches the
 *          sensor through the masks), in counts; current as "dark";
 *   masks  each mask of a set shown alone on a uniform white target (the devices provide one on the simulated
 *          bench; a real bench needs one in front of the camera: daemon/devices.h), averaged, minus the dark
 *          calibration when it has the sensor's size (else the configured dark level), divided by the white
 *          level: the mean of the pixels the mask opens (known when a mirror maps to a pixel, else the pixels
 *          brighter than half the brightest); current as "masks-<set>", with that white level as
 *          counts_per_unit.
 * Both are written to the store (ROOT/calibrations, daemon/store.h) before they count, then reported by the
 * events calibrate.started, calibrate.progress (masks), calibrate.done / .failed / .canceled.
 *
 * scicapd_calibs: the calibrations in use by key, loaded from the store on first use (a key found missing is not
 * looked up again until a job writes it) and replaced when a job writes a new one; at most 64 keys. Owns what it
 * holds. Acquisition thread only.
 */
#ifndef SCICAP_DAEMON_CALIBRATE_H
#define SCICAP_DAEMON_CALIBRATE_H

#include <jansson.h>

#include "base/cube.h"
#include "base/log.h"
#include "daemon/acquire.h"
#include "daemon/jobs.h"
#include "daemon/store.h"

typedef struct scicapd_calib {
    sci_cube *data;          /* dark: counts (w×h×1); masks: the measured masks (w×h×N, white = 1) */
    json_t *record;          /* calibration.json as stored (with "id" and "folder") */
    double counts_per_unit;  /* masks: the white level; 0 for dark */
} scicapd_calib;

typedef struct scicapd_calibs scicapd_calibs;

/* store and log borrowed (outlive the cache). -ENOMEM. */
int scicapd_calibs_new(scicapd_calibs **out, scicapd_store *store, const sci_log *log, sci_error *err);
void scicapd_calibs_free(scicapd_calibs *c); /* NULL is harmless */
/* The current calibration for `key` ("dark", "masks-<set>"), borrowed until the next set; NULL when none. */
const scicapd_calib *scicapd_calibs_get(scicapd_calibs *c, const char *key);

/* Run calibrate job j to its end (state, events, output id). */
void scicapd_calibrate_run(scicapd_acquire *a, scicapd_job *j);

#endif
