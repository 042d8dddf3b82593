/* daemon/devices.h — the bench's three devices, opened per the configuration's backends (docs/config.md):
 *
 *     DMD      "sim" (sim/dmd_sim.h: the dlpc900 backend on an emulator) or "dlpc900" (drivers/dmd_dlpc900.c over
 *              USB HID, or over the in-process DLPC900 emulator with "emulator": true)
 *     camera   "sim" (the simulated bench, sim/bench.h), or a backend of drivers/backends.h: "v4l2"
 *              (drivers/camera_v4l2.h), "aravis" (drivers/camera_aravis.h, GenICam); daemon/backends.h says how
 *              each one's settings are parsed
 *     trigger  "sim" (the simulated bench) or "gpiod" (drivers/trigger_gpiod.h)
 *
 * Camera and trigger are both simulated or both real (the config refuses a mix: the trigger output starts the
 * camera and the camera's strobe comes back to a trigger input). When they are simulated the DMD, whatever its
 * backend, is wired into the simulated bench (its masks shape the simulated image); otherwise it is used as is,
 * and an emulated DMD ("sim", or the DLPC900 emulator) gets the real camera's size (one mirror per pixel).
 * One exception: Aravis's in-process fake camera ("device": "Fake_1") may run with the "sim" trigger, opened
 * alone (its output reaches nothing, no input wired): the GenICam path end to end without hardware.
 * An aravis camera in "trigger": "software" mode gets the trigger wrapped (daemon/swtrigger.h): each pulse also
 * sends the camera's TriggerSoftware, where the exposure starts; only host-master sync can work that way.
 *
 * A device that fails to open does not stop the daemon: its error (naming the device) is kept, logged, shown by
 * `devices` and `status`, and returned by scicapd_devices_ready to every capture; scicapd_devices_retry re-opens
 * what is missing (every few seconds while idle, and at once after a reload).
 *
 * This file is the one place of the daemon that knows a simulated device from a real one: what the acquisition
 * needs of the difference it asks here in the devices' terms (scicapd_devices_prepare for a sync mode, the masks
 * the camera sees, the scene's truth when one is known, the white target, per-snapshot metadata).
 *
 * Threads: everything except scicapd_devices_json, _dmd_connected and _fault_supported is called by the
 * acquisition thread only (the device handles are not thread-safe). Those three are safe from any thread.
 */
#ifndef SCICAP_DAEMON_DEVICES_H
#define SCICAP_DAEMON_DEVICES_H

#include <jansson.h>
#include <stdint.h>

#include "base/cube.h"
#include "base/log.h"
#include "daemon/config.h"
#include "daemon/protocol.h"
#include "drivers/camera.h"
#include "drivers/dmd.h"
#include "drivers/trigger.h"

typedef struct scicapd_devices scicapd_devices;

/* Copy what is needed from cfg and try to open the three devices. Fails only for -ENOMEM: device errors are
 * kept (scicapd_devices_ready). DMD connect/disconnect events (including hotplug) go to on_event/user, on the
 * calling thread of the device functions. */
int scicapd_devices_open(scicapd_devices **out, const scicapd_config *cfg, const sci_log *log,
                         dmd_event_fn on_event, void *user, sci_error *err);
void scicapd_devices_close(scicapd_devices *d); /* NULL is harmless */

/* 1 when cfg opens the devices differently from what d was opened with. */
int scicapd_devices_differ(const scicapd_devices *d, const scicapd_config *cfg);
/* Close everything and open per cfg (reload with changed devices or simulator sections). -ENOMEM only. */
int scicapd_devices_reconfigure(scicapd_devices *d, const scicapd_config *cfg, sci_error *err);
/* Re-open the devices that are not open, at most every `period_ns` unless `force`. 1 if one came back. */
int scicapd_devices_retry(scicapd_devices *d, int64_t period_ns, int force);
/* 0 when all three are open; else -ENODEV with "camera (v4l2): not connected: <its open error>". */
int scicapd_devices_ready(scicapd_devices *d, sci_error *err);
/* Before a job in sync mode `mode`: the devices are ready (as above), the camera can be run that way (-EINVAL
 * with the reason otherwise: a camera in software-trigger mode needs host master), and set up for it (the
 * simulated camera free-runs in camera master and waits for its trigger otherwise: its handle may change, so
 * take scicapd_devices_camera afterwards). */
int scicapd_devices_prepare(scicapd_devices *d, enum sync_mode mode, sci_error *err);

/* Handles (borrowed, valid until the next reconfigure/retry/close; NULL when that device is not open). */
dmd *scicapd_devices_dmd(scicapd_devices *d);
camera *scicapd_devices_camera(scicapd_devices *d);
trigger *scicapd_devices_trigger(scicapd_devices *d);
const dmd_identity *scicapd_devices_dmd_identity(const scicapd_devices *d);
/* Start (pulse or DMD start) to first pattern: the simulator's latency, or the DLPC900 trigger delay. */
int64_t scicapd_devices_dmd_latency_ns(const scicapd_devices *d);
/* Exposure end to frame timestamp, for the exposure window when no strobe is wired. */
int64_t scicapd_devices_readout_ns(const scicapd_devices *d);
/* What the DMD needs in its dmd_timing beyond exposure/dark/trigger mode (DLPC900 trigger-in settings). */
void scicapd_devices_timing_defaults(const scicapd_devices *d, dmd_timing *t);

/* The masks as the camera sees them, from masks at the DMD's size, when the optics are known without a
 * calibration: a mirror per pixel (same size: a copy), or the simulated bench's central window. 1 with *out a new
 * cube at the camera's size (cam_w × cam_h); 0 when they are not known (measured masks are needed: scicap
 * calibrate --masks); negative on error. */
int scicapd_devices_camera_masks(const scicapd_devices *d, const sci_cube *dmd_masks, int cam_w, int cam_h,
                                 sci_cube **out, sci_error *err);
/* The frames the camera sees for n masks, when the devices know them (the simulated bench's scene at the time
 * scicapd_devices_scene_at set): 1 with *out a new cube; 0 when unknown (a real scene); negative on error. */
int scicapd_devices_truth(scicapd_devices *d, int n, sci_cube **out, sci_error *err);
/* The simulated bench's scene time for the next snapshot: capture number `capture` (1 for c000001) sees clock
 * frames (capture − 1)·n … (capture − 1)·n + n − 1 (sim/bench.h), so every capture shows the scene moved on, the
 * same for the same number whenever it is taken. No-op on real devices. */
void scicapd_devices_scene_at(scicapd_devices *d, unsigned long capture);
/* A uniform white target in front of the camera (on) or the scene again (off), for mask calibration: the simulated
 * bench switches its target; a real bench cannot, so the log asks the operator for one. */
void scicapd_devices_white_target(scicapd_devices *d, int on);
/* What the devices add to a snapshot's meta.json: "camera_trigger" ({"mode": "software", "sent": software
 * triggers sent since the camera opened, "last_sent_ns": CLOCK_MONOTONIC just before the last one}) when the
 * camera is in software-trigger mode, "simulated" ({"scene": name, "scene_frames": the scene time of each of the
 * n masks' frames}) on the simulated bench. */
void scicapd_devices_snapshot_meta(scicapd_devices *d, int n, json_t *meta);

/* Mark the DMD (dis)connected after a hotplug event (the acquisition thread's event callback calls this). */
void scicapd_devices_dmd_event(scicapd_devices *d, dmd_event ev);

/* Thread-safe: {"dmd": {backend, connected, error | identity...}, "camera": ..., "trigger": ...} (new ref). */
json_t *scicapd_devices_json(scicapd_devices *d);
/* Thread-safe: 1 when the DMD is open and connected. */
int scicapd_devices_dmd_connected(scicapd_devices *d);
/* Thread-safe: 1 if `fault` can be injected into the devices as configured (DMD faults need an emulated DMD,
 * camera and trigger faults the simulated bench). */
int scicapd_devices_fault_supported(scicapd_devices *d, scicapd_fault fault);
/* Inject it (acquisition thread); unsupported faults are ignored. */
void scicapd_devices_fault_apply(scicapd_devices *d, scicapd_fault fault, long n);

#endif
