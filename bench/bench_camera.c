/* Sustained frames per second and CPU time per frame through the capture path (camera_wait_frame: wire buffer →
 * unpack → 16-bit frame, sequence accounting) on the simulated camera, 1920×1080, for each wire format; Y16 is the
 * headline figure. Two runs per format:
 *   unpaced — the sim always has a frame ready, so the rate is what the capture path itself can sustain;
 *   paced   — the sim free-runs at 120 fps; the test is that it keeps up (no frames lost) and what it costs.
 * Then snapshots per second through capture_snapshot_take (host master, 1 ms exposure, 4 patterns).
 * Writes bench/results/camera.md. Timings on a shared 2-core machine are noisy. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/runtime_env.h"
#include "drivers/capture.h"
#include "sim/camera_sim.h"
#include "sim/trigger_sim.h"

typedef struct result {
    const char *fmt;
    const char *mode;
    int frames;
    double fps, cpu_us, lost;
} result;

static int run_stream(enum pixfmt f, int unpaced, double seconds, result *out)
{
    sci_error err = {0};
    camera_sim_options opt = {.unpaced = unpaced};
    camera_config cfg = camera_config_default();
    cfg.width = 1920;
    cfg.height = 1080;
    cfg.pixfmt = f;
    cfg.exposure_us = 1000;
    cfg.interval_num = 1;
    cfg.interval_den = 120;
    cfg.buffer_count = 4;
    cfg.backend_options = &opt;
    camera *cam;
    if (camera_open(&cam, &camera_sim_ops, &cfg, &err) < 0 || camera_start(cam, &err) < 0) {
        fprintf(stderr, "bench_camera: %s\n", err.msg);
        return -1;
    }
    camera_frame fr = {0};
    camera_wait_frame(cam, 1000000000, &fr, &err); /* warm-up: allocation, template */
    int64_t t0 = sci_clock_mono_ns(), c0 = sci_clock_cpu_ns();
    int n = 0;
    uint64_t checksum = 0;
    while (sci_clock_mono_ns() - t0 < (int64_t)(seconds * 1e9)) {
        if (camera_wait_frame(cam, 1000000000, &fr, &err) < 0) {
            fprintf(stderr, "bench_camera: %s\n", err.msg);
            break;
        }
        checksum += fr.data[(size_t)n % (1920 * 1080)];
        n++;
    }
    int64_t t1 = sci_clock_mono_ns(), c1 = sci_clock_cpu_ns();
    out->fmt = pixfmt_name(f);
    out->mode = unpaced ? "unpaced" : "paced 120 fps";
    out->frames = n;
    out->fps = n / sci_clock_s(t0, t1);
    out->cpu_us = (double)(c1 - c0) / n * 1e-3;
    out->lost = (double)fr.lost_total;
    printf("%-5s %-14s %6d frames  %8.1f fps  %8.1f us CPU/frame  lost %llu  (checksum %llu)\n", out->fmt, out->mode, n,
           out->fps, out->cpu_us, (unsigned long long)fr.lost_total, (unsigned long long)checksum);
    camera_frame_release(&fr);
    camera_close(cam);
    return 0;
}

typedef struct wiring {
    camera_sim *cs;
    trigger_sim *ts;
    sync_timeline tl;
} wiring;

static void on_output(void *arg, int64_t t, uint32_t w)
{
    wiring *wr = arg;
    (void)w;
    camera_sim_trigger(wr->cs, t);
    trigger_sim_play(wr->ts, &wr->tl, t + 50000, 1000, 20);
}

static void on_strobe(void *arg, const camera_sim_exposure *e)
{
    wiring *wr = arg;
    trigger_sim_inject(wr->ts, TRIGGER_ROLE_STROBE, e->start_ns, 1);
    trigger_sim_inject(wr->ts, TRIGGER_ROLE_STROBE, e->end_ns, 0);
}

static int run_snapshots(double seconds, double *per_s, double *cpu_us, int *broken, int *count)
{
    sci_error err = {0};
    wiring wr;
    memset(&wr, 0, sizeof wr);
    sync_timeline_uniform(&wr.tl, 0, 4, 200, 10, NULL);
    camera_sim_options copt = {.strobe = on_strobe, .strobe_arg = &wr};
    camera_config cc = camera_config_default();
    cc.width = 1920;
    cc.height = 1080;
    cc.pixfmt = PIXFMT_Y16;
    cc.exposure_us = 1000;
    cc.trigger_profile[0] = (camera_control){.name = "trigger_mode", .value = 1};
    cc.trigger_profile_count = 1;
    cc.backend_options = &copt;
    trigger_sim_options topt = {.seed = 1, .latency_ns = 10000, .jitter_ns = 2000, .on_output = on_output,
                                .on_output_arg = &wr};
    trigger_config tc = trigger_config_default();
    tc.output.offset = 0;
    tc.inputs[TRIGGER_ROLE_DMD].offset = 1;
    tc.inputs[TRIGGER_ROLE_STROBE].offset = 2;
    tc.backend_options = &topt;
    camera *cam;
    trigger *trig;
    if (camera_open(&cam, &camera_sim_ops, &cc, &err) < 0 || trigger_open(&trig, &trigger_sim_ops, &tc, &err) < 0 ||
        camera_start(cam, &err) < 0) {
        fprintf(stderr, "bench_camera: %s\n", err.msg);
        return -1;
    }
    wr.cs = camera_sim_from(cam);
    wr.ts = trigger_sim_from(trig);
    capture_params p = capture_params_default();
    p.timeline = &wr.tl;
    p.dmd_latency_ns = 50000;
    p.settle_ns = 100000;
    capture_snapshot *snap = calloc(1, sizeof *snap);
    int n = 0;
    *broken = 0;
    int64_t t0 = sci_clock_mono_ns(), c0 = sci_clock_cpu_ns();
    while (sci_clock_mono_ns() - t0 < (int64_t)(seconds * 1e9)) {
        if (capture_snapshot_take(cam, trig, &p, snap, &err) < 0) {
            fprintf(stderr, "bench_camera: %s\n", err.msg);
            break;
        }
        *broken += snap->report.broken;
        n++;
    }
    int64_t t1 = sci_clock_mono_ns(), c1 = sci_clock_cpu_ns();
    *per_s = n / sci_clock_s(t0, t1);
    *cpu_us = (double)(c1 - c0) / (n ? n : 1) * 1e-3;
    *count = n;
    printf("snapshots host-master 1 ms exposure: %d in %.1f s, %.1f /s, %.1f us CPU each, %d broken\n", n,
           sci_clock_s(t0, t1), *per_s, *cpu_us, *broken);
    capture_snapshot_release(snap);
    free(snap);
    trigger_close(trig);
    camera_close(cam);
    return 0;
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* the BLAS kernels and OpenMP waiting that scicap and scicapd run with */
    const enum pixfmt fmts[] = {PIXFMT_Y16, PIXFMT_Y12, PIXFMT_Y10, PIXFMT_Y10P, PIXFMT_GREY};
    result res[10];
    int nr = 0;
    printf("capture path on the simulated camera, 1920x1080 (timings on a shared 2-core machine are noisy)\n");
    for (size_t i = 0; i < sizeof fmts / sizeof fmts[0]; i++)
        for (int unpaced = 1; unpaced >= 0; unpaced--)
            if (run_stream(fmts[i], unpaced, 1.5, &res[nr]) == 0)
                nr++;
    double sps = 0, scpu = 0;
    int broken = 0, ns = 0;
    run_snapshots(1.5, &sps, &scpu, &broken, &ns);

    FILE *md = fopen("bench/results/camera.md", "w");
    if (!md) {
        perror("bench/results/camera.md");
        return 1;
    }
    fprintf(md, "| format (1920×1080) | camera | frames | sustained fps | CPU µs/frame | frames lost |\n");
    fprintf(md, "|---|---|---:|---:|---:|---:|\n");
    for (int i = 0; i < nr; i++)
        fprintf(md, "| %s | sim, %s | %d | %.1f | %.1f | %.0f |\n", res[i].fmt, res[i].mode, res[i].frames, res[i].fps,
                res[i].cpu_us, res[i].lost);
    fprintf(md, "\nSnapshots through `capture_snapshot_take` (host master, Y16, 1 ms exposure, 4 patterns): "
                "%d, %.1f per second, %.1f µs CPU each, %d broken.\n", ns, sps, scpu, broken);
    fprintf(md, "\nShared 2-core machine: timings are noisy.\n");
    fclose(md);
    return 0;
}
