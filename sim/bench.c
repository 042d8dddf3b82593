/* sim/bench.c — the simulated bench's wiring and its image model (see the header). */
#include "sim/bench.h"

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

struct sim_bench {
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
    sim_bench_options opt;   /* as opened (scene and scene_path cleared: not kept) */
    sim_bench_target target;
    sci_rng rng;
    uint64_t snapshot;       /* scene time: snapshot j sees clock frames j·n … j·n + n − 1 */
    sci_cube *truth;         /* cached truth, n frames of truth_snapshot */
    uint64_t truth_snapshot;
    float *last;             /* last snapshot before counts (w×h); last_valid once one was taken */
    int last_valid;
};

/* ---- the DMD wrapper: the DMD plus the wiring of its trigger output ---- */

static int no_dmd(sci_error *err) { return sci_error_set(err, -ENODEV, "DMD: not connected"); }

/* Opened by sim_bench_open only, with the bench as backend_options: the wrapper's state is the bench. */
static int w_open(void **state, const dmd_config *cfg, sci_error *err)
{
    if (!cfg->backend_options)
        return sci_error_set(err, -ENOTSUP, "simulated bench DMD: opened by sim_bench_open only");
    *state = (void *)cfg->backend_options;
    return 0;
}
static void w_close(void *state) { (void)state; }
static int w_identify(void *state, dmd_identity *id, sci_error *err)
{
    sim_bench *b = state;
    return b->inner ? dmd_identify(b->inner, id, err) : no_dmd(err);
}

static int w_upload(void *state, const sci_cube *m, sci_error *err)
{
    sim_bench *b = state;
    if (!b->inner)
        return no_dmd(err);
    int rc = dmd_upload(b->inner, m, err);
    if (rc < 0)
        return rc;
    int w = b->scene->w, h = b->scene->h;
    if (m->w < w || m->h < h)
        return sci_error_set(err, SCI_ESHAPE, "simulated bench: masks %d×%d are smaller than the camera's %d×%d",
                             m->w, m->h, w, h);
    b->ox = (m->w - w) / 2;
    b->oy = (m->h - h) / 2;
    sci_cube *copy;
    if ((rc = sci_cube_new(&copy, w, h, m->n, err)) < 0)
        return rc;
    /* what the mirrors the camera sees do */
    for (int k = 0; k < m->n; k++)
        for (int y = 0; y < h; y++) {
            const float *src = sci_cube_frame(m, k) + (size_t)(y + b->oy) * m->w + b->ox;
            float *dst = sci_cube_frame(copy, k) + (size_t)y * w;
            for (int x = 0; x < w; x++)
                dst[x] = src[x] >= 0.5f ? 1.0f : 0.0f;
        }
    sci_cube_free(b->masks);
    b->masks = copy;
    b->tl_valid = 0;
    return 0;
}

static int w_set_timing(void *state, const dmd_timing *t, sci_error *err)
{
    sim_bench *b = state;
    if (!b->inner)
        return no_dmd(err);
    int rc = dmd_set_timing(b->inner, t, err);
    if (rc < 0)
        return rc;
    b->external = t->trigger == DMD_TRIGGER_EXTERNAL;
    if (b->masks && (rc = capture_timeline_from_dmd(t, b->masks->n, b->tl, err)) < 0)
        return rc;
    b->tl_valid = b->masks != NULL;
    return 0;
}

static void play(sim_bench *b, int64_t t0)
{
    b->seq_start_ns = t0;
    trigger_sim_play(b->ts, b->tl, t0, 1000, 20);
}

static int w_start(void *state, sci_error *err)
{
    sim_bench *b = state;
    if (!b->inner)
        return no_dmd(err);
    /* A DMD starts when the command reaches it, not when its reply comes back: the clock is read before the
     * call, so the (emulated) USB round trip, slow under ASan or load, is not counted as latency. */
    int64_t issued = sci_clock_mono_ns();
    int rc = dmd_start(b->inner, err);
    if (rc < 0)
        return rc;
    b->seq_start_ns = 0;
    if (b->external) {
        b->armed = 1;
        b->armed_ns = sci_clock_mono_ns();
    } else if (b->tl_valid) {
        /* DMD master: the sequence runs now; the first pattern's trigger output starts the camera */
        int64_t t0 = issued + b->opt.dmd_latency_ns;
        play(b, t0);
        camera_sim_trigger(b->cs, t0);
    }
    return 0;
}

static int w_stop(void *state, sci_error *err)
{
    sim_bench *b = state;
    b->armed = 0;
    return b->inner ? dmd_stop(b->inner, err) : 0;
}
static int w_status(void *state, dmd_status *st, sci_error *err)
{
    sim_bench *b = state;
    if (b->inner)
        return dmd_status_get(b->inner, st, err);
    memset(st, 0, sizeof *st);
    return 0;
}
static int w_poll(void *state, int timeout_ms, sci_error *err)
{
    sim_bench *b = state;
    return b->inner ? dmd_poll(b->inner, timeout_ms, err) : 0;
}

static const dmd_ops bench_dmd_ops = {
    .name = "sim", .open = w_open, .close = w_close, .identify = w_identify, .upload = w_upload,
    .set_timing = w_set_timing, .start = w_start, .stop = w_stop, .status = w_status, .poll = w_poll,
};

/* ---- trigger output and camera strobe ---- */

static void on_output(void *arg, int64_t t, uint32_t width_us)
{
    sim_bench *b = arg;
    (void)width_us;
    camera_sim_trigger(b->cs, t);
    if (b->armed && b->tl_valid) {
        dmd_status st;
        sci_error e = {0};
        /* a DMD that lost power (unplugged) plays nothing */
        if (b->inner && dmd_status_get(b->inner, &st, &e) == 0 && st.connected && st.running)
            play(b, t + b->opt.dmd_latency_ns);
        b->armed = 0;
    }
}

static void on_strobe(void *arg, const camera_sim_exposure *e)
{
    sim_bench *b = arg;
    if (b->free_run && b->armed && b->tl_valid && e->start_ns >= b->armed_ns) {
        /* camera master: the strobe is wired to the DMD's trigger input */
        dmd_status st;
        sci_error err = {0};
        if (b->inner && dmd_status_get(b->inner, &st, &err) == 0 && st.connected && st.running)
            play(b, e->start_ns + b->opt.dmd_latency_ns);
        b->armed = 0;
    }
    trigger_sim_inject(b->ts, TRIGGER_ROLE_STROBE, e->start_ns, 1);
    trigger_sim_inject(b->ts, TRIGGER_ROLE_STROBE, e->end_ns, 0);
}

/* ---- the image ---- */

/* The scene's length in frames as the bench's clock plays it (the header says why). */
static uint64_t loop_frames(const sim_scene *sc)
{
    uint64_t len = (uint64_t)sc->snapshots * (uint64_t)sc->n;
    return sc->kind == SIM_SCENE_VIDEO2D && len < SIM_BENCH_LOOP_FRAMES ? SIM_BENCH_LOOP_FRAMES : len;
}

double sim_bench_frame_time(const sim_bench *b, int n, int k)
{
    uint64_t len = loop_frames(b->scene), period = len > 1 ? 2 * (len - 1) : 1;
    uint64_t u = (b->snapshot * (uint64_t)n + (uint64_t)k) % period;
    return (double)(u < len ? u : period - u);
}

static int render_truth(sim_bench *b, int n, sci_error *err)
{
    if (b->truth && b->truth->n == n && b->truth_snapshot == b->snapshot)
        return 0;
    sci_cube *t;
    int rc = sci_cube_new(&t, b->scene->w, b->scene->h, n, err);
    if (rc < 0)
        return rc;
    for (int k = 0; k < n; k++)
        if ((rc = sim_render_frame(b->scene, sim_bench_frame_time(b, n, k), sci_cube_frame(t, k))) < 0) {
            sci_cube_free(t);
            return sci_error_set(err, rc, "simulator: rendering scene time %g of %s failed",
                                 sim_bench_frame_time(b, n, k), b->scene->name);
        }
    sci_cube_free(b->truth);
    b->truth = t;
    b->truth_snapshot = b->snapshot;
    return 0;
}

const sci_cube *sim_bench_truth(sim_bench *b, int n, sci_error *err)
{
    return render_truth(b, n, err) < 0 ? NULL : b->truth;
}

static int source(void *arg, const camera_sim_exposure *e, uint16_t *out, uint32_t w, uint32_t h, int bits,
                  sci_error *err)
{
    sim_bench *b = arg;
    size_t np = (size_t)w * h;
    double maxv = (double)((1u << bits) - 1);
    double *acc = calloc(np, sizeof *acc);
    if (!acc)
        return sci_error_set(err, -ENOMEM, "simulated camera: out of memory");
    const sci_cube *m = b->masks;
    if (m && b->tl_valid && b->seq_start_ns && (uint32_t)m->w == w && (uint32_t)m->h == h) {
        if (b->target == SIM_BENCH_TARGET_SCENE && render_truth(b, m->n, err) < 0) {
            free(acc);
            return err ? err->code : -EIO;
        }
        for (int k = 0; k < m->n; k++) {
            int64_t s = b->seq_start_ns + (sync_timeline_pattern_start_ns(b->tl, k) - b->tl->start_ns);
            int64_t d = (int64_t)b->tl->exposure_us[k] * 1000;
            int64_t lo = s > e->start_ns ? s : e->start_ns, hi = s + d < e->end_ns ? s + d : e->end_ns;
            if (hi <= lo || d <= 0)
                continue;
            double wk = (double)(hi - lo) / (double)d;
            const float *mk = sci_cube_frame(m, k);
            const float *xk = b->target == SIM_BENCH_TARGET_SCENE ? sci_cube_frame(b->truth, k) : NULL;
            for (size_t i = 0; i < np; i++)
                acc[i] += wk * mk[i] * (xk ? xk[i] : 1.0);
        }
    }
    int keep = (int)w == b->scene->w && (int)h == b->scene->h;
    for (size_t i = 0; i < np; i++) {
        if (keep)
            b->last[i] = (float)acc[i];
        double v = b->opt.dark_counts + b->opt.counts_per_unit * acc[i];
        if (b->opt.read_noise > 0)
            v += b->opt.read_noise * sci_rng_normal(&b->rng);
        v = v < 0 ? 0 : v > maxv ? maxv : v;
        out[i] = (uint16_t)lrint(v);
    }
    free(acc);
    b->last_valid |= keep;
    /* One sequence per exposure: the one it lit is spent. An older frame still queued, rendered after a later
     * strobe started the sequence, must not clear it. */
    if (b->seq_start_ns && e->end_ns > b->seq_start_ns)
        b->seq_start_ns = 0;
    return 0;
}

/* ---- life ---- */

/* The simulated camera, streaming: external trigger (host and DMD master) or free run at 30 frames/s (camera
 * master). A sensor changes this through its trigger-profile controls, set at open: so does the simulator. */
static int open_camera(sim_bench *b, int free_run, sci_error *err)
{
    camera_sim_options copt = {.card = "scicap simulated camera", .readout_ns = b->opt.readout_ns, .source = source,
                               .source_arg = b, .strobe = on_strobe, .strobe_arg = b};
    camera_config cc = camera_config_default();
    cc.width = (uint32_t)b->scene->w;
    cc.height = (uint32_t)b->scene->h;
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
    camera_close(b->cam);
    b->cam = cam;
    b->cs = camera_sim_from(cam);
    b->free_run = free_run;
    b->armed = 0;
    return 0;
}

int sim_bench_set_free_run(sim_bench *b, int free_run, sci_error *err)
{
    return (free_run != 0) == b->free_run ? 0 : open_camera(b, free_run != 0, err);
}

int sim_bench_snapshot(sim_bench *b, const sci_cube *masks, uint32_t pattern_us, sci_cube *meas, sci_error *err)
{
    if (!b->inner)
        return no_dmd(err);
    int w = b->scene->w, h = b->scene->h;
    if (meas->w != w || meas->h != h || meas->n != 1)
        return sci_error_set(err, SCI_ESHAPE, "simulated bench: measurement %d×%d×%d, the camera is %d×%d×1",
                             meas->w, meas->h, meas->n, w, h);
    dmd_timing t = {.exposure_us = pattern_us, .dark_us = 0, .trigger = DMD_TRIGGER_EXTERNAL, .passes = 1};
    uint32_t e = (uint32_t)((b->opt.dmd_latency_ns + 999) / 1000) + (uint32_t)masks->n * pattern_us;
    int64_t edge;
    camera_frame fr = {0};
    sci_error e2 = {0};
    int rc;
    if ((rc = sim_bench_set_free_run(b, 0, err)) < 0 || (rc = camera_set_exposure_us(b->cam, &e, err)) < 0 ||
        (rc = dmd_upload(b->outer, masks, err)) < 0 || (rc = dmd_set_timing(b->outer, &t, err)) < 0 ||
        (rc = dmd_start(b->outer, err)) < 0)
        return rc;
    if ((rc = trigger_pulse(b->trig, 10, &edge, err)) == 0 &&
        (rc = camera_wait_frame(b->cam, (int64_t)e * 1000 + 1000000000, &fr, err)) == 0) {
        for (int i = 0; i < w * h; i++)
            meas->data[i] = (float)((fr.data[i] - b->opt.dark_counts) / b->opt.counts_per_unit);
        camera_frame_release(&fr);
    }
    dmd_stop(b->outer, &e2);
    return rc;
}

sim_bench_options sim_bench_options_default(void)
{
    return (sim_bench_options){.seed = 1, .dmd_latency_ns = 300000, .trigger_latency_ns = 20000,
                               .trigger_jitter_ns = 3000, .readout_ns = 100000, .counts_per_unit = 6000,
                               .dark_counts = 200, .read_noise = 2};
}

int sim_bench_open(sim_bench **out, const sim_bench_options *opt, sci_error *err)
{
    sim_bench *b = calloc(1, sizeof *b);
    int rc;
    if (!b || !(b->tl = calloc(1, sizeof *b->tl))) {
        free(b);
        sim_scene_free(opt->scene);
        return sci_error_set(err, -ENOMEM, "simulated bench: out of memory");
    }
    b->opt = *opt;
    b->opt.scene = NULL;
    b->opt.scene_path = NULL;
    if (opt->scene)
        b->scene = opt->scene;
    else if ((rc = opt->scene_path && opt->scene_path[0] ? sim_scene_load_file(&b->scene, opt->scene_path, err)
                                                         : sim_default_scene_load(&b->scene, err)) < 0)
        goto fail;
    if (!(b->last = malloc((size_t)b->scene->w * b->scene->h * sizeof *b->last))) {
        rc = sci_error_set(err, -ENOMEM, "simulated bench: out of memory for a %d×%d scene", b->scene->w,
                           b->scene->h);
        goto fail;
    }
    sci_rng_seed(&b->rng, opt->seed, 0x5c1cbe4c);

    dmd_config wc = dmd_config_default();
    wc.backend_options = b;
    if ((rc = dmd_open(&b->outer, &bench_dmd_ops, &wc, err)) < 0)
        goto fail;

    if ((rc = open_camera(b, 0, err)) < 0)
        goto fail;

    trigger_sim_options topt = {.seed = opt->seed, .latency_ns = opt->trigger_latency_ns,
                                .jitter_ns = opt->trigger_jitter_ns, .on_output = on_output, .on_output_arg = b};
    trigger_config tc = trigger_config_default();
    tc.chip = "sim-gpiochip0";
    tc.consumer = "scicap";
    tc.output.offset = 17;
    tc.inputs[TRIGGER_ROLE_DMD].offset = 22;
    tc.inputs[TRIGGER_ROLE_STROBE].offset = 27;
    tc.backend_options = &topt;
    if ((rc = trigger_open(&b->trig, &trigger_sim_ops, &tc, err)) < 0)
        goto fail;
    b->ts = trigger_sim_from(b->trig);
    *out = b;
    return 0;
fail:
    sim_bench_close(b);
    return rc;
}

void sim_bench_close(sim_bench *b)
{
    if (!b)
        return;
    trigger_close(b->trig);
    camera_close(b->cam);
    dmd_close(b->outer);
    sim_scene_free(b->scene);
    sci_cube_free(b->masks);
    sci_cube_free(b->truth);
    free(b->last);
    free(b->tl);
    free(b);
}

void sim_bench_attach_dmd(sim_bench *b, dmd *inner)
{
    b->inner = inner;
    b->armed = 0;
    b->tl_valid = 0;
    sci_cube_free(b->masks);
    b->masks = NULL;
}

void sim_bench_size(const sim_bench *b, int *w, int *h)
{
    *w = b->scene->w;
    *h = b->scene->h;
}

int sim_bench_crop(const sim_bench *b, const sci_cube *dmd_masks, sci_cube **out, sci_error *err)
{
    int w = b->scene->w, h = b->scene->h;
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

dmd *sim_bench_dmd(sim_bench *b) { return b->outer; }
camera *sim_bench_camera(sim_bench *b) { return b->cam; }
trigger *sim_bench_trigger(sim_bench *b) { return b->trig; }
const sim_bench_options *sim_bench_get_options(const sim_bench *b) { return &b->opt; }
const float *sim_bench_last(const sim_bench *b) { return b->last_valid ? b->last : NULL; }
void sim_bench_set_target(sim_bench *b, sim_bench_target t) { b->target = t; }
void sim_bench_set_snapshot(sim_bench *b, uint64_t snapshot) { b->snapshot = snapshot; }
const char *sim_bench_scene_name(const sim_bench *b) { return b->scene->name; }

void sim_bench_camera_stall(sim_bench *b, int n) { camera_sim_fault(b->cs, CAMERA_SIM_FAULT_STALL, n); }
void sim_bench_trigger_miss(sim_bench *b, int n) { trigger_sim_miss_next(b->ts, n); }
