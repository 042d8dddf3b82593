/* daemon/calibrate.h — calibrate jobs.
 *
 * A calibrate job (scicapd_calibrate_run, on the acquisition thread, daemon/acquire.h, using the rig,
 * daemon/rig.h) is one of two kinds:
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
 * The calibrations in use live in daemon/calibs.h (read by daemon/package.h); this job replaces them.
 */
#ifndef SCICAP_DAEMON_CALIBRATE_H
#define SCICAP_DAEMON_CALIBRATE_H

#include "daemon/jobs.h"
#include "daemon/rig.h"

/* Run calibrate job j to its end (state, events, output id). */
void scicapd_calibrate_run(scicapd_rig *r, scicapd_job *j);

#endif
