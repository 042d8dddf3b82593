/* daemon/acquire.c — the acquisition thread (see the header). */
#include "daemon/acquire.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "daemon/devices.h"
#include "drivers/capture.h"

#define MAX_CALIB 64
#define RETRY_NS 5000000000LL /* a device that failed to open is tried again this often while idle */

typedef struct calib_entry {
    char key[96];            /* "dark" or "masks-<set>" */
    sci_cube *data;          /* dark counts, or measured masks */
    json_t *record;
    double counts_per_unit;  /* masks: white level */
    int missing;             /* looked up in the store and not found */
} calib_entry;

typedef struct mask_cache {
    char name[SCICAPD_NAME_MAX];
    scicapd_mask_set def;
    sci_cube *masks;
} mask_cache;

struct scicapd_acquire {
    scicapd_acquire_env env;
    scicapd_devices *dev;       /* DMD, camera, trigger per backend (daemon/devices.h) */
    /* per job, from dev (valid while the thread runs a job: devices change only between jobs) */
    scicapd_simbench *sim;      /* NULL on a real camera */
    dmd *dmd;
    camera *cam;
    trigger *trig;
    dmd_identity dmd_id;
    double counts_per_unit, dark_level;
    pthread_t thread;
    int running;
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
    calib_entry calib[MAX_CALIB];
    int ncalib;
    capture_snapshot *snap;
};

static void post(scicapd_acquire *a, const scicapd_job *j, const char *name, json_t *data)
{
    scicapd_mailbox_post(a->env.mailbox, j ? j->client : 0, j ? (long)j->owner : SCICAPD_OWNER_ALL, 1,
                         scicapd_event(name, j ? j->id : 0, j ? j->request_id : NULL, data));
}

static void on_dmd_event(void *user, dmd_event ev, const char *serial)
{
    scicapd_acquire *a = user;
    a->uploaded[0] = '\0';
    a->timing_valid = 0;
    sci_log_write(a->env.log, SCI_LOG_WARNING, "DMD %s %s", serial ? serial : "",
                  ev == DMD_EVENT_CONNECTED ? "connected" : "disconnected");
    post(a, NULL, ev == DMD_EVENT_CONNECTED ? "device.connected" : "device.disconnected",
         json_pack("{s:s, s:s}", "device", "dmd", "serial", serial ? serial : ""));
}

static void set_scale(scicapd_acquire *a, const scicapd_config *cfg)
{
    a->counts_per_unit = cfg->counts_per_unit > 0 ? cfg->counts_per_unit : cfg->sim_counts_per_unit;
    a->dark_level = cfg->sim_dark_counts;
}

int scicapd_acquire_new(scicapd_acquire **out, const scicapd_config *cfg, const scicapd_acquire_env *env,
                        sci_error *err)
{
    scicapd_acquire *a = calloc(1, sizeof *a);
    if (!a || !(a->snap = calloc(1, sizeof *a->snap))) {
        free(a);
        return sci_error_set(err, -ENOMEM, "acquire: out of memory");
    }
    a->env = *env;
    pthread_mutex_init(&a->mu, NULL);
    /* device errors do not fail the start: they are kept, shown and retried (daemon/devices.h) */
    int rc = scicapd_devices_open(&a->dev, cfg, env->log, on_dmd_event, a, err);
    if (rc < 0) {
        scicapd_acquire_free(a);
        return rc;
    }
    set_scale(a, cfg);
    atomic_store(&a->heartbeat_ns, sci_clock_mono_ns());
    *out = a;
    return 0;
}

int scicapd_acquire_reconfigure(scicapd_acquire *a, const scicapd_config *cfg, sci_error *err)
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

void scicapd_acquire_free(scicapd_acquire *a)
{
    if (!a)
        return;
    scicapd_devices_close(a->dev);
    scicapd_config_free(a->pending);
    for (int i = 0; i < a->nmasks; i++)
        sci_cube_free(a->masks[i].masks);
    for (int i = 0; i < a->ncalib; i++) {
        sci_cube_free(a->calib[i].data);
        json_decref(a->calib[i].record);
    }
    capture_snapshot_release(a->snap);
    free(a->snap);
    pthread_mutex_destroy(&a->mu);
    free(a);
}

int64_t scicapd_acquire_heartbeat_ns(scicapd_acquire *a) { return atomic_load(&a->heartbeat_ns); }
int scicapd_acquire_dmd_connected(scicapd_acquire *a) { return scicapd_devices_dmd_connected(a->dev); }

json_t *scicapd_acquire_devices_json(scicapd_acquire *a) { return scicapd_devices_json(a->dev); }

int scicapd_acquire_fault(scicapd_acquire *a, const scicapd_simulate_args *f, sci_error *err)
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

static void apply_faults(scicapd_acquire *a)
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

/* ---- mask sets and calibrations ---- */

static const sci_cube *mask_set_cube(scicapd_acquire *a, const scicapd_mask_set *ms, sci_error *err)
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

static calib_entry *calib_get(scicapd_acquire *a, const char *key)
{
    for (int i = 0; i < a->ncalib; i++)
        if (strcmp(a->calib[i].key, key) == 0)
            return a->calib[i].missing ? NULL : &a->calib[i];
    if (a->ncalib == MAX_CALIB)
        return NULL;
    calib_entry *c = &a->calib[a->ncalib++];
    memset(c, 0, sizeof *c);
    snprintf(c->key, sizeof c->key, "%s", key);
    sci_error err = {0};
    if (scicapd_store_load_calibration(a->env.store, key, &c->data, &c->record, &err) < 0) {
        if (err.code != -ENOENT)
            sci_log_write(a->env.log, SCI_LOG_WARNING, "calibration %s: %s", key, err.msg);
        c->missing = 1;
        return NULL;
    }
    c->counts_per_unit = json_number_value(json_object_get(c->record, "counts_per_unit"));
    return c;
}

static void calib_set(scicapd_acquire *a, const char *key, sci_cube *data, json_t *record, double cpu)
{
    calib_entry *c = NULL;
    for (int i = 0; i < a->ncalib; i++)
        if (strcmp(a->calib[i].key, key) == 0)
            c = &a->calib[i];
    if (!c && a->ncalib < MAX_CALIB)
        c = &a->calib[a->ncalib++];
    if (!c) {
        sci_cube_free(data);
        json_decref(record);
        return;
    }
    sci_cube_free(c->data);
    json_decref(c->record);
    snprintf(c->key, sizeof c->key, "%s", key);
    c->data = data;
    c->record = record;
    c->counts_per_unit = cpu;
    c->missing = 0;
}

/* ---- one snapshot ---- */

static int program(scicapd_acquire *a, const char *set_name, const sci_cube *masks, uint32_t pattern_us,
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

/* Arm, take one frame, stop. The frame is in a->snap. */
static int take(scicapd_acquire *a, int n, uint32_t exposure_us, enum sync_mode mode, int dark, sci_error *err)
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
    if (mode == SYNC_MODE_CAMERA_MASTER) {
        /* A free-running camera has frames waiting: drain them before arming, so that the first strobe after
         * the arm belongs to an exposure capture_snapshot_take keeps (draining takes time on the simulator). */
        sci_error e0 = {0};
        for (int k = 0; k < 4 * CAMERA_MAX_BUFFERS && camera_wait_frame(a->cam, 0, &a->snap->frame, &e0) == 0; k++)
            ;
    }
    if (mode != SYNC_MODE_DMD_MASTER) {
        /* armed: the sequence starts at the trigger input's edge */
        if (!dark && (rc = dmd_start(a->dmd, err)) < 0)
            goto out;
    } else {
        p.dmd = a->dmd;
    }
    rc = capture_snapshot_take(a->cam, a->trig, &p, a->snap, err);
    sci_error e2 = {0};
    dmd_stop(a->dmd, &e2);
    if (rc == -ENODEV || rc == -EIO) {
        sci_error e3 = {0};
        camera_recover(a->cam, &e3);
    }
out:
    free(plan);
    return rc;
}

static int frame_cube(const camera_frame *f, sci_cube **out, sci_error *err)
{
    int rc = sci_cube_new(out, (int)f->width, (int)f->height, 1, err);
    if (rc < 0)
        return rc;
    size_t np = (size_t)f->width * f->height;
    for (size_t i = 0; i < np; i++)
        (*out)->data[i] = (float)f->data[i];
    return 0;
}

static json_t *time_json(int64_t mono_ns)
{
    int64_t real = sci_clock_real_ns();
    time_t s = (time_t)(real / 1000000000);
    struct tm tm;
    char iso[64];
    gmtime_r(&s, &tm);
    strftime(iso, sizeof iso, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return json_pack("{s:I, s:I, s:s}", "mono_ns", (json_int_t)mono_ns, "realtime_ns", (json_int_t)real, "utc", iso);
}

/* Build the stored snapshot from a->snap. */
static int package(scicapd_acquire *a, scicapd_job *j, int index, const sci_cube *ideal, scicapd_snapshot **out,
                   sci_error *err)
{
    const scicapd_capture_args *c = &j->capture;
    scicapd_snapshot *s = calloc(1, sizeof *s);
    sci_problem *p = calloc(1, sizeof *p);
    int rc = -ENOMEM;
    if (!s || !p) {
        free(s);
        free(p);
        return sci_error_set(err, -ENOMEM, "acquire: out of memory");
    }
    s->problem = p;
    s->index = index;
    if ((rc = frame_cube(&a->snap->frame, &s->raw, err)) < 0 || (rc = sci_cube_clone(&s->dmd_masks, ideal, err)) < 0 ||
        (rc = sci_cube_new(&p->meas, s->raw->w, s->raw->h, 1, err)) < 0)
        goto fail;
    char key[96];
    snprintf(key, sizeof key, "masks-%s", c->mask_set.name);
    calib_entry *dark = calib_get(a, "dark"), *cm = calib_get(a, key);
    if (dark && !sci_cube_same_shape(dark->data, s->raw))
        dark = NULL;
    if (cm && (cm->data->w != s->raw->w || cm->data->h != s->raw->h || cm->data->n != ideal->n))
        cm = NULL; /* measured masks are at the sensor's size, one per mask of the set */
    double cpu = cm && cm->counts_per_unit > 0 ? cm->counts_per_unit : a->counts_per_unit;
    double level = dark ? 0 : a->dark_level;
    for (size_t i = 0; i < sci_cube_count(s->raw); i++)
        p->meas->data[i] = (float)((s->raw->data[i] - (dark ? dark->data->data[i] : level)) / cpu);
    if (cm)
        rc = sci_cube_clone(&p->mask, cm->data, err);
    else if (ideal->w == s->raw->w && ideal->h == s->raw->h)
        rc = sci_cube_clone(&p->mask, ideal, err); /* a mirror per pixel: the DMD masks are the sensor's */
    else if (a->sim)
        rc = scicapd_simbench_crop(a->sim, ideal, &p->mask, err); /* the simulated camera's window */
    else
        rc = sci_error_set(err, SCI_ESHAPE, "the DMD is %d×%d and the camera %d×%d: without measured masks the "
                           "snapshot cannot be reconstructed; run `scicap calibrate --masks --mask-set %s` first",
                           ideal->w, ideal->h, s->raw->w, s->raw->h, c->mask_set.name);
    if (rc < 0)
        goto fail;
    if (dark && (rc = sci_cube_clone(&s->dark, dark->data, err)) < 0)
        goto fail;
    if (a->sim) {
        const sci_cube *t = scicapd_simbench_truth(a->sim, ideal->n, err);
        if (!t || (rc = sci_cube_clone(&p->truth, t, err)) < 0) {
            rc = err ? err->code : -EIO;
            goto fail;
        }
    }
    p->peak = 1;
    json_t *cal = json_object();
    if (dark)
        json_object_set(cal, "dark", dark->record);
    if (cm)
        json_object_set(cal, "masks", cm->record);
    json_object_set_new(cal, "kind", json_string(cm ? "measured-masks" : dark ? "dark-only" : "none"));
    s->calibration = cal;
    s->broken = a->snap->report.broken;
    json_t *m = capture_snapshot_meta_json(a->snap);
    if (!m) {
        rc = sci_error_set(err, -ENOMEM, "acquire: out of memory");
        goto fail;
    }
    json_object_set_new(m, "format", json_string("scicap-capture"));
    json_object_set_new(m, "version", json_integer(1));
    json_object_set_new(m, "software", json_pack("{s:s, s:s}", "name", "scicapd", "version", SCICAP_VERSION));
    json_object_set_new(m, "job", json_integer((json_int_t)j->id));
    json_object_set_new(m, "snapshot_index", json_integer(index));
    json_object_set_new(m, "settings",
                        json_pack("{s:s, s:i, s:I, s:I, s:I, s:s, s:f, s:f, s:s}", "mask_set", c->mask_set.name,
                                  "mask_count", ideal->n, "pattern_us", (json_int_t)c->pattern_us, "dark_us",
                                  (json_int_t)c->dark_us, "exposure_us", (json_int_t)camera_exposure_us(a->cam),
                                  "sync_mode", sync_mode_name(c->sync), "counts_per_unit", cpu, "dark_level_counts",
                                  level, "calibration", cm ? "measured-masks" : dark ? "dark-only" : "none"));
    json_object_set_new(m, "devices", scicapd_acquire_devices_json(a));
    json_t *ct = scicapd_devices_camera_trigger_json(a->dev);
    if (ct)
        json_object_set_new(m, "camera_trigger", ct); /* the software triggers the host sent, up to this frame */
    json_object_set_new(m, "requested", json_pack("{s:I}", "mono_ns", (json_int_t)j->submitted_ns));
    json_object_set_new(m, "captured", time_json(a->snap->start_ns));
    if (a->sim)
        json_object_set_new(m, "simulated", json_pack("{s:s}", "scene", scicapd_simbench_scene_name(a->sim)));
    s->meta = m;
    *out = s;
    return 0;
fail:
    scicapd_snapshot_free(a->env.jobs, s);
    return rc;
}

/* The devices for this job: all three open, or an error naming the one that is not. */
static int bind_devices(scicapd_acquire *a, enum sync_mode mode, sci_error *err)
{
    int rc = scicapd_devices_ready(a->dev, err);
    if (rc < 0 || (rc = scicapd_devices_check_sync(a->dev, mode, err)) < 0)
        return rc;
    a->sim = scicapd_devices_sim(a->dev);
    /* the simulated camera free-runs in camera master, waits for its trigger otherwise */
    if (a->sim && (rc = scicapd_simbench_set_free_run(a->sim, mode == SYNC_MODE_CAMERA_MASTER, err)) < 0)
        return rc;
    a->dmd = scicapd_devices_dmd(a->dev);
    a->cam = scicapd_devices_camera(a->dev);
    a->trig = scicapd_devices_trigger(a->dev);
    a->dmd_id = *scicapd_devices_dmd_identity(a->dev);
    return 0;
}

static void run_capture(scicapd_acquire *a, scicapd_job *j)
{
    const scicapd_capture_args *c = &j->capture;
    sci_error err = {0};
    scicapd_job_set_state(a->env.jobs, j, SCICAPD_JOB_RUNNING, NULL);
    scicapd_job_set_progress(a->env.jobs, j, 0, c->count, NAN);
    post(a, j, "capture.started", json_pack("{s:s, s:i}", "mask_set", c->mask_set.name, "count", c->count));
    int rc = bind_devices(a, c->sync, &err);
    const sci_cube *masks = rc < 0 ? NULL : mask_set_cube(a, &c->mask_set, &err);
    rc = masks ? 0 : err.code;
    uint32_t exposure = c->exposure_us ? c->exposure_us
                                       : scicapd_auto_exposure_us(c->mask_set.frames, c->pattern_us, c->dark_us,
                                                                  (uint32_t)(scicapd_devices_dmd_latency_ns(a->dev) / 1000));
    int i;
    for (i = 0; rc == 0 && i < c->count; i++) {
        if (atomic_load(&j->cancel) || atomic_load(&a->stop))
            break;
        apply_faults(a);
        scicapd_span sp;
        scicapd_span_begin(&sp);
        if ((rc = program(a, c->mask_set.name, masks, c->pattern_us, c->dark_us, c->sync, &err)) < 0 ||
            (rc = take(a, masks->n, exposure, c->sync, 0, &err)) < 0)
            break;
        atomic_store(&a->heartbeat_ns, sci_clock_mono_ns());
        char flags[160];
        sync_flags_describe(a->snap->report.flags, flags, sizeof flags);
        scicapd_snapshot *s = NULL;
        if ((rc = package(a, j, i, masks, &s, &err)) < 0)
            break;
        scicapd_timing_add(a->env.timing, SCICAPD_STAGE_ACQUIRE, &sp);
        post(a, j, "capture.snapshot", json_pack("{s:i, s:i, s:b, s:s, s:i, s:I}", "index", i, "count", c->count,
                                                 "broken", s->broken, "sync", flags, "inside", a->snap->report.inside,
                                                 "offset_ns", (json_int_t)a->snap->report.offset_ns));
        if (s->broken)
            sci_log_write(a->env.log, SCI_LOG_WARNING, "job %llu snapshot %d: broken sync (%s), stored flagged",
                          (unsigned long long)j->id, i, flags);
        if (a->delay_ms > 0) {
            struct timespec ts = {a->delay_ms / 1000, (a->delay_ms % 1000) * 1000000L};
            nanosleep(&ts, NULL);
        }
        s->job = scicapd_jobs_find(a->env.jobs, j->id); /* the writer's reference */
        /* ids in acquisition order, whichever writer stores it; durable before the snapshot goes on */
        if ((rc = scicapd_store_reserve_id(a->env.store, s, &err)) < 0) {
            scicapd_snapshot_free(a->env.jobs, s);
            break;
        }
        if (scicapd_queue_push_wait(a->env.out, s) < 0) {
            scicapd_snapshot_free(a->env.jobs, s);
            rc = sci_error_set(&err, -EPIPE, "storage writer stopped");
            break;
        }
    }
    if (rc < 0) {
        sci_log_write(a->env.log, SCI_LOG_ERR, "job %llu: snapshot %d: %s", (unsigned long long)j->id, i, err.msg);
        scicapd_job_set_state(a->env.jobs, j, SCICAPD_JOB_FAILED, err.msg);
        post(a, j, "capture.failed", json_pack("{s:i, s:s, s:s}", "index", i, "error", err.msg, "code",
                                               sci_strerror(rc)));
    } else if (i < c->count) {
        scicapd_job_set_state(a->env.jobs, j, SCICAPD_JOB_CANCELED, "canceled");
        post(a, j, "capture.canceled", json_pack("{s:i}", "acquired", i));
    }
}

static int average(scicapd_acquire *a, int n, int frames, uint32_t exposure, int dark, sci_cube *acc,
                   sci_error *err)
{
    memset(acc->data, 0, sci_cube_count(acc) * sizeof(float));
    for (int f = 0; f < frames; f++) {
        int rc = take(a, n, exposure, SYNC_MODE_HOST_MASTER, dark, err);
        if (rc < 0)
            return rc;
        const camera_frame *fr = &a->snap->frame;
        if ((int)fr->width != acc->w || (int)fr->height != acc->h)
            return sci_error_set(err, SCI_ESHAPE, "calibration: frame %ux%u, expected %dx%d", fr->width, fr->height,
                                 acc->w, acc->h);
        for (size_t i = 0; i < sci_cube_frame_size(acc); i++)
            acc->data[i] += (float)fr->data[i] / (float)frames;
    }
    return 0;
}

static void run_calibrate(scicapd_acquire *a, scicapd_job *j)
{
    const scicapd_calib_args *c = &j->calib;
    sci_error err = {0};
    scicapd_job_set_state(a->env.jobs, j, SCICAPD_JOB_RUNNING, NULL);
    int rc = 0;
    json_t *rec = NULL;
    sci_cube *acc = NULL, *result = NULL;
    camera_format cf;
    uint32_t lat = (uint32_t)(scicapd_devices_dmd_latency_ns(a->dev) / 1000);
    const sci_cube *masks = NULL;
    if ((rc = bind_devices(a, SYNC_MODE_HOST_MASTER, &err)) < 0)
        goto done;
    camera_format_get(a->cam, &cf);
    if (!(masks = mask_set_cube(a, &c->mask_set, &err))) {
        rc = err.code;
        goto done;
    }
    if ((rc = sci_cube_new(&acc, (int)cf.width, (int)cf.height, 1, &err)) < 0)
        goto done;
    if (c->kind == SCICAPD_CALIB_DARK) {
        /* The DMD is not started: no light reaches the sensor through the masks. */
        uint32_t e = c->exposure_us ? c->exposure_us
                                    : scicapd_auto_exposure_us(masks->n, c->pattern_us, c->dark_us, lat);
        post(a, j, "calibrate.started", json_pack("{s:s, s:i}", "kind", "dark", "frames", c->average));
        if ((rc = program(a, c->mask_set.name, masks, c->pattern_us, c->dark_us, SYNC_MODE_HOST_MASTER, &err)) < 0 ||
            (rc = average(a, masks->n, c->average, e, 1, acc, &err)) < 0)
            goto done;
        double mean = 0;
        for (size_t i = 0; i < sci_cube_count(acc); i++)
            mean += acc->data[i];
        mean /= (double)sci_cube_count(acc);
        rec = json_pack("{s:s, s:I, s:i, s:f, s:o}", "kind", "dark", "exposure_us", (json_int_t)e, "frames",
                        c->average, "mean_counts", mean, "time", time_json(sci_clock_mono_ns()));
        json_t *final = NULL;
        if ((rc = scicapd_store_write_calibration(a->env.store, "dark", acc, rec, &final, &err)) < 0)
            goto done;
        calib_set(a, "dark", acc, json_incref(final), 0);
        acc = NULL;
        json_decref(rec);
        rec = final;
    } else {
        /* Each mask alone on a white target; white level from the pixels the mask opens. */
        calib_entry *dark = calib_get(a, "dark");
        if (dark && !sci_cube_same_shape(dark->data, acc))
            dark = NULL;
        if ((rc = sci_cube_new(&result, acc->w, acc->h, masks->n, &err)) < 0)
            goto done;
        uint32_t e = c->exposure_us ? c->exposure_us : scicapd_auto_exposure_us(1, c->pattern_us, c->dark_us, lat);
        post(a, j, "calibrate.started", json_pack("{s:s, s:s, s:i}", "kind", "masks", "mask_set", c->mask_set.name,
                                                   "masks", masks->n));
        sci_cube *one;
        if ((rc = sci_cube_new(&one, masks->w, masks->h, 1, &err)) < 0)
            goto done;
        if (a->sim)
            scicapd_simbench_set_target(a->sim, SCICAPD_TARGET_WHITE);
        else
            sci_log_write(a->env.log, SCI_LOG_NOTICE, "calibrate masks: expecting a uniform white target in front "
                          "of the camera");
        double white_sum = 0, white_n = 0;
        for (int k = 0; k < masks->n && rc == 0; k++) {
            if (atomic_load(&j->cancel) || atomic_load(&a->stop)) {
                rc = SCI_ECANCELED;
                sci_error_set(&err, rc, "canceled");
                break;
            }
            memcpy(one->data, sci_cube_frame(masks, k), sci_cube_frame_size(one) * sizeof(float));
            a->uploaded[0] = '\0';
            char tag[80];
            snprintf(tag, sizeof tag, ".calib-%d", k);
            if ((rc = program(a, tag, one, c->pattern_us, c->dark_us, SYNC_MODE_HOST_MASTER, &err)) < 0 ||
                (rc = average(a, 1, c->average, e, 0, acc, &err)) < 0)
                break;
            float *dst = sci_cube_frame(result, k);
            /* the white level from the pixels the mask opens: known when a mirror maps to a pixel, else the
             * pixels brighter than half the brightest */
            const float *ideal = masks->w == acc->w && masks->h == acc->h ? sci_cube_frame(masks, k) : NULL;
            float hi = 0;
            for (size_t i = 0; i < sci_cube_frame_size(acc); i++) {
                dst[i] = acc->data[i] - (dark ? dark->data->data[i] : (float)a->dark_level);
                hi = dst[i] > hi ? dst[i] : hi;
            }
            for (size_t i = 0; i < sci_cube_frame_size(acc); i++)
                if (ideal ? ideal[i] >= 0.5f : dst[i] > 0.5f * hi) {
                    white_sum += dst[i];
                    white_n++;
                }
            scicapd_job_set_progress(a->env.jobs, j, k + 1, masks->n, NAN);
            post(a, j, "calibrate.progress", json_pack("{s:i, s:i}", "mask", k + 1, "of", masks->n));
        }
        if (a->sim)
            scicapd_simbench_set_target(a->sim, SCICAPD_TARGET_SCENE);
        a->uploaded[0] = '\0';
        sci_cube_free(one);
        if (rc < 0)
            goto done;
        double white = white_n > 0 ? white_sum / white_n : 0;
        if (!(white > 1)) {
            rc = sci_error_set(&err, SCI_EDEVICE, "calibration: no light on the white target (mean %.1f counts)", white);
            goto done;
        }
        for (size_t i = 0; i < sci_cube_count(result); i++)
            result->data[i] /= (float)white;
        rec = json_pack("{s:s, s:s, s:i, s:f, s:I, s:i, s:b, s:o}", "kind", "masks", "mask_set", c->mask_set.name,
                        "masks", masks->n, "counts_per_unit", white, "exposure_us", (json_int_t)e, "frames",
                        c->average, "dark_subtracted", dark != NULL, "time", time_json(sci_clock_mono_ns()));
        char key[96];
        snprintf(key, sizeof key, "masks-%s", c->mask_set.name);
        json_t *final = NULL;
        if ((rc = scicapd_store_write_calibration(a->env.store, key, result, rec, &final, &err)) < 0)
            goto done;
        calib_set(a, key, result, json_incref(final), white);
        result = NULL;
        json_decref(rec);
        rec = final;
    }
done:
    if (rc < 0) {
        scicapd_job_set_state(a->env.jobs, j, rc == SCI_ECANCELED ? SCICAPD_JOB_CANCELED : SCICAPD_JOB_FAILED, err.msg);
        post(a, j, rc == SCI_ECANCELED ? "calibrate.canceled" : "calibrate.failed", json_pack("{s:s}", "error", err.msg));
    } else {
        scicapd_job_add_output(a->env.jobs, j, json_string_value(json_object_get(rec, "id")));
        scicapd_job_set_state(a->env.jobs, j, SCICAPD_JOB_DONE, NULL);
        post(a, j, "calibrate.done", json_incref(rec));
    }
    json_decref(rec);
    sci_cube_free(acc);
    sci_cube_free(result);
}

static void forget_masks(scicapd_acquire *a)
{
    for (int i = 0; i < a->nmasks; i++)
        sci_cube_free(a->masks[i].masks);
    a->nmasks = 0;
    a->uploaded[0] = '\0';
    a->timing_valid = 0;
}

/* A reloaded configuration: re-open the devices if their settings changed, else retry the missing ones now. */
static void apply_config(scicapd_acquire *a)
{
    pthread_mutex_lock(&a->mu);
    scicapd_config *c = a->pending;
    a->pending = NULL;
    pthread_mutex_unlock(&a->mu);
    if (!c)
        return;
    sci_error err = {0};
    set_scale(a, c);
    if (scicapd_devices_differ(a->dev, c)) {
        forget_masks(a); /* the DMD may have another size */
        if (scicapd_devices_reconfigure(a->dev, c, &err) < 0)
            sci_log_write(a->env.log, SCI_LOG_ERR, "devices: %s", err.msg);
    } else {
        scicapd_devices_retry(a->dev, 0, 1);
    }
    scicapd_config_free(c);
}

static void *acquire_main(void *arg)
{
    scicapd_acquire *a = arg;
    while (!atomic_load(&a->stop)) {
        atomic_store(&a->heartbeat_ns, sci_clock_mono_ns());
        scicapd_job *j = scicapd_queue_pop(a->env.in, 200000000);
        apply_faults(a);
        apply_config(a);
        sci_error err = {0};
        scicapd_devices_retry(a->dev, RETRY_NS, 0);
        dmd *dm = scicapd_devices_dmd(a->dev);
        if (dm)
            dmd_poll(dm, 0, &err);
        if (!j)
            continue;
        if (atomic_load(&j->cancel)) {
            scicapd_job_set_state(a->env.jobs, j, SCICAPD_JOB_CANCELED, "canceled before it started");
            post(a, j, j->kind == SCICAPD_JOB_CAPTURE ? "capture.canceled" : "calibrate.canceled",
                 json_pack("{s:i}", "acquired", 0));
        } else if (j->kind == SCICAPD_JOB_CAPTURE) {
            run_capture(a, j);
        } else {
            run_calibrate(a, j);
        }
        scicapd_job_unref(a->env.jobs, j);
    }
    /* jobs still queued: canceled, and said so */
    scicapd_job *j;
    while ((j = scicapd_queue_take(a->env.in))) {
        scicapd_job_set_state(a->env.jobs, j, SCICAPD_JOB_CANCELED, "daemon stopping");
        post(a, j, j->kind == SCICAPD_JOB_CAPTURE ? "capture.canceled" : "calibrate.canceled",
             json_pack("{s:s}", "reason", "daemon stopping"));
        scicapd_job_unref(a->env.jobs, j);
    }
    return NULL;
}

int scicapd_acquire_start(scicapd_acquire *a, sci_error *err)
{
    int rc = pthread_create(&a->thread, NULL, acquire_main, a);
    if (rc != 0)
        return sci_error_set(err, -rc, "acquire: cannot start the thread: %s", strerror(rc));
    a->running = 1;
    return 0;
}

void scicapd_acquire_stop(scicapd_acquire *a)
{
    if (!a || !a->running)
        return;
    atomic_store(&a->stop, 1);
    pthread_join(a->thread, NULL);
    a->running = 0;
}
