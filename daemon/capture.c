/* daemon/capture.c — capture jobs (see the header). */
#include "daemon/capture.h"

#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "base/file.h"
#include "base/json.h"
#include "daemon/package.h"
#include "daemon/store.h"

/* Snapshot `index` of job j taken and packaged for the store (*out; its id not yet set). */
static int shoot(scicapd_rig *a, const scicapd_job *j, int index, const sci_cube *masks, uint32_t exposure,
                 scicapd_snapshot **out, sci_error *err)
{
    const scicapd_capture_args *c = &j->capture;
    int rc;
    if ((rc = scicapd_rig_program(a, c->mask_set.name, masks, c->pattern_us, c->dark_us, c->sync, err)) < 0 ||
        (rc = scicapd_rig_take(a, masks->n, exposure, c->sync, 0, err)) < 0)
        return rc;
    scicapd_rig_beat(a);
    scicapd_package_in pin = {.jobs = scicapd_rig_env_get(a)->jobs, .job = j, .index = index, .dmd_masks = masks,
                              .shot = scicapd_rig_shot(a), .calibs = scicapd_rig_calibs(a),
                              .dev = scicapd_rig_devices(a),
                              .exposure_us = camera_exposure_us(scicapd_rig_camera(a))};
    scicapd_rig_scale(a, &pin.counts_per_unit, &pin.dark_level);
    return scicapd_package_snapshot(&pin, out, err);
}

/* ROOT/capture.running names the capture in progress, so that a daemon killed during it (kill -9, a power cut)
 * reports it interrupted at its next start (daemon.c) instead of losing it silently; removed when the capture
 * ends in any way. Written whole (sci_json_write_atomic); failures only logged: it is a report, not the capture. */
static void running_mark(const scicapd_rig_env *env, const scicapd_job *j, int count)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/capture.running", scicapd_store_root(env->store));
    json_t *m = json_pack("{s:I, s:I, s:i, s:I}", "job", (json_int_t)j->id, "owner", (json_int_t)j->owner, "count",
                          count, "started_unix", (json_int_t)time(NULL));
    sci_error err = {0};
    int rc = m ? sci_json_write_atomic(path, m, JSON_COMPACT, 0644,
                                       scicapd_store_fsync_on(env->store) ? 0 : SCI_FILE_NO_SYNC, &err)
               : sci_error_set(&err, -ENOMEM, "%s: out of memory", path);
    json_decref(m);
    if (rc < 0)
        sci_log_write(env->log, SCI_LOG_WARNING, "%s (an interruption of this capture would go unreported)",
                      err.msg);
}

static void running_clear(const scicapd_rig_env *env)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/capture.running", scicapd_store_root(env->store));
    unlink(path);
}

void scicapd_capture_run(scicapd_rig *a, scicapd_job *j)
{
    const scicapd_capture_args *c = &j->capture;
    const scicapd_rig_env *env = scicapd_rig_env_get(a);
    scicapd_devices *dev = scicapd_rig_devices(a);
    sci_error err = {0};
    scicapd_job_set_state(env->jobs, j, SCICAPD_JOB_RUNNING, NULL);
    scicapd_job_set_progress(env->jobs, j, 0, c->count, NAN);
    running_mark(env, j, c->count);
    scicapd_rig_post(a, j, "capture.started",
                         json_pack("{s:s, s:i}", "mask_set", c->mask_set.name, "count", c->count));
    int rc = scicapd_rig_bind(a, c->sync, &err);
    const sci_cube *masks = rc < 0 ? NULL : scicapd_rig_mask_set(a, &c->mask_set, &err);
    rc = masks ? 0 : err.code;
    uint32_t lat_us = (uint32_t)(scicapd_devices_dmd_latency_ns(dev) / 1000);
    uint32_t exposure = c->exposure_us ? c->exposure_us
                                       : scicapd_auto_exposure_us(c->mask_set.frames, c->pattern_us, c->dark_us,
                                                                  lat_us);
    int i;
    for (i = 0; rc == 0 && i < c->count; i++) {
        if (scicapd_rig_canceled(a, j))
            break;
        scicapd_rig_apply_faults(a);
        /* ids in acquisition order, whichever writer stores it, durable before the snapshot goes on; taken before
         * the exposure because the simulated scene's time follows the capture number */
        char id[32];
        unsigned long num;
        if ((rc = scicapd_store_take_id(env->store, id, sizeof id, &num, &err)) < 0)
            break;
        scicapd_devices_scene_at(dev, num);
        scicapd_span sp;
        scicapd_span_begin(&sp);
        scicapd_snapshot *s = NULL;
        if ((rc = shoot(a, j, i, masks, exposure, &s, &err)) < 0) {
            scicapd_store_give_back_id(env->store, num);
            break;
        }
        snprintf(s->capture_id, sizeof s->capture_id, "%s", id);
        const capture_snapshot *shot = scicapd_rig_shot(a);
        char flags[160];
        sync_flags_describe(shot->report.flags, flags, sizeof flags);
        scicapd_timing_add(env->timing, SCICAPD_STAGE_ACQUIRE, &sp);
        scicapd_rig_post(a, j, "capture.snapshot",
                             json_pack("{s:i, s:i, s:b, s:s, s:i, s:I}", "index", i, "count", c->count, "broken",
                                       s->broken, "sync", flags, "inside", shot->report.inside, "offset_ns",
                                       (json_int_t)shot->report.offset_ns));
        if (s->broken)
            sci_log_write(env->log, SCI_LOG_WARNING, "job %llu snapshot %d: broken sync (%s), stored flagged",
                          (unsigned long long)j->id, i, flags);
        scicapd_rig_injected_delay(a);
        s->job = scicapd_jobs_find(env->jobs, j->id); /* the writer's reference */
        if (scicapd_queue_push_wait(env->out, s) < 0) {
            scicapd_snapshot_free(env->jobs, s);
            rc = sci_error_set(&err, -EPIPE, "storage writer stopped");
            break;
        }
    }
    if (rc < 0) {
        sci_log_write(env->log, SCI_LOG_ERR, "job %llu: snapshot %d: %s", (unsigned long long)j->id, i, err.msg);
        scicapd_job_set_state(env->jobs, j, SCICAPD_JOB_FAILED, err.msg);
        scicapd_rig_post(a, j, "capture.failed", json_pack("{s:i, s:s, s:s}", "index", i, "error", err.msg,
                                                                "code", sci_strerror(rc)));
    } else if (i < c->count && atomic_load(&j->cancel) == SCICAPD_CANCEL_STORAGE) {
        /* failed, and said so with the reason, by the writer that could not store a snapshot (daemon.c) */
        sci_log_write(env->log, SCI_LOG_ERR, "job %llu: stopped after %d of %d snapshots: a snapshot could not be "
                      "stored", (unsigned long long)j->id, i, c->count);
    } else if (i < c->count) {
        scicapd_job_set_state(env->jobs, j, SCICAPD_JOB_CANCELED, "canceled");
        scicapd_rig_post(a, j, "capture.canceled", json_pack("{s:i}", "acquired", i));
    }
    running_clear(env);
}

