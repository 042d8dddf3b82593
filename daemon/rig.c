/* daemon/rig.c — the devices as the acquisition jobs use them (see the header). */
#include "daemon/rig.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"

#define RETRY_NS 5000000000LL /* a device that failed to open is tried again this often while idle */

typedef struct mask_cache {
    char name[SCICAPD_NAME_MAX];
    scicapd_mask_set def;
    sci_cube *masks;
} mask_cache;

struct scicapd_rig {
    scicapd_rig_env env;
    scicapd_devices *dev;       /* DMD, camera, trigger per backend (daemon/devices.h) */
    scicapd_calibs *calibs;     /* the calibrations in use (daemon/calibs.h) */
    /* per job, from dev (valid while the thread runs a job: devices change only between jobs) */
    dmd *dmd;
    camera *cam;
    trigger *trig;
    dmd_identity dmd_id;
    double counts_per_unit, dark_level;
    atomic_int stop;
    _Atomic int64_t heartbeat_ns;
    /* faults, under mu */
    pthread_mutex_t mu;
    scicapd_simulate_args faults[16];
    int nfaults;
    long delay_ms;
    scicapd_config *pending;    /* a reloaded configuration for the devices (applied between jobs) */
    /* thread-only state */
    char uploaded[SCICAPD_NAME_MAX]; /* mask set on the DMD ("" after a reconnect) */
    dmd_timing timing;
    int timing_valid;
    mask_cache masks[8];
    int nmasks;
    capture_snapshot *snap;
};

void scicapd_rig_post(scicapd_rig *a, const scicapd_job *j, const char *name, json_t *data)
{
    scicapd_mailbox_post(a->env.mailbox, j ? j->client : 0, j ? (long)j->owner : SCICAPD_OWNER_ALL, 1,
                         scicapd_event(name, j ? j->id : 0, j ? j->request_id : NULL, data));
}

static void on_dmd_event(void *user, dmd_event ev, const char *serial)
{
    scicapd_rig *a = user;
    a->uploaded[0] = '\0';
    a->timing_valid = 0;
    sci_log_write(a->env.log, SCI_LOG_WARNING, "DMD %s %s", serial ? serial : "",
                  ev == DMD_EVENT_CONNECTED ? "connected" : "disconnected");
    scicapd_rig_post(a, NULL, ev == DMD_EVENT_CONNECTED ? "device.connected" : "device.disconnected",
                         json_pack("{s:s, s:s}", "device", "dmd", "serial", serial ? serial : ""));
}

int scicapd_rig_new(scicapd_rig **out, const scicapd_config *cfg, const scicapd_rig_env *env,
                        sci_error *err)
{
    scicapd_rig *a = calloc(1, sizeof *a);
    if (!a || !(a->snap = calloc(1, sizeof *a->snap))) {
        free(a);
        return sci_error_set(err, -ENOMEM, "acquire: out of memory");
    }
    a->env = *env;
    pthread_mutex_init(&a->mu, NULL);
    int rc = scicapd_calibs_new(&a->calibs, env->store, env->log, err);
    /* device errors do not fail the start: they are kept, shown and retried (daemon/devices.h) */
    if (rc < 0 || (rc = scicapd_devices_open(&a->dev, cfg, env->log, on_dmd_event, a, err)) < 0) {
        scicapd_rig_free(a);
        return rc;
    }
    scicapd_config_uncalibrated_scale(cfg, &a->counts_per_unit, &a->dark_level);
    atomic_store(&a->heartbeat_ns, sci_clock_mono_ns());
    *out = a;
    return 0;
}

int scicapd_rig_reconfigure(scicapd_rig *a, const scicapd_config *cfg, sci_error *err)
{
    scicapd_config *c;
    int rc = scicapd_config_copy(&c, cfg, err);
    if (rc < 0)
        return rc;
    pthread_mutex_lock(&a->mu);
    scicapd_config_free(a->pending);
    a->pending = c;
    pthread_mutex_unlock(&a->mu);
    return 0;
}

void scicapd_rig_free(scicapd_rig *a)
{
    if (!a)
        return;
    scicapd_devices_close(a->dev);
    scicapd_config_free(a->pending);
    for (int i = 0; i < a->nmasks; i++)
        sci_cube_free(a->masks[i].masks);
    scicapd_calibs_free(a->calibs);
    capture_snapshot_release(a->snap);
    free(a->snap);
    pthread_mutex_destroy(&a->mu);
    free(a);
}

int64_t scicapd_rig_heartbeat_ns(scicapd_rig *a) { return atomic_load(&a->heartbeat_ns); }
int scicapd_rig_dmd_connected(scicapd_rig *a) { return scicapd_devices_dmd_connected(a->dev); }

json_t *scicapd_rig_devices_json(scicapd_rig *a) { return scicapd_devices_json(a->dev); }

int scicapd_rig_fault(scicapd_rig *a, const scicapd_simulate_args *f, sci_error *err)
{
    if (!scicapd_devices_fault_supported(a->dev, f->fault))
        return sci_error_set(err, -ENOTSUP, "simulate: this fault can only be injected into simulated devices "
                             "(DMD faults need the \"sim\" DMD or the DLPC900 emulator; camera and trigger faults "
                             "the simulated camera and trigger)");
    pthread_mutex_lock(&a->mu);
    int rc = 0;
    if (a->nfaults == 16)
        rc = sci_error_set(err, SCI_EBUSY, "simulate: 16 faults already pending");
    else
        a->faults[a->nfaults++] = *f;
    pthread_mutex_unlock(&a->mu);
    return rc;
}

void scicapd_rig_apply_faults(scicapd_rig *a)
{
    scicapd_simulate_args f[16];
    pthread_mutex_lock(&a->mu);
    int n = a->nfaults;
    memcpy(f, a->faults, sizeof f);
    a->nfaults = 0;
    pthread_mutex_unlock(&a->mu);
    for (int i = 0; i < n; i++) {
        sci_log_write(a->env.log, SCI_LOG_NOTICE, "simulate: fault %d (n = %ld)", (int)f[i].fault, f[i].n);
        if (f[i].fault == SCICAPD_FAULT_ACQUIRE_DELAY)
            a->delay_ms = f[i].n;
        else
            scicapd_devices_fault_apply(a->dev, f[i].fault, f[i].n);
    }
}

const scicapd_rig_env *scicapd_rig_env_get(const scicapd_rig *a) { return &a->env; }
scicapd_devices *scicapd_rig_devices(scicapd_rig *a) { return a->dev; }
scicapd_calibs *scicapd_rig_calibs(scicapd_rig *a) { return a->calibs; }
int scicapd_rig_canceled(scicapd_rig *a, const scicapd_job *j)
{
    return atomic_load(&j->cancel) || atomic_load(&a->stop);
}
void scicapd_rig_beat(scicapd_rig *a) { atomic_store(&a->heartbeat_ns, sci_clock_mono_ns()); }

void scicapd_rig_injected_delay(scicapd_rig *a)
{
    if (a->delay_ms > 0) {
        struct timespec ts = {a->delay_ms / 1000, (a->delay_ms % 1000) * 1000000L};
        nanosleep(&ts, NULL);
    }
}

void scicapd_rig_scale(const scicapd_rig *a, double *counts_per_unit, double *dark_level)
{
    *counts_per_unit = a->counts_per_unit;
    *dark_level = a->dark_level;
}

/* ---- mask sets ---- */

const sci_cube *scicapd_rig_mask_set(scicapd_rig *a, const scicapd_mask_set *ms, sci_error *err)
{
    for (int i = 0; i < a->nmasks; i++)
        if (memcmp(&a->masks[i].def, ms, sizeof *ms) == 0)
            return a->masks[i].masks;
    sci_cube *m;
    sim_mask_spec spec = ms->spec;
    spec.dmd_w = a->dmd_id.width;
    spec.dmd_h = a->dmd_id.height;
    spec.scale = 1;
    spec.mapped = 0;
    if (sim_masks_make(&spec, a->dmd_id.width, a->dmd_id.height, ms->frames, ms->seed, &m, err) < 0) {
        sci_error_prefix(err, "mask set %s: ", ms->name);
        return NULL;
    }
    int slot = a->nmasks < 8 ? a->nmasks++ : 0;
    if (a->masks[slot].masks)
        sci_cube_free(a->masks[slot].masks);
    a->masks[slot] = (mask_cache){.def = *ms, .masks = m};
    snprintf(a->masks[slot].name, sizeof a->masks[slot].name, "%s", ms->name);
    if (strcmp(a->uploaded, ms->name) == 0)
        a->uploaded[0] = '\0'; /* same name, new definition (reload): upload again */
    return m;
}

/* ---- one snapshot ---- */

int scicapd_rig_program(scicapd_rig *a, const char *set_name, const sci_cube *masks, uint32_t pattern_us,
                   uint32_t dark_us, enum sync_mode mode, sci_error *err)
{
    int rc;
    if (pattern_us < (uint32_t)a->dmd_id.min_exposure_us)
        return sci_error_set(err, -EINVAL, "pattern_us %u is below the minimum exposure of DMD %s %s (%d µs)",
                             pattern_us, a->dmd_id.model, a->dmd_id.serial, a->dmd_id.min_exposure_us);
    if (strcmp(a->uploaded, set_name) != 0) {
        a->uploaded[0] = '\0';
        if ((rc = dmd_upload(a->dmd, masks, err)) < 0)
            return rc;
        snprintf(a->uploaded, sizeof a->uploaded, "%s", set_name);
        a->timing_valid = 0;
    }
    /* host and camera master: the DMD waits for its trigger input (our pulse, or the camera's strobe) */
    dmd_timing t = {.exposure_us = pattern_us, .dark_us = dark_us, .passes = 1,
                    .trigger = mode == SYNC_MODE_DMD_MASTER ? DMD_TRIGGER_INTERNAL : DMD_TRIGGER_EXTERNAL};
    scicapd_devices_timing_defaults(a->dev, &t);
    if (!a->timing_valid || a->timing.exposure_us != t.exposure_us || a->timing.dark_us != t.dark_us ||
        a->timing.trigger != t.trigger) {
        if ((rc = dmd_set_timing(a->dmd, &t, err)) < 0)
            return rc;
        a->timing = t;
        a->timing_valid = 1;
    }
    return 0;
}

int scicapd_rig_take(scicapd_rig *a, int n, uint32_t exposure_us, enum sync_mode mode, int dark, sci_error *err)
{
    int rc;
    uint32_t e = exposure_us;
    if (camera_exposure_us(a->cam) != e && (rc = camera_set_exposure_us(a->cam, &e, err)) < 0)
        return rc;
    sync_timeline *plan = malloc(sizeof *plan);
    if (!plan)
        return sci_error_set(err, -ENOMEM, "acquire: out of memory");
    if ((rc = capture_timeline_from_dmd(&a->timing, n, plan, err)) < 0)
        goto out;
    capture_params p = capture_params_default();
    p.mode = mode;
    p.timeline = plan;
    p.dmd_latency_ns = scicapd_devices_dmd_latency_ns(a->dev);
    p.readout_ns = scicapd_devices_readout_ns(a->dev);
    p.frame_timeout_ns = (int64_t)e * 1000 + 500000000;
    if (mode == SYNC_MODE_HOST_MASTER) {
        /* armed: the sequence starts at the trigger input's edge */
        if (!dark && (rc = dmd_start(a->dmd, err)) < 0)
            goto out;
    } else if (mode == SYNC_MODE_DMD_MASTER || !dark) {
        /* DMD master starts it; camera master arms it after draining the free-running camera, so that the
         * exposure whose strobe starts the sequence cannot be drained as stale */
        p.dmd = a->dmd;
    }
    rc = capture_snapshot_take(a->cam, a->trig, &p, a->snap, err);
    sci_error e2 = {0};
    dmd_stop(a->dmd, &e2);
    if ((rc == -ENODEV || rc == -EIO) && !a->snap->dmd_failed) { /* the camera's error, not the DMD's */
        sci_error e3 = {0};
        camera_recover(a->cam, &e3);
    }
out:
    free(plan);
    return rc;
}

void scicapd_rig_forget_upload(scicapd_rig *a) { a->uploaded[0] = '\0'; }
const capture_snapshot *scicapd_rig_shot(const scicapd_rig *a) { return a->snap; }
const dmd_identity *scicapd_rig_dmd_identity(const scicapd_rig *a) { return &a->dmd_id; }
camera *scicapd_rig_camera(scicapd_rig *a) { return a->cam; }

int scicapd_rig_bind(scicapd_rig *a, enum sync_mode mode, sci_error *err)
{
    int rc = scicapd_devices_prepare(a->dev, mode, err);
    if (rc < 0)
        return rc;
    a->dmd = scicapd_devices_dmd(a->dev);
    a->cam = scicapd_devices_camera(a->dev);
    a->trig = scicapd_devices_trigger(a->dev);
    a->dmd_id = *scicapd_devices_dmd_identity(a->dev);
    return 0;
}

static void forget_masks(scicapd_rig *a)
{
    for (int i = 0; i < a->nmasks; i++)
        sci_cube_free(a->masks[i].masks);
    a->nmasks = 0;
    a->uploaded[0] = '\0';
    a->timing_valid = 0;
}

void scicapd_rig_apply_config(scicapd_rig *a)
{
    pthread_mutex_lock(&a->mu);
    scicapd_config *c = a->pending;
    a->pending = NULL;
    pthread_mutex_unlock(&a->mu);
    if (!c)
        return;
    sci_error err = {0};
    scicapd_config_uncalibrated_scale(c, &a->counts_per_unit, &a->dark_level);
    if (scicapd_devices_differ(a->dev, c)) {
        forget_masks(a); /* the DMD may have another size */
        if (scicapd_devices_reconfigure(a->dev, c, &err) < 0)
            sci_log_write(a->env.log, SCI_LOG_ERR, "devices: %s", err.msg);
    } else {
        scicapd_devices_retry(a->dev, 0, 1);
    }
    scicapd_config_free(c);
}

void scicapd_rig_idle(scicapd_rig *a)
{
    sci_error err = {0};
    scicapd_devices_retry(a->dev, RETRY_NS, 0);
    dmd *dm = scicapd_devices_dmd(a->dev);
    if (dm)
        dmd_poll(dm, 0, &err);
}

void scicapd_rig_stop_request(scicapd_rig *a) { atomic_store(&a->stop, 1); }
int scicapd_rig_stopping(const scicapd_rig *a) { return atomic_load(&a->stop); }
