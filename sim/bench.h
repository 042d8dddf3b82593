/* sim/bench.h — the simulated bench: a simulated camera and trigger wired like the real lab around a DMD of any
 * backend (the "sim" DMD, the DLPC900 emulator behind the dlpc900 backend, or a real DLPC900), imaging a scene.
 * It is the one simulated bench of the project: scicapd's "sim" camera and trigger (daemon/devices.c) and
 * `scicap sim --bench` (cli/sim.c) both run it.
 *
 * Wiring (drivers/capture.h, per sync mode): in host-master the trigger output starts the DMD sequence (DMD in
 * external-trigger mode) and the camera exposure; in dmd-master dmd_start starts the sequence and the DMD's
 * first pattern trigger starts the camera; in camera-master the camera free-runs and the strobe of the first
 * exposure that starts after the DMD was armed (dmd_start in external-trigger mode) starts the sequence. The
 * DMD's per-pattern trigger output and the camera strobe are fed back to the trigger's inputs, so a sync report
 * measures the simulated timing.
 *
 * Image model: the sensor integrates
 *     counts = dark_counts + counts_per_unit · Σ_k w_k M_k ⊙ X_k + read noise (normal, σ = read_noise)
 * rounded and clamped to the sample range, where w_k ∈ [0, 1] is the fraction of mask k's display time that falls
 * inside the exposure window, M_k the masks as uploaded (thresholded at 0.5, the mirrors the camera sees) and X_k
 * frame k of the scene (or a uniform white target, for calibration). So under ideal timing — the exposure covering
 * the whole sequence — the snapshot before conversion to counts is exactly the forward model Σ_k M_k ⊙ X_k
 * (sci_op_forward); a wrong mask order, a late DMD, a missed trigger or a short exposure shows in it as on
 * hardware. A trigger pulse reaches its output latency + uniform [0, jitter] later; the DMD's first pattern
 * starts dmd_latency after its trigger edge (or after dmd_start in dmd-master). One sequence per exposure.
 * Units: counts (samples of 16 bits), ns of CLOCK_MONOTONIC.
 *
 * The DMD: the bench hands out a wrapper handle (sim_bench_dmd) around the attached DMD (sim_bench_attach_dmd,
 * borrowed), used as any DMD; the wrapper forwards every call and keeps what the mirrors show for the image
 * model. A DMD larger than the scene is seen through its central scene-sized window (sim_bench_crop gives the
 * masks the camera sees); a smaller one is refused at upload (SCI_ESHAPE).
 *
 * Ownership: the bench owns its scene (loaded from options.scene_path, the embedded default scene when that is
 * NULL or "", or given ready in options.scene), its camera, trigger and the DMD wrapper; the attached DMD is
 * borrowed. Errors: negative codes with the message in err. Threads: like the devices, one thread at a time.
 */
#ifndef SCICAP_SIM_BENCH_H
#define SCICAP_SIM_BENCH_H

#include <stdint.h>

#include "base/cube.h"
#include "drivers/camera.h"
#include "drivers/dmd.h"
#include "drivers/trigger.h"
#include "sim/scene.h"

typedef struct sim_bench_options {
    const char *scene_path;      /* scene file (docs/scene-format.md); NULL or "": the embedded default scene */
    sim_scene *scene;            /* or a loaded scene, handed over (the bench frees it, also when open fails);
                                    wins over scene_path */
    uint64_t seed;               /* trigger jitter and read noise */
    int64_t dmd_latency_ns;      /* trigger edge (or dmd_start in dmd-master) to the first pattern */
    int64_t trigger_latency_ns;  /* trigger_pulse to its output edge */
    int64_t trigger_jitter_ns;   /* extra uniform delay in [0, jitter] */
    int64_t readout_ns;          /* exposure end to frame ready */
    double counts_per_unit;      /* counts for a full-on mirror on a white target, one whole sequence */
    double dark_counts;          /* dark level */
    double read_noise;           /* σ of the read noise, counts (0: none) */
} sim_bench_options;

/* The daemon's defaults: latencies 300 µs (DMD) and 20 µs + 3 µs jitter (trigger), 100 µs readout, 6000 counts
 * per unit, dark level 200, read noise 2 counts, seed 1, the default scene. */
sim_bench_options sim_bench_options_default(void);

typedef struct sim_bench sim_bench;

typedef enum sim_bench_target { SIM_BENCH_TARGET_SCENE, SIM_BENCH_TARGET_WHITE } sim_bench_target;

/* Load the scene, open the simulated camera (streaming, external trigger, Y16 at the scene's size) and trigger.
 * No DMD yet. */
int sim_bench_open(sim_bench **out, const sim_bench_options *opt, sci_error *err);
/* Detach the DMD first if it is closed before the bench. NULL is harmless. */
void sim_bench_close(sim_bench *b);
/* The camera's size (the scene's): a DMD of at least this size can be attached. */
void sim_bench_size(const sim_bench *b, int *w, int *h);
/* Wire `inner` (borrowed; NULL detaches, e.g. before it is closed). Forgets the masks shown. */
void sim_bench_attach_dmd(sim_bench *b, dmd *inner);
/* The part of DMD-sized masks the camera sees (new cube, camera size); SCI_ESHAPE if they are smaller. */
int sim_bench_crop(const sim_bench *b, const sci_cube *dmd_masks, sci_cube **out, sci_error *err);

/* Camera master (free run at 30 frames/s, each exposure's strobe starts the armed DMD) or not (external
 * trigger). Re-opens the simulated camera when the mode changes: the camera handle changes (take it again). */
int sim_bench_set_free_run(sim_bench *b, int free_run, sci_error *err);

dmd *sim_bench_dmd(sim_bench *b);         /* the wrapper (borrowed, lives as long as the bench) */
camera *sim_bench_camera(sim_bench *b);   /* borrowed, until set_free_run or close */
trigger *sim_bench_trigger(sim_bench *b); /* borrowed */
const sim_bench_options *sim_bench_get_options(const sim_bench *b); /* as opened (scene and path not kept) */
void sim_bench_set_target(sim_bench *b, sim_bench_target t);
/* The scene's time for the next exposures: snapshot j sees frames j·n … j·n + n − 1 of the bench's clock (n = the
 * masks in the sequence); 0 until set. scicapd sets it from the capture number, so consecutive captures see the
 * scene move on. The clock plays the scene forward, then backward, and so on (a bounce, so that positions stay
 * continuous) over its length: the scene's snapshots × frames, and for a video2d scene at least
 * SIM_BENCH_LOOP_FRAMES (layers move for ever; a one-snapshot scene would otherwise never change); frame f of the
 * clock is scene time f while f < length. So snapshots never run out of scene, and the first ones are exactly
 * those `scicap sim` renders. */
void sim_bench_set_snapshot(sim_bench *b, uint64_t snapshot);
#define SIM_BENCH_LOOP_FRAMES 32
/* The scene time (in frames, 0 … length − 1) of mask k's frame of the current snapshot of n masks. */
double sim_bench_frame_time(const sim_bench *b, int n, int k);
/* The truth the camera sees for `n` masks (those frames of the scene, rendered once per n and snapshot): borrowed
 * until the next call or close. NULL on failure (err set). */
const sci_cube *sim_bench_truth(sim_bench *b, int n, sci_error *err);
/* The scene's name, for metadata. */
const char *sim_bench_scene_name(const sim_bench *b);
/* The last snapshot before conversion to counts (camera size, forward-model scale: Σ w_k M_k ⊙ X_k); borrowed
 * until the next frame; NULL before the first. Lets tests compare with sci_op_forward without the rounding. */
const float *sim_bench_last(const sim_bench *b);

/* One snapshot in host-master sync, as the lab takes it: `masks` (the DMD's size, 0/1) uploaded to the attached
 * DMD, pattern_us per mask without dark time, external trigger, armed; one trigger pulse starts the exposure and,
 * dmd_latency later, the sequence; the exposure lasts dmd_latency + n · pattern_us, so it holds the whole sequence.
 * meas (camera size × 1) receives (counts − dark_counts) / counts_per_unit: the forward model's scale. -ENODEV
 * without a DMD; the camera's and DMD's errors otherwise (-ETIMEDOUT for a lost pulse). */
int sim_bench_snapshot(sim_bench *b, const sci_cube *masks, uint32_t pattern_us, sci_cube *meas, sci_error *err);

/* Faults (tests and `scicapd simulate`): stall the camera's next n exposures, lose the next n trigger pulses.
 * (DMD unplugs go to the DLPC900 emulator.) */
void sim_bench_camera_stall(sim_bench *b, int n);
void sim_bench_trigger_miss(sim_bench *b, int n);

#endif
