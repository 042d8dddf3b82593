/* daemon/capture.h — capture jobs, run by the acquisition thread (daemon/acquire.h) on the rig (daemon/rig.h).
 *
 * A capture job takes `count` snapshots of one mask set: bind the devices for its sync mode, make the set at the
 * DMD's size, then per snapshot apply pending faults, program the DMD (uploaded once; timing when it changed),
 * arm the sync and take one frame (drivers/capture.h), stop the DMD, package it (daemon/package.h: a broken sync
 * is stored but flagged, never hidden), reserve its capture id in acquisition order (durable before it goes on)
 * and push it to the writer queue, waiting when that is full. It never waits for a reconstruction. The exposure is
 * the job's, or the whole sequence plus the DMD's latency (scicapd_auto_exposure_us).
 * Events: capture.started, capture.snapshot per snapshot (index, broken, sync flags, offset), then
 * capture.failed (the snapshot index and the error) or capture.canceled (how many were acquired); the job's state
 * and progress in the job table. The writer marks the job done when the last snapshot is stored.
 */
#ifndef SCICAP_DAEMON_CAPTURE_H
#define SCICAP_DAEMON_CAPTURE_H

#include "daemon/jobs.h"
#include "daemon/rig.h"

/* Run capture job j to its end (or cancel, or the thread's stop). */
void scicapd_capture_run(scicapd_rig *r, scicapd_job *j);

#endif
