/* daemon/devices.c — open the bench's devices per backend, keep their errors, re-open what is missing. */
#include "daemon/devices.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "daemon/backends.h"
#include "daemon/swtrigger.h"
#include "drivers/dlpc900_emu.h"
#include "sim/bench.h"
#include "sim/dmd_sim.h"
#include "sim/trigger_sim.h"

enum { DEV_DMD, DEV_CAMERA, DEV_TRIGGER, DEV_COUNT };
static const char *const dev_names[DEV_COUNT] = {"dmd", "camera", "trigger"};

struct scicapd_devices {
    scicapd_config *cfg;       /* owned copy: what the devices were opened with */
    const sci_log *log;
    dmd_event_fn on_event;
    void *user;
    sim_bench *sim;            /* camera and trigger simulated (sim/bench.h) */
    dlpc900_emu *emu;          /* dlpc900 backend with "emulator": true */
    dmd *dmd_dev;              /* NULL while closed */
    int dmd_open;
    dmd_identity dmd_id;
    camera *cam;               /* real camera (the simulated one belongs to sim) */
    int cam_software;          /* cam waits for its software trigger: trig is a scicapd_swtrigger around the
                                  configured trigger (daemon/swtrigger.h) */
    trigger *trig;
    char error[DEV_COUNT][512]; /* open error, "" when open */
    int64_t last_try_ns;
    /* shared with other threads */
    pthread_mutex_t mu;
    json_t *json;              /* description, rebuilt after every change */
    atomic_int dmd_connected, can_dmd_faults, can_bench_faults;
};

/* ---- description (for `devices`, `status` and meta.json) ---- */

static void merge(json_t *into, json_t *from)
{
    json_object_update(into, from);
    json_decref(from);
}

static json_t *describe(scicapd_devices *d)
{
    const scicapd_config *c = d->cfg;
    json_t *o = json_object();
    const char *backends[DEV_COUNT] = {c->dmd_backend, c->camera_backend, c->trigger_backend};
    for (int i = 0; i < DEV_COUNT; i++) {
        json_t *e = json_pack("{s:s, s:b}", "backend", backends[i], "connected",
                              i == DEV_DMD ? atomic_load(&d->dmd_connected) : !d->error[i][0]);
        if (d->error[i][0])
            json_object_set_new(e, "error", json_string(d->error[i]));
        json_object_set_new(o, dev_names[i], e);
    }
    json_t *dm = json_object_get(o, "dmd");
    if (d->dmd_open) {
        const dmd_identity *id = &d->dmd_id;
        merge(dm, json_pack("{s:s, s:s, s:s, s:i, s:i, s:i, s:i}", "model", id->model, "serial",
                                         id->serial, "firmware", id->firmware, "width", id->width, "height",
                                         id->height, "max_masks", id->max_masks, "min_exposure_us",
                                         id->min_exposure_us));
        if (d->emu)
            json_object_set_new(dm, "transport", json_string("emulator"));
    }
    camera *cam = scicapd_devices_camera(d);
    if (cam) {
        camera_identity ci;
        camera_format cf;
        camera_identity_get(cam, &ci);
        camera_format_get(cam, &cf);
        merge(json_object_get(o, "camera"),
                           json_pack("{s:o, s:i, s:i, s:i}", "identity", camera_identity_json(&ci), "width",
                                     (int)cf.width, "height", (int)cf.height, "bits", cf.bits_per_sample));
    }
    trigger *tr = scicapd_devices_trigger(d);
    if (tr) {
        trigger_identity ti;
        trigger_identity_get(tr, &ti);
        json_object_set_new(json_object_get(o, "trigger"), "identity", trigger_identity_json(&ti));
    }
    return o;
}

static void publish(scicapd_devices *d)
{
    json_t *j = describe(d);
    pthread_mutex_lock(&d->mu);
    json_decref(d->json);
    d->json = j;
    pthread_mutex_unlock(&d->mu);
}

json_t *scicapd_devices_json(scicapd_devices *d)
{
    pthread_mutex_lock(&d->mu);
    json_t *j = json_deep_copy(d->json);
    pthread_mutex_unlock(&d->mu);
    return j;
}

int scicapd_devices_dmd_connected(scicapd_devices *d) { return atomic_load(&d->dmd_connected); }

/* ---- opening ---- */

/* Logged when it changes: a retry every few seconds that fails the same way stays quiet. */
static void set_error(scicapd_devices *d, int which, const char *msg)
{
    if (strncmp(d->error[which], msg, sizeof d->error[which] - 1) == 0)
        return;
    snprintf(d->error[which], sizeof d->error[which], "%s", msg);
    sci_log_write(d->log, SCI_LOG_ERR, "%s (%s): %s", dev_names[which],
                  which == DEV_DMD ? d->cfg->dmd_backend : which == DEV_CAMERA ? d->cfg->camera_backend
                                                                                : d->cfg->trigger_backend, msg);
}

static void on_dmd_event(void *user, dmd_event ev, const char *serial)
{
    scicapd_devices *d = user;
    scicapd_devices_dmd_event(d, ev);
    if (d->on_event)
        d->on_event(d->user, ev, serial);
}

void scicapd_devices_dmd_event(scicapd_devices *d, dmd_event ev)
{
    atomic_store(&d->dmd_connected, d->dmd_open && ev == DMD_EVENT_CONNECTED);
    publish(d);
}

/* The real camera, through the backend table (daemon/backends.h). */
static void open_camera(scicapd_devices *d)
{
    const scicapd_config *c = d->cfg;
    sci_error e = {0};
    scicapd_camera_backend b;
    camera_config cc;
    scicapd_camera_opts opts; /* cc.backend_options points here: alive until camera_open returns */
    camera *cam = NULL;
    int rc = scicapd_camera_backend_get(c->camera_backend, &b, &e);
    if (rc == 0)
        rc = b.parse ? b.parse(c->camera_json, "devices.camera", &cc, &opts, &e)
                     : sci_error_set(&e, -ENOTSUP, "the %s camera is opened with the simulated bench", b.ops->name);
    if (rc == 0)
        rc = camera_open(&cam, b.ops, &cc, &e);
    if (rc == 0 && (rc = camera_start(cam, &e)) < 0)
        camera_close(cam);
    if (rc < 0) {
        set_error(d, DEV_CAMERA, e.msg);
        return;
    }
    d->cam = cam;
    d->cam_software = scicapd_camera_software_trigger(&b, &opts);
    d->error[DEV_CAMERA][0] = '\0';
}

/* The configured trigger: gpiod, or (with Aravis's in-process fake camera only, daemon/config.c) a simulated one
 * whose output reaches nothing and whose inputs are not wired, like a bench with only the output line connected.
 * A camera in software-trigger mode gets it wrapped so that each pulse also fires the camera (swtrigger.h); the
 * wrapper needs the camera, so the trigger waits for it. */
static void open_trigger(scicapd_devices *d)
{
    const scicapd_config *c = d->cfg;
    sci_error e = {0};
    trigger *t = NULL;
    int rc;
    if (d->cam_software && !d->cam) {
        set_error(d, DEV_TRIGGER, "waiting for the camera (its software trigger is fired with each pulse)");
        return;
    }
    const trigger_ops *ops = scicapd_trigger_backend_find(c->trigger_backend, &e);
    if (!ops)
        rc = e.code;
    else if (scicapd_trigger_simulated(ops)) {
        trigger_sim_options so = {.seed = c->sim_seed};
        trigger_config tc = trigger_config_default();
        tc.chip = "sim-gpiochip";
        tc.output.offset = 0;
        tc.backend_options = &so;
        rc = trigger_open(&t, ops, &tc, &e);
    } else {
        trigger_config tc;
        rc = trigger_config_from_json(c->trigger_json, "devices.trigger", &tc, &e);
        if (rc == 0) {
            if (!tc.consumer)
                tc.consumer = "scicapd";
            rc = trigger_open(&t, ops, &tc, &e);
        }
    }
    if (rc == 0 && d->cam_software) {
        scicapd_swtrigger_options so = {.inner = t, .cam = d->cam};
        trigger_config tc = trigger_config_default();
        tc.backend_options = &so;
        trigger *w = NULL;
        if ((rc = trigger_open(&w, &scicapd_swtrigger_ops, &tc, &e)) < 0)
            trigger_close(t);
        t = w;
    }
    if (rc < 0) {
        set_error(d, DEV_TRIGGER, e.msg);
        return;
    }
    d->trig = t;
    d->error[DEV_TRIGGER][0] = '\0';
}

static void open_bench(scicapd_devices *d)
{
    const scicapd_config *c = d->cfg;
    sci_error e = {0};
    /* the simulated camera comes with the simulated bench (sim/bench.h), which also opens the trigger */
    scicapd_camera_backend cb;
    if (scicapd_camera_backend_get(c->camera_backend, &cb, NULL) == 0 && cb.simulated) {
        sim_bench_options o = sim_bench_options_default();
        o.scene_path = c->scene_path;
        o.seed = c->sim_seed;
        o.dmd_latency_ns = (int64_t)c->sim_dmd_latency_us * 1000;
        o.counts_per_unit = c->sim_counts_per_unit;
        o.dark_counts = c->sim_dark_counts;
        o.read_noise = c->sim_read_noise;
        if (!d->sim && sim_bench_open(&d->sim, &o, &e) < 0) {
            set_error(d, DEV_CAMERA, e.msg);
            set_error(d, DEV_TRIGGER, e.msg);
            return;
        }
        d->error[DEV_CAMERA][0] = d->error[DEV_TRIGGER][0] = '\0';
        atomic_store(&d->can_bench_faults, 1);
        return;
    }
    if (!d->cam)
        open_camera(d);
    if (!d->trig)
        open_trigger(d);
}

static void open_dmd(scicapd_devices *d)
{
    if (d->dmd_open)
        return;
    const scicapd_config *c = d->cfg;
    sci_error e = {0};
    dmd_config dc = dmd_config_default();
    dc.serial = c->dmd_serial[0] ? c->dmd_serial : NULL;
    dc.timeout_ms = c->dmd_timeout_ms > 0 ? c->dmd_timeout_ms : dc.timeout_ms;
    dc.on_event = on_dmd_event;
    dc.event_user = d;
    dc.log = d->log;
    int w = 0, h = 0, rc;
    if (d->sim)
        sim_bench_size(d->sim, &w, &h); /* emulated mirrors: one per simulated pixel */
    else if (d->cam) {
        /* an emulated DMD before a real camera: one mirror per pixel too, so that the masks it shows are the
         * reconstruction's (a real DMD has its own size: calibrate then, docs/config.md) */
        camera_format cf;
        camera_format_get(d->cam, &cf);
        w = (int)cf.width;
        h = (int)cf.height;
    }
    const dmd_ops *ops = scicapd_dmd_backend_find(c->dmd_backend, &e);
    if (!ops) {
        set_error(d, DEV_DMD, e.msg);
        return;
    }
    dc.width = w; /* the simulated DMD's size; a DLPC900 has its own */
    dc.height = h;
    if (scicapd_dmd_is_dlpc900(ops) && c->dmd_emulator) {
        if (!d->emu) {
            dlpc900_emu_config ec = {.serial = dc.serial ? dc.serial : "EMU0001", .width = w, .height = h};
            if ((rc = dlpc900_emu_new(&d->emu, &ec, &e)) < 0) {
                set_error(d, DEV_DMD, e.msg);
                return;
            }
        }
        dc.emulator = d->emu;
    }
    if ((rc = dmd_open(&d->dmd_dev, ops, &dc, &e)) < 0) {
        set_error(d, DEV_DMD, e.msg);
        return;
    }
    if ((rc = dmd_identify(d->dmd_dev, &d->dmd_id, &e)) < 0) {
        dmd_close(d->dmd_dev);
        d->dmd_dev = NULL;
        set_error(d, DEV_DMD, e.msg);
        return;
    }
    d->dmd_open = 1;
    d->error[DEV_DMD][0] = '\0';
    atomic_store(&d->dmd_connected, 1);
    atomic_store(&d->can_dmd_faults, dmd_sim_emulator(d->dmd_dev) != NULL || d->emu != NULL);
    sci_log_write(d->log, SCI_LOG_INFO, "dmd (%s%s): %s %s, %d×%d, firmware %s", c->dmd_backend,
                  d->emu ? " on the DLPC900 emulator" : "", d->dmd_id.model, d->dmd_id.serial, d->dmd_id.width,
                  d->dmd_id.height, d->dmd_id.firmware);
}

static void open_missing(scicapd_devices *d)
{
    d->last_try_ns = sci_clock_mono_ns();
    open_bench(d);
    open_dmd(d);
    if (d->sim)
        sim_bench_attach_dmd(d->sim, d->dmd_open ? d->dmd_dev : NULL);
    publish(d);
}

static void close_all(scicapd_devices *d)
{
    if (d->sim)
        sim_bench_attach_dmd(d->sim, NULL);
    dmd_close(d->dmd_dev);
    d->dmd_dev = NULL;
    d->dmd_open = 0;
    atomic_store(&d->dmd_connected, 0);
    atomic_store(&d->can_dmd_faults, 0);
    atomic_store(&d->can_bench_faults, 0);
    dlpc900_emu_free(d->emu); /* after the dmd that talks to it */
    d->emu = NULL;
    sim_bench_close(d->sim);
    d->sim = NULL;
    trigger_close(d->trig); /* first: a software-trigger wrapper borrows the camera */
    d->trig = NULL;
    camera_close(d->cam);
    d->cam = NULL;
    d->cam_software = 0;
}

int scicapd_devices_open(scicapd_devices **out, const scicapd_config *cfg, const sci_log *log,
                         dmd_event_fn on_event, void *user, sci_error *err)
{
    scicapd_devices *d = calloc(1, sizeof *d);
    if (!d)
        return sci_error_set(err, -ENOMEM, "devices: out of memory");
    int rc = scicapd_config_copy(&d->cfg, cfg, err);
    if (rc < 0) {
        free(d);
        return rc;
    }
    d->log = log;
    d->on_event = on_event;
    d->user = user;
    pthread_mutex_init(&d->mu, NULL);
    open_missing(d);
    *out = d;
    return 0;
}

void scicapd_devices_close(scicapd_devices *d)
{
    if (!d)
        return;
    close_all(d);
    json_decref(d->json);
    pthread_mutex_destroy(&d->mu);
    scicapd_config_free(d->cfg);
    free(d);
}

int scicapd_devices_differ(const scicapd_devices *d, const scicapd_config *cfg)
{
    return scicapd_config_devices_differ(d->cfg, cfg);
}

int scicapd_devices_reconfigure(scicapd_devices *d, const scicapd_config *cfg, sci_error *err)
{
    scicapd_config *c;
    int rc = scicapd_config_copy(&c, cfg, err);
    if (rc < 0)
        return rc;
    close_all(d);
    scicapd_config_free(d->cfg);
    d->cfg = c;
    for (int i = 0; i < DEV_COUNT; i++)
        d->error[i][0] = '\0';
    sci_log_write(d->log, SCI_LOG_NOTICE, "devices re-opened: dmd %s, camera %s, trigger %s", c->dmd_backend,
                  c->camera_backend, c->trigger_backend);
    open_missing(d);
    return 0;
}

static int all_open(const scicapd_devices *d)
{
    return d->dmd_open && (d->sim || (d->cam && d->trig));
}

int scicapd_devices_retry(scicapd_devices *d, int64_t period_ns, int force)
{
    if (all_open(d) || (!force && sci_clock_mono_ns() - d->last_try_ns < period_ns))
        return 0;
    open_missing(d);
    if (!all_open(d))
        return 0;
    sci_log_write(d->log, SCI_LOG_NOTICE, "devices: all open");
    return 1;
}

int scicapd_devices_ready(scicapd_devices *d, sci_error *err)
{
    const char *backends[DEV_COUNT] = {d->cfg->dmd_backend, d->cfg->camera_backend, d->cfg->trigger_backend};
    for (int i = 0; i < DEV_COUNT; i++)
        if (d->error[i][0])
            return sci_error_set(err, -ENODEV, "%s (%s): not connected: %s", dev_names[i], backends[i], d->error[i]);
    if (!all_open(d))
        return sci_error_set(err, -ENODEV, "devices: not open");
    return 0;
}

dmd *scicapd_devices_dmd(scicapd_devices *d)
{
    if (!d->dmd_open)
        return NULL;
    return d->sim ? sim_bench_dmd(d->sim) : d->dmd_dev;
}

camera *scicapd_devices_camera(scicapd_devices *d) { return d->sim ? sim_bench_camera(d->sim) : d->cam; }
trigger *scicapd_devices_trigger(scicapd_devices *d) { return d->sim ? sim_bench_trigger(d->sim) : d->trig; }
const dmd_identity *scicapd_devices_dmd_identity(const scicapd_devices *d) { return d->dmd_open ? &d->dmd_id : NULL; }

int64_t scicapd_devices_dmd_latency_ns(const scicapd_devices *d)
{
    if (d->sim)
        return sim_bench_get_options(d->sim)->dmd_latency_ns;
    /* a real bench: the DLPC900 starts its first pattern TRIG_IN_1 delay after the edge */
    return (int64_t)(d->cfg->dmd_trigger_delay_us ? d->cfg->dmd_trigger_delay_us : 105) * 1000;
}

int64_t scicapd_devices_readout_ns(const scicapd_devices *d)
{
    return d->sim ? sim_bench_get_options(d->sim)->readout_ns : (int64_t)d->cfg->camera_readout_us * 1000;
}

void scicapd_devices_timing_defaults(const scicapd_devices *d, dmd_timing *t)
{
    t->trigger_delay_us = d->cfg->dmd_trigger_delay_us;
    t->trigger_falling = d->cfg->dmd_trigger_falling;
}

int scicapd_devices_fault_supported(scicapd_devices *d, scicapd_fault fault)
{
    switch (fault) {
    case SCICAPD_FAULT_DMD_UNPLUG:
    case SCICAPD_FAULT_DMD_REPLUG: return atomic_load(&d->can_dmd_faults);
    case SCICAPD_FAULT_CAMERA_STALL:
    case SCICAPD_FAULT_TRIGGER_MISS: return atomic_load(&d->can_bench_faults);
    default: return 1;
    }
}

void scicapd_devices_fault_apply(scicapd_devices *d, scicapd_fault fault, long n)
{
    dlpc900_emu *emu = d->emu ? d->emu : d->dmd_open ? dmd_sim_emulator(d->dmd_dev) : NULL;
    switch (fault) {
    case SCICAPD_FAULT_DMD_UNPLUG:
        if (emu)
            dlpc900_emu_unplug_after(emu, n);
        break;
    case SCICAPD_FAULT_DMD_REPLUG:
        if (emu && !dlpc900_emu_plugged(emu))
            dlpc900_emu_replug(emu);
        break;
    case SCICAPD_FAULT_CAMERA_STALL:
        if (d->sim)
            sim_bench_camera_stall(d->sim, (int)n);
        break;
    case SCICAPD_FAULT_TRIGGER_MISS:
        if (d->sim)
            sim_bench_trigger_miss(d->sim, (int)n);
        break;
    default: break;
    }
}

static int check_sync(const scicapd_devices *d, enum sync_mode mode, sci_error *err)
{
    if (!d->cam_software || mode == SYNC_MODE_HOST_MASTER)
        return 0;
    /* dmd-master starts the DMD by dmd_start (no pulse to send the command with); camera-master needs a
     * free-running camera whose strobe starts the DMD */
    return sci_error_set(err, -EINVAL, "camera (%s) is in \"trigger\": \"software\" mode: the host starts each "
                         "exposure, so sync_mode must be host-master (got %s; for dmd-master use \"trigger\": "
                         "\"line\" wired to the DMD's trigger output, for camera-master \"free-run\")",
                         d->cfg->camera_backend, sync_mode_name(mode));
}

int scicapd_devices_prepare(scicapd_devices *d, enum sync_mode mode, sci_error *err)
{
    int rc = scicapd_devices_ready(d, err);
    if (rc < 0 || (rc = check_sync(d, mode, err)) < 0)
        return rc;
    /* the simulated camera free-runs in camera master, waits for its trigger otherwise */
    return d->sim ? sim_bench_set_free_run(d->sim, mode == SYNC_MODE_CAMERA_MASTER, err) : 0;
}

int scicapd_devices_camera_masks(const scicapd_devices *d, const sci_cube *dmd_masks, int cam_w, int cam_h,
                                 sci_cube **out, sci_error *err)
{
    int rc;
    if (dmd_masks->w == cam_w && dmd_masks->h == cam_h)
        rc = sci_cube_clone(out, dmd_masks, err); /* a mirror per pixel: the DMD masks are the sensor's */
    else if (d->sim)
        rc = sim_bench_crop(d->sim, dmd_masks, out, err); /* the simulated camera's window */
    else
        return 0;
    return rc < 0 ? rc : 1;
}

int scicapd_devices_truth(scicapd_devices *d, int n, sci_cube **out, sci_error *err)
{
    if (!d->sim)
        return 0;
    const sci_cube *t = sim_bench_truth(d->sim, n, err);
    int rc = t ? sci_cube_clone(out, t, err) : err ? err->code : -EIO;
    return rc < 0 ? rc : 1;
}

void scicapd_devices_scene_at(scicapd_devices *d, unsigned long capture)
{
    if (d->sim)
        sim_bench_set_snapshot(d->sim, capture > 0 ? capture - 1 : 0);
}

void scicapd_devices_white_target(scicapd_devices *d, int on)
{
    if (d->sim)
        sim_bench_set_target(d->sim, on ? SIM_BENCH_TARGET_WHITE : SIM_BENCH_TARGET_SCENE);
    else if (on)
        sci_log_write(d->log, SCI_LOG_NOTICE, "calibrate masks: expecting a uniform white target in front of the "
                      "camera");
}

void scicapd_devices_snapshot_meta(scicapd_devices *d, int n, json_t *meta)
{
    uint64_t sent;
    int64_t last;
    /* the software triggers the host sent, up to this frame */
    if (d->cam_software && scicapd_swtrigger_stats(d->trig, &sent, &last) == 0)
        json_object_set_new(meta, "camera_trigger", json_pack("{s:s, s:I, s:I}", "mode", "software", "sent",
                                                              (json_int_t)sent, "last_sent_ns", (json_int_t)last));
    if (!d->sim)
        return;
    json_t *times = json_array();
    for (int k = 0; k < n; k++)
        json_array_append_new(times, json_real(sim_bench_frame_time(d->sim, n, k)));
    json_object_set_new(meta, "simulated", json_pack("{s:s, s:o}", "scene", sim_bench_scene_name(d->sim),
                                                     "scene_frames", times));
}
