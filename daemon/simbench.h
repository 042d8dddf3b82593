/* daemon/simbench.h — the simulated bench: sim DMD, sim camera and sim trigger wired like the real lab.
 *
 * Wiring (drivers/capture.h, per sync mode): in host-master the trigger output starts the DMD sequence (DMD in
 * external-trigger mode) and the camera exposure; in dmd-master dmd_start starts the sequence and the DMD's
 * first pattern trigger starts the camera. The DMD's per-pattern trigger output and the camera strobe are fed
 * back to the trigger's inputs, so the sync report measures the simulated timing.
 * The camera's image is what the sensor would integrate: dark level + counts_per_unit · Σ_k w_k M_k ⊙ X_k + read
 * noise, where w_k is the fraction of mask k's display time inside the exposure, M_k the masks as uploaded to
 * the DMD and X_k the scene's frames (the embedded default scene unless a scene file is configured), or a
 * uniform white target (calibration). Units: counts (16-bit), ns of CLOCK_MONOTONIC.
 *
 * The DMD handle is a wrapper table around dmd_sim_ops, so the acquisition code drives it as any DMD.
 * Threads: like the devices, used by one thread at a time (the acquisition thread).
 */
#ifndef SCICAP_DAEMON_SIMBENCH_H
#define SCICAP_DAEMON_SIMBENCH_H

#include "base/cube.h"
#include "base/log.h"
#include "daemon/config.h"
#include "drivers/camera.h"
#include "drivers/dmd.h"
#include "drivers/trigger.h"

typedef struct scicapd_simbench scicapd_simbench;

typedef enum scicapd_target { SCICAPD_TARGET_SCENE, SCICAPD_TARGET_WHITE } scicapd_target;

/* Open the three simulated devices; dmd events go to on_event/user. */
int scicapd_simbench_open(scicapd_simbench **out, const scicapd_config *cfg, const sci_log *log,
                          dmd_event_fn on_event, void *user, sci_error *err);
void scicapd_simbench_close(scicapd_simbench *sb);

dmd *scicapd_simbench_dmd(scicapd_simbench *sb);       /* borrowed */
camera *scicapd_simbench_camera(scicapd_simbench *sb); /* borrowed */
trigger *scicapd_simbench_trigger(scicapd_simbench *sb);
int64_t scicapd_simbench_dmd_latency_ns(const scicapd_simbench *sb);
void scicapd_simbench_set_target(scicapd_simbench *sb, scicapd_target t);
/* The truth the camera sees for `n` frames (rendered once per n, cached): borrowed until the next call or close.
 * NULL on failure (err set). */
const sci_cube *scicapd_simbench_truth(scicapd_simbench *sb, int n, sci_error *err);
/* The scene's name, for metadata. */
const char *scicapd_simbench_scene_name(const scicapd_simbench *sb);

/* Faults (tests): unplug the DMD after `reports` more USB reports (0 = now), plug it back, stall the camera's
 * next n exposures, lose the next n trigger pulses. */
void scicapd_simbench_dmd_unplug(scicapd_simbench *sb, long reports);
void scicapd_simbench_dmd_replug(scicapd_simbench *sb);
void scicapd_simbench_camera_stall(scicapd_simbench *sb, int n);
void scicapd_simbench_trigger_miss(scicapd_simbench *sb, int n);

#endif
