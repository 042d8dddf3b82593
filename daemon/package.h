/* daemon/package.h — one snapshot as the store keeps it: the frame taken, turned into a reconstruction problem.
 *
 * From the frame in counts (raw), the masks as shown on the DMD and the calibrations in use:
 *   meas  = (raw − dark) / counts_per_unit, where dark is the dark calibration when it has the sensor's size
 *           (else the uncalibrated dark level) and counts_per_unit the measured masks' white level (else the
 *           uncalibrated scale), so the problem is on the forward model's scale (peak 1);
 *   mask  = the measured masks for this set when they have the sensor's size and the set's count, else the masks
 *           the camera sees by geometry (daemon/devices.h: a mirror per pixel, or the simulated bench's window);
 *           SCI_ESHAPE asking for `scicap calibrate --masks` when neither is known;
 *   truth = the frames the camera saw, when the devices know them (the simulated bench);
 * plus the calibration record used, the sync report's verdict (broken snapshots are stored, flagged) and
 * meta.json (format, settings, device identities and state, timestamps, sync report: docs/capture-folder.md).
 * Errors: negative codes with err set; nothing is handed out on error.
 */
#ifndef SCICAP_DAEMON_PACKAGE_H
#define SCICAP_DAEMON_PACKAGE_H

#include <jansson.h>
#include <stdint.h>

#include "base/cube.h"
#include "daemon/calibs.h"
#include "daemon/devices.h"
#include "daemon/jobs.h"
#include "daemon/store.h"
#include "drivers/capture.h"

typedef struct scicapd_package_in {
    scicapd_jobs *jobs;              /* for scicapd_snapshot_free on error */
    const scicapd_job *job;          /* the capture job: its settings */
    int index;                       /* snapshot of the job, 0-based */
    const sci_cube *dmd_masks;       /* as shown on the DMD (0/1, the DMD's size), copied */
    const capture_snapshot *shot;    /* the frame and its sync report */
    scicapd_calibs *calibs;          /* the calibrations in use */
    scicapd_devices *dev;            /* geometry, truth, identities, metadata */
    double counts_per_unit, dark_level; /* the scale without calibrations (scicapd_rig_scale) */
    uint32_t exposure_us;            /* the camera's exposure as set */
} scicapd_package_in;

/* A new snapshot (free with scicapd_snapshot_free); its job reference is not taken here. */
int scicapd_package_snapshot(const scicapd_package_in *in, scicapd_snapshot **out, sci_error *err);

#endif
