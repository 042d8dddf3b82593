/* daemon/simbench.h — the simulated bench: sim camera and sim trigger wired like the real lab around a DMD of
 * any backend (the "sim" DMD, the DLPC900 emulator behind the dlpc900 backend, or a real DLPC900).
 *
 * Wiring (drivers/capture.h, per sync mode): in host-master the trigger output starts the DMD sequence (DMD in
 * external-trigger mode) and the camera exposure; in dmd-master dmd_start starts the sequence and the DMD's
 * first pattern trigger starts the camera; in camera-master the camera free-runs and the strobe of the first
 * exposure that starts after the DMD was armed (dmd_start in external-trigger mode) starts the sequence. The DMD's per-pattern trigger output and the camera strobe are fed
 * back to the trigger's inputs, so the sync report measures the simulated timing.
 * The camera's image is what the sensor would integrate: dark level + counts_per_unit · Σ_k w_k M_k ⊙ X_k + read
 * noise, where w_k is the fraction of mask k's display time inside the exposure, M_k the masks as uploaded to
 * the DMD and X_k the scene's frames (the embedded default scene unless a scene file is configured), or a
 * uniform white target (calibration). Units: counts (16-bit), ns of CLOCK_MONOTONIC.
 *
 * The DMD handle is a wrapper table around the attached DMD (scicapd_simbench_attach_dmd, borrowed), so the
 * acquisition code drives it as any DMD; the wrapper keeps a copy of what the mirrors show for the image model.
 * A DMD larger than the scene is seen through its central scene-sized window (scicapd_simbench_crop gives the
 * masks the camera sees); a smaller one is refused at upload.
 *
 * Why this is not sim/bench_source.h (the simulator's frame source, which asks the sim DMD what it displays at
 * each moment): the daemon's bench times the sequence from the simulated trigger edge (latency, jitter and
 * missed pulses of the trigger simulator show in the image), works with any DMD backend (bench_source needs
 * dmd_sim's displayed_at and masks), and adds the dark level, read noise and the white calibration target.
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

/* Load the scene, open the simulated camera (streaming, external trigger) and trigger. No DMD yet. */
int scicapd_simbench_open(scicapd_simbench **out, const scicapd_config *cfg, sci_error *err);
/* Detach the DMD first if it is closed before the bench. NULL is harmless. */
void scicapd_simbench_close(scicapd_simbench *sb);
/* The camera's size (the scene's): a DMD of at least this size can be attached. */
void scicapd_simbench_size(const scicapd_simbench *sb, int *w, int *h);
/* Wire `inner` (borrowed; NULL detaches, e.g. before it is closed). Forgets the masks shown. */
void scicapd_simbench_attach_dmd(scicapd_simbench *sb, dmd *inner);
/* The part of DMD-sized masks the camera sees (new cube, camera size). */
int scicapd_simbench_crop(const scicapd_simbench *sb, const sci_cube *dmd_masks, sci_cube **out, sci_error *err);

/* Camera master (free run, each exposure's strobe starts the armed DMD) or not (external trigger). Re-opens the
 * simulated camera when the mode changes: the camera handle changes (take it again afterwards). */
int scicapd_simbench_set_free_run(scicapd_simbench *sb, int free_run, sci_error *err);

dmd *scicapd_simbench_dmd(scicapd_simbench *sb);       /* the wrapper (borrowed) */
camera *scicapd_simbench_camera(scicapd_simbench *sb); /* borrowed */
trigger *scicapd_simbench_trigger(scicapd_simbench *sb);
int64_t scicapd_simbench_dmd_latency_ns(const scicapd_simbench *sb);
void scicapd_simbench_set_target(scicapd_simbench *sb, scicapd_target t);
/* The truth the camera sees for `n` frames (rendered once per n, cached): borrowed until the next call or close.
 * NULL on failure (err set). */
const sci_cube *scicapd_simbench_truth(scicapd_simbench *sb, int n, sci_error *err);
/* The scene's name, for metadata. */
const char *scicapd_simbench_scene_name(const scicapd_simbench *sb);

/* Faults (tests): stall the camera's next n exposures, lose the next n trigger pulses. (DMD unplugs go to the
 * DLPC900 emulator: daemon/devices.h.) */
void scicapd_simbench_camera_stall(scicapd_simbench *sb, int n);
void scicapd_simbench_trigger_miss(scicapd_simbench *sb, int n);

#endif
