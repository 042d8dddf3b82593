/* bench_sim — what the simulator costs: time per snapshot at 256×256×8 with no effects (against the bare forward
 * model), with each effect alone and with all; and static3d rendering at 256×256×8 with supersampling.
 * Prints the figures and writes bench/results/sim.md. Timings are medians over repeats, on a shared machine. */
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/runtime_env.h"
#include "recon/sci_ops.h"
#include "sim/simulate.h"

#define REPEATS 31

static const char *const fx_json[SIM_FX_COUNT] = {
    "\"motion_blur\": {\"samples\": 4}",
    "\"blur\": {\"sigma_px\": 1.0}",
    "\"vignetting\": {\"corner\": 0.6}",
    "\"dmd_contrast\": {\"leakage\": 0.002, \"fill_factor\": 0.92}",
    "\"misregistration\": {\"shift_px\": [0.3, -0.2], \"rotation_rad\": 0.002}",
    "\"jitter\": {\"sigma\": 0.05}",
    "\"shot_noise\": true",
    "\"dark_offset\": {\"e\": 10}",
    "\"saturation\": true",
    "\"read_noise\": {\"sigma_e\": 3}",
    "\"quantization\": true",
};

static sim_scene *scene_with(unsigned listed)
{
    char fx[2048] = "", text[4096];
    for (int e = 0; e < SIM_FX_COUNT; e++)
        if (listed & (1u << e)) {
            size_t l = strlen(fx);
            snprintf(fx + l, sizeof fx - l, "%s%s", l ? ", " : "", fx_json[e]);
        }
    snprintf(text, sizeof text,
             "{\"kind\": \"video2d\", \"width\": 256, \"height\": 256, \"frames\": 8, \"seed\": 3,"
             " \"layers\": [{\"texture\": {\"type\": \"noise\", \"cell\": 40}},"
             " {\"shape\": \"polygon\", \"sides\": 5, \"size\": [90, 90], \"position\": [170, 90],"
             "  \"velocity\": [-3, 2], \"spin_rad\": 0.05, \"texture\": {\"type\": \"checkerboard\", \"cell\": 10}},"
             " {\"shape\": \"disc\", \"size\": [80, 80], \"position\": [70, 160], \"velocity\": [4, -1.5],"
             "  \"texture\": {\"type\": \"radial\", \"center\": [40, 40], \"length\": 40}}],"
             " \"effects\": {%s}}",
             fx);
    sim_scene *sc;
    sci_error err = {0};
    if (sim_scene_load_string(&sc, "bench.json", text, NULL, &err) < 0) {
        fprintf(stderr, "bench_sim: %s\n", err.msg);
        exit(1);
    }
    return sc;
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp);
    return v[n / 2];
}

static int render_cb(void *user, double t, float *out) { return sim_render_frame(user, t, out); }

/* Median ms of sim_effects_measure for the scene's listed effects. */
static double time_measure(const sim_scene *sc, const sci_cube *x, const sci_cube *m, sci_cube *y, double *min_ms)
{
    sim_effects *fx;
    sci_error err = {0};
    if (sim_effects_new(&fx, &sc->fx, sc->w, sc->h, sc->n, sc->seed, &err) < 0) {
        fprintf(stderr, "bench_sim: %s\n", err.msg);
        exit(1);
    }
    double t[REPEATS];
    for (int r = 0; r < REPEATS; r++) {
        int64_t t0 = sci_clock_mono_ns();
        sim_effects_measure(fx, 0, x, m, render_cb, (void *)sc, y, NULL, &err);
        t[r] = sci_clock_s(t0, sci_clock_mono_ns()) * 1e3;
    }
    sim_effects_free(fx);
    double med = median(t, REPEATS);
    *min_ms = t[0];
    return med;
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* the BLAS kernels and OpenMP waiting that scicap and scicapd run with */
    sci_error err = {0};
    sim_scene *base = scene_with(0);
    sci_cube *x, *m, *y;
    sim_masks_make(&base->masks, base->w, base->h, base->n, base->seed, &m, &err);
    sci_cube_new(&x, base->w, base->h, base->n, &err);
    sci_cube_new(&y, base->w, base->h, 1, &err);
    int threads = omp_get_max_threads();
    /* The measurement table runs on one thread: on a shared 2-core machine an OpenMP barrier that waits for a
     * descheduled thread costs a whole scheduler tick, which swamps millisecond kernels. */
    omp_set_num_threads(1);

    double tr[5];
    for (int r = 0; r < 5; r++) {
        int64_t t0 = sci_clock_mono_ns();
        sim_render_truth(base, 0, x, &err);
        tr[r] = sci_clock_s(t0, sci_clock_mono_ns()) * 1e3;
    }
    double render_ms = median(tr, 5);

    double tf[REPEATS];
    for (int r = 0; r < REPEATS; r++) {
        int64_t t0 = sci_clock_mono_ns();
        sci_op_forward(m, x, y);
        tf[r] = sci_clock_s(t0, sci_clock_mono_ns()) * 1e3;
    }
    double fwd_ms = median(tf, REPEATS), fwd_min = tf[0];

    FILE *md = fopen("bench/results/sim.md", "w");
    char line[256];
#define OUT(...)                                                                                                  \
    do {                                                                                                          \
        snprintf(line, sizeof line, __VA_ARGS__);                                                                 \
        fputs(line, stdout);                                                                                      \
        if (md)                                                                                                   \
            fputs(line, md);                                                                                      \
    } while (0)
    OUT("### Simulator: time per snapshot, 256×256×8 (video2d, 1 thread, median of %d; shared 2-core machine, "
        "noisy)\n\n", REPEATS);
    OUT("Measurement stage only: truth and masks are given (rendering them took %.1f ms per snapshot at supersample 1); motion_blur re-renders 4 instants per frame, so it includes rendering.\n\n", render_ms);
    OUT("| effects | median ms | min ms | × bare forward |\n|---|---:|---:|---:|\n");
    OUT("| bare `sci_op_forward` | %.3f | %.3f | 1.00 |\n", fwd_ms, fwd_min);
    double mn, med = time_measure(base, x, m, y, &mn);
    OUT("| none (the simulator) | %.3f | %.3f | %.2f |\n", med, mn, med / fwd_ms);
    for (int e = 0; e < SIM_FX_COUNT; e++) {
        sim_scene *sc = scene_with(1u << e);
        med = time_measure(sc, x, m, y, &mn);
        OUT("| %s%s | %.3f | %.3f | %.2f |\n", sim_fx_name(e), e == SIM_FX_MOTION_BLUR ? " (4 renders/frame)" : "",
            med, mn, med / fwd_ms);
        sim_scene_free(sc);
    }
    sim_scene *all = scene_with((1u << SIM_FX_COUNT) - 1);
    med = time_measure(all, x, m, y, &mn);
    OUT("| all eleven | %.3f | %.3f | %.2f |\n", med, mn, med / fwd_ms);
    sim_scene_free(all);

    omp_set_num_threads(threads);
    OUT("\n### static3d rendering, 256×256×8 (3 objects + wall, moving camera; %d threads)\n\n", threads);
    OUT("| supersample | rays per pixel | ms per snapshot (8 frames) | Mrays/s |\n|---:|---:|---:|---:|\n");
    int ss_list[] = {1, 2, 4};
    for (int i = 0; i < 3; i++) {
        char text[2048];
        snprintf(text, sizeof text,
                 "{\"kind\": \"static3d\", \"width\": 256, \"height\": 256, \"frames\": 8, \"supersample\": %d,"
                 " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, -4], \"radius\": 1,"
                 "   \"texture\": {\"type\": \"checkerboard\", \"cell\": 8}},"
                 "  {\"type\": \"box\", \"center\": [1.5, -0.5, -5], \"size\": [1, 1, 1], \"rotation_rad\": [0.3, 0.6, 0],"
                 "   \"texture\": {\"type\": \"noise\", \"cell\": 6}},"
                 "  {\"type\": \"plane\", \"center\": [0, -1.2, -5], \"size\": [10, 10], \"rotation_rad\": [-1.5708, 0, 0],"
                 "   \"texture\": {\"type\": \"checkerboard\", \"cell\": 16}},"
                 "  {\"type\": \"plane\", \"center\": [0, 0, -9], \"size\": [20, 20], \"texture\": {\"type\": \"gradient\", \"length\": 600}}],"
                 " \"light\": {\"direction\": [0.4, 1, 0.6]},"
                 " \"camera\": {\"start\": {\"position\": [-0.3, 0.2, 0], \"look_at\": [0, 0, -4]},"
                 "   \"end\": {\"position\": [0.3, 0.3, 0.2], \"look_at\": [0.2, 0, -4]}}}",
                 ss_list[i]);
        sim_scene *sc;
        if (sim_scene_load_string(&sc, "bench3d.json", text, NULL, &err) < 0) {
            fprintf(stderr, "bench_sim: %s\n", err.msg);
            return 1;
        }
        double t3[3];
        for (int r = 0; r < 3; r++) {
            int64_t t0 = sci_clock_mono_ns();
            sim_render_truth(sc, 0, x, &err);
            t3[r] = sci_clock_s(t0, sci_clock_mono_ns()) * 1e3;
        }
        double ms = median(t3, 3), rays = 256.0 * 256 * 8 * ss_list[i] * ss_list[i];
        OUT("| %d | %d | %.1f | %.1f |\n", ss_list[i], ss_list[i] * ss_list[i], ms, rays / (ms * 1e3));
        sim_scene_free(sc);
    }
    if (md)
        fclose(md);
    sci_cube_free(x);
    sci_cube_free(m);
    sci_cube_free(y);
    sim_scene_free(base);
    return 0;
}
