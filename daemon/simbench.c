/* daemon/simbench.c — the simulated bench's wiring and its image model (see the header). */
#include "daemon/simbench.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/rng.h"
#include "drivers/capture.h"
#include "sim/camera_sim.h"
#include "sim/default_scene.h"
#include "sim/simulate.h"
#include "sim/trigger_sim.h"

struct scicapd_simbench {
    sim_scene *scene;
    dmd *inner;              /* the DMD, any backend (borrowed; NULL while it is not open) */
    int ox, oy;              /* the camera sees mirrors [ox, ox + w) × [oy, oy + h) */
    dmd *outer;              /* wrapper handed to the acquisition code (owned) */
    camera *cam;
    trigger *trig;
    camera_sim *cs;
    trigger_sim *ts;
    sci_cube *masks;         /* as uploaded (0/1), w×h×N */
    sync_timeline *tl;       /* as set by set_timing */
    int tl_valid;
    int external;            /* DMD waits for the trigger input (host master) */
    int armed;               /* started and waiting for a trigger (host or camera master) */
    int64_t armed_ns;        /* when it was armed: only an exposure starting later may start it */
    int free_run;            /* camera free-running, its strobe starts the DMD (camera master) */
    int64_t seq_start_ns;    /* when pattern 0 began (0: not playing) */
    int64_t latency_ns;
    scicapd_target target;
    double counts_per_unit, dark_counts, read_noise;
    sci_rng rng;
    sci_cube *truth;         /* cached truth, n frames */
};

/* ---- the DMD wrapper: the DMD plus the wiring of its trigger output ---- */

static int no_dmd(sci_error *err) { return sci_error_set(err, -ENODEV, "DMD: not connected"); }

/* Opened by scicapd_simbench_open only, with the bench as backend_options: the wrapper's state is the bench. */
static int w_open(void **state, const dmd_config *cfg, sci_error *err)
{
    if (!cfg->backend_options)
        return sci_error_set(err, -ENOTSUP, "simbench DMD: opened by scicapd_simbench_open only");
    *state = (void *)cfg->backend_options;
    return 0;
}
static void w_close(void *state) { (void)state; }
static int w_identify(void *state, dmd_identity *id, sci_error *err)
{
    scicapd_simbench *sb = state;
    return sb->inner ? dmd_identify(sb->inner, id, err) : no_dmd(err);
}

static int w_upload(void *state, const sci_cube *m, sci_error *err)
{
    scicapd_simbench *sb = state;
    if (!sb->inner)
        return no_dmd(err);
    int rc = dmd_upload(sb->inner, m, err);
    if (rc < 0)
        return rc;
    int w = sb->scene->w, h = sb->scene->h;
    if (m->w < w || m->h < h)
        return sci_error_set(err, SCI_ESHAPE, "simulated bench: masks %d×%d are smaller than the camera's %d×%d",
                             m->w, m->h, w, h);
    sb->ox = (m->w - w) / 2;
    sb->oy = (m->h - h) / 2;
    sci_cube *copy;
    if ((rc = sci_cube_new(&copy, w, h, m->n, err)) < 0)
        return rc;
    /* what the mirrors the camera sees do */
    for (int k = 0; k < m->n; k++)
        for (int y = 0; y < h; y++) {
            const float *src = sci_cube_frame(m, k) + (size_t)(y + sb->oy) * m->w + sb->ox;
            float *dst = sci_cube_frame(copy, k) + (size_t)y * w;
            for (int x = 0; x < w; x++)
                dst[x] = src[x] >= 0.5f ? 1.0f : 0.0f;
        }
    sci_cube_free(sb->masks);
    sb->masks = copy;
    sb->tl_valid = 0;
    return 0;
}

static int w_set_timing(void *state, const dmd_timing *t, sci_error *err)
{
    scicapd_simbench *sb = state;
    if (!sb->inner)
        return no_dmd(err);
    int rc = dmd_set_timing(sb->inner, t, err);
    if (rc < 0)
        return rc;
    sb->external = t->trigger == DMD_TRIGGER_EXTERNAL;
    if (sb->masks && (rc = capture_timeline_from_dmd(t, sb->masks->n, sb->tl, err)) < 0)
        return rc;
    sb->tl_valid = sb->masks != NULL;
    return 0;
}

static void play(scicapd_simbench *sb, int64_t t0)
{
    sb->seq_start_ns = t0;
    trigger_sim_play(sb->ts, sb->tl, t0, 1000, 20);
}

static int w_start(void *state, sci_error *err)
{
    scicapd_simbench *sb = state;
    if (!sb->inner)
        return no_dmd(err);
    int rc = dmd_start(sb->inner, err);
    if (rc < 0)
        return rc;
    sb->seq_start_ns = 0;
    if (sb->external) {
        sb->armed = 1;
        sb->armed_ns = sci_clock_mono_ns();
    } else if (sb->tl_valid) {
        /* DMD master: the sequence runs now; the first pattern's trigger output starts the camera */
        int64_t t0 = sci_clock_mono_ns() + sb->latency_ns;
        play(sb, t0);
        camera_sim_trigger(sb->cs, t0);
    }
    return 0;
}

static int w_stop(void *state, sci_error *err)
{
    scicapd_simbench *sb = state;
    sb->armed = 0;
    return sb->inner ? dmd_stop(sb->inner, err) : 0;
}
static int w_status(void *state, dmd_status *st, sci_error *err)
{
    scicapd_simbench *sb = state;
    if (sb->inner)
        return dmd_status_get(sb->inner, st, err);
    memset(st, 0, sizeof *st);
    return 0;
}
static int w_poll(void *state, int timeout_ms, sci_error *err)
{
    scicapd_simbench *sb = state;
    return sb->inner ? dmd_poll(sb->inner, timeout_ms, err) : 0;
}

static const dmd_ops simbench_dmd_ops = {
    .name = "sim", .open = w_open, .close = w_close, .identify = w_identify, .upload = w_upload,
    .set_timing = w_set_timing, .start = w_start, .stop = w_stop, .status = w_status, .poll = w_poll,
};

/* ---- trigger output and camera strobe ---- */

static void on_output(void *arg, int64_t t, uint32_t width_us)
{
    scicapd_simbench *sb = arg;
    (void)width_us;
    camera_sim_trigger(sb->cs, t);
    if (sb->armed && sb->tl_valid) {
        dmd_status st;
        sci_error e = {0};
        /* a DMD that lost power (unplugged) plays nothing */
        if (sb->inner && dmd_status_get(sb->inner, &st, &e) == 0 && st.connected && st.running)
            play(sb, t + sb->latency_ns);
        sb->armed = 0;
    }
}

static void on_strobe(void *arg, const camera_sim_exposure *e)
{
    scicapd_simbench *sb = arg;
    if (sb->free_run && sb->armed && sb->tl_valid && e->start_ns >= sb->armed_ns) {
        /* camera master: the strobe is wired to the DMD's trigger input */
        dmd_status st;
        sci_error err = {0};
        if (sb->inner && dmd_status_get(sb->inner, &st, &err) == 0 && st.connected && st.running)
            play(sb, e->start_ns + sb->latency_ns);
        sb->armed = 0;
    }
    trigger_sim_inject(sb->ts, TRIGGER_ROLE_STROBE, e->start_ns, 1);
    trigger_sim_inject(sb->ts, TRIGGER_ROLE_STROBE, e->end_ns, 0);
}

/* ---- the image ---- */

static int render_truth(scicapd_simbench *sb, int n, sci_error *err)
{
    if (sb->truth && sb->truth->n == n)
        return 0;
    sci_cube *t;
    int rc = sci_cube_new(&t, sb->scene->w, sb->scene->h, n, err);
    if (rc < 0)
        return rc;
    for (int k = 0; k < n; k++)
        if ((rc = sim_render_frame(sb->scene, k, sci_cube_frame(t, k))) < 0) {
            sci_cube_free(t);
            return sci_error_set(err, rc, "simulator: rendering frame %d of %s failed", k, sb->scene->name);
        }
    sci_cube_free(sb->truth);
    sb->truth = t;
    return 0;
}

const sci_cube *scicapd_simbench_truth(scicapd_simbench *sb, int n, sci_error *err)
{
    return render_truth(sb, n, err) < 0 ? NULL : sb->truth;
}

static int source(void *arg, const camera_sim_exposure *e, uint16_t *out, uint32_t w, uint32_t h, int bits,
                  sci_error *err)
{
    scicapd_simbench *sb = arg;
    size_t np = (size_t)w * h;
    double maxv = (double)((1u << bits) - 1);
    double *acc = calloc(np, sizeof *acc);
    if (!acc)
        return sci_error_set(err, -ENOMEM, "simulated camera: out of memory");
    const sci_cube *m = sb->masks;
    if (m && sb->tl_valid && sb->seq_start_ns && (uint32_t)m->w == w && (uint32_t)m->h == h) {
        if (sb->target == SCICAPD_TARGET_SCENE && render_truth(sb, m->n, err) < 0) {
            free(acc);
            return err ? err->code : -EIO;
        }
        for (int k = 0; k < m->n; k++) {
            int64_t s = sb->seq_start_ns + (sync_timeline_pattern_start_ns(sb->tl, k) - sb->tl->start_ns);
            int64_t d = (int64_t)sb->tl->exposure_us[k] * 1000;
            int64_t a = s > e->start_ns ? s : e->start_ns, b = s + d < e->end_ns ? s + d : e->end_ns;
            if (b <= a || d <= 0)
                continue;
            double wk = (double)(b - a) / (double)d;
            const float *mk = sci_cube_frame(m, k);
            const float *xk = sb->target == SCICAPD_TARGET_SCENE ? sci_cube_frame(sb->truth, k) : NULL;
            for (size_t i = 0; i < np; i++)
                acc[i] += wk * mk[i] * (xk ? xk[i] : 1.0);
        }
    }
    for (size_t i = 0; i < np; i++) {
        double v = sb->dark_counts + sb->counts_per_unit * acc[i];
        if (sb->read_noise > 0)
            v += sb->read_noise * sci_rng_normal(&sb->rng);
        v = v < 0 ? 0 : v > maxv ? maxv : v;
        out[i] = (uint16_t)lrint(v);
    }
    free(acc);
    sb->seq_start_ns = 0; /* one sequence per exposure */
    return 0;
}

/* ---- life ---- */

/* The simulated camera, streaming: external trigger (host and DMD master) or free run at 30 frames/s (camera
 * master). A sensor changes this through its trigger-profile controls, set at open: so does the simulator. */
static int open_camera(scicapd_simbench *sb, int free_run, sci_error *err)
{
    camera_sim_options copt = {.card = "scicap simulated camera", .readout_ns = 100000, .source = source,
                               .source_arg = sb, .strobe = on_strobe, .strobe_arg = sb};
    camera_config cc = camera_config_default();
    cc.width = (uint32_t)sb->scene->w;
    cc.height = (uint32_t)sb->scene->h;
    cc.pixfmt = PIXFMT_Y16;
    cc.exposure_us = 10000;
    cc.interval_num = 1;
    cc.interval_den = 30;
    cc.trigger_profile_name = free_run ? "sim-free-run" : "sim-external";
    cc.trigger_profile[0] = (camera_control){.name = "trigger_mode", .value = free_run ? 0 : 1};
    cc.trigger_profile_count = 1;
    cc.backend_options = &copt;
    camera *cam;
    int rc = camera_open(&cam, &camera_sim_ops, &cc, err);
    if (rc < 0)
        return rc;
    if ((rc = camera_start(cam, err)) < 0) {
        camera_close(cam);
        return rc;
    }
    camera_close(sb->cam);
    sb->cam = cam;
    sb->cs = camera_sim_from(cam);
    sb->free_run = free_run;
    sb->armed = 0;
    return 0;
}

int scicapd_simbench_set_free_run(scicapd_simbench *sb, int free_run, sci_error *err)
{
    return (free_run != 0) == sb->free_run ? 0 : open_camera(sb, free_run != 0, err);
}

int scicapd_simbench_open(scicapd_simbench **out, const scicapd_config *cfg, sci_error *err)
{
    scicapd_simbench *sb = calloc(1, sizeof *sb);
    int rc;
    if (!sb || !(sb->tl = calloc(1, sizeof *sb->tl))) {
        free(sb);
        return sci_error_set(err, -ENOMEM, "simulated bench: out of memory");
    }
    rc = cfg->scene_path[0] ? sim_scene_load_file(&sb->scene, cfg->scene_path, err)
                            : sim_default_scene_load(&sb->scene, err);
    if (rc < 0)
        goto fail;
    sb->latency_ns = (int64_t)cfg->sim_dmd_latency_us * 1000;
    sb->counts_per_unit = cfg->sim_counts_per_unit;
    sb->dark_counts = cfg->sim_dark_counts;
    sb->read_noise = cfg->sim_read_noise;
    sci_rng_seed(&sb->rng, cfg->sim_seed, 0x5c1cbe4c);

    dmd_config wc = dmd_config_default();
    wc.backend_options = sb;
    if ((rc = dmd_open(&sb->outer, &simbench_dmd_ops, &wc, err)) < 0)
        goto fail;

    if ((rc = open_camera(sb, 0, err)) < 0)
        goto fail;

    trigger_sim_options topt = {.seed = cfg->sim_seed, .latency_ns = 20000, .jitter_ns = 3000,
                                .on_output = on_output, .on_output_arg = sb};
    trigger_config tc = trigger_config_default();
    tc.chip = "sim-gpiochip0";
    tc.consumer = "scicapd";
    tc.output.offset = 17;
    tc.inputs[TRIGGER_ROLE_DMD].offset = 22;
    tc.inputs[TRIGGER_ROLE_STROBE].offset = 27;
    tc.backend_options = &topt;
    if ((rc = trigger_open(&sb->trig, &trigger_sim_ops, &tc, err)) < 0)
        goto fail;
    sb->ts = trigger_sim_from(sb->trig);
    *out = sb;
    return 0;
fail:
    scicapd_simbench_close(sb);
    return rc;
}

void scicapd_simbench_close(scicapd_simbench *sb)
{
    if (!sb)
        return;
    trigger_close(sb->trig);
    camera_close(sb->cam);
    dmd_close(sb->outer);
    sim_scene_free(sb->scene);
    sci_cube_free(sb->masks);
    sci_cube_free(sb->truth);
    free(sb->tl);
    free(sb);
}

void scicapd_simbench_attach_dmd(scicapd_simbench *sb, dmd *inner)
{
    sb->inner = inner;
    sb->armed = 0;
    sb->tl_valid = 0;
    sci_cube_free(sb->masks);
    sb->masks = NULL;
}

void scicapd_simbench_size(const scicapd_simbench *sb, int *w, int *h)
{
    *w = sb->scene->w;
    *h = sb->scene->h;
}

int scicapd_simbench_crop(const scicapd_simbench *sb, const sci_cube *dmd_masks, sci_cube **out, sci_error *err)
{
    int w = sb->scene->w, h = sb->scene->h;
    if (dmd_masks->w < w || dmd_masks->h < h)
        return sci_error_set(err, SCI_ESHAPE, "simulated bench: masks %d×%d are smaller than the camera's %d×%d",
                             dmd_masks->w, dmd_masks->h, w, h);
    int ox = (dmd_masks->w - w) / 2, oy = (dmd_masks->h - h) / 2;
    int rc = sci_cube_new(out, w, h, dmd_masks->n, err);
    if (rc < 0)
        return rc;
    for (int k = 0; k < dmd_masks->n; k++)
        for (int y = 0; y < h; y++)
            memcpy(sci_cube_frame(*out, k) + (size_t)y * w,
                   sci_cube_frame(dmd_masks, k) + (size_t)(y + oy) * dmd_masks->w + ox, (size_t)w * sizeof(float));
    return 0;
}

dmd *scicapd_simbench_dmd(scicapd_simbench *sb) { return sb->outer; }
camera *scicapd_simbench_camera(scicapd_simbench *sb) { return sb->cam; }
trigger *scicapd_simbench_trigger(scicapd_simbench *sb) { return sb->trig; }
int64_t scicapd_simbench_dmd_latency_ns(const scicapd_simbench *sb) { return sb->latency_ns; }
void scicapd_simbench_set_target(scicapd_simbench *sb, scicapd_target t) { sb->target = t; }
const char *scicapd_simbench_scene_name(const scicapd_simbench *sb) { return sb->scene->name; }

void scicapd_simbench_camera_stall(scicapd_simbench *sb, int n) { camera_sim_fault(sb->cs, CAMERA_SIM_FAULT_STALL, n); }
void scicapd_simbench_trigger_miss(scicapd_simbench *sb, int n) { trigger_sim_miss_next(sb->ts, n); }
