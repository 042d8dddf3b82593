/* daemon/calibs.h — the calibrations in use, by key ("dark", "masks-<set>"), as calibrate jobs wrote them
 * (daemon/calibrate.h) and snapshots are packaged with them (daemon/package.h).
 *
 * Loaded from the store (ROOT/calibrations, daemon/store.h) on first use; a key found missing is not looked up
 * again until a job sets it; replaced when a job writes a new one; at most 64 keys (a 65th is neither kept nor
 * looked up: NULL). Owns what it holds. Not thread-safe: the acquisition thread only.
 *
 *     const scicapd_calib *dark = scicapd_calibs_get(calibs, "dark");   // NULL: none
 */
#ifndef SCICAP_DAEMON_CALIBS_H
#define SCICAP_DAEMON_CALIBS_H

#include <jansson.h>

#include "base/cube.h"
#include "base/error.h"
#include "base/log.h"
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
/* The current calibration for `key`, borrowed until the next scicapd_calibs_set of that key; NULL when none. */
const scicapd_calib *scicapd_calibs_get(scicapd_calibs *c, const char *key);
/* Make (data, record) current for key, as written to the store; takes both (freed at once when 64 other keys are
 * held). cpu: counts per unit (the white level of measured masks; 0 for dark). */
void scicapd_calibs_set(scicapd_calibs *c, const char *key, sci_cube *data, json_t *record, double cpu);

#endif
