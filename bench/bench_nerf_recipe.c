/* bench/bench_nerf_recipe.c — the recipe study: one NeRF run with any setting changed by name, printing
 * PSNR, the measurement residual and the mean largest ray weight along the run, so each candidate of the recipe
 * can be kept or dropped by what it buys per second.
 *
 *   build/bench/bench_nerf_recipe PROBLEM METHOD [preset=fast] [key=value ...]
 *
 * PROBLEM is anything `scicap recon` reads (a `scicap sim` folder); METHOD any NeRF row of the solver table
 * (recon/solver.h). Keys are the method's settings as `scicap recon` takes them (the table's fields, e.g.
 * spacing=disparity distortion_weight=0.01 zero_gates=true final_norm=false ablation=patch samples=32
 * threads=1); a value is read as JSON when it parses, else as a string. metrics_every defaults to 100 here.
 * Output: one line per full render ("curve ITER WALL_S PSNR_PEAK1 MEAS_RESIDUAL MAX_WEIGHT") and a last line
 * "final NAME ..." with the same figures, the SSIM, the pose error (0 with known poses; rotation in rad,
 * translation after the scale: nerf_poses_relative_error) and the 1-minute load average. Not part of `make
 * bench`: the candidates it measured are in docs/nerf-methods.md ("The recipe").
 *
 * clean=DIR (a simulation of the same scene without its noise effects: same masks, noise-free measurement) adds
 * a line "clean noise_floor=‖n‖/‖y‖ signal_res=‖A x − y₀‖/‖y₀‖ noise_fit=⟨n, A x − y₀⟩/‖n‖²" with y₀ the clean
 * and n = y − y₀ the noise of the measurement trained on: how closely the result fits the signal, and which
 * fraction of the noise it reproduces (0: none, 1: all of it), so a noisy scene's residual can be read.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "base/json.h"
#include "base/runtime_env.h"
#include "bench/bench_load.h"
#include "io/source.h"
#include "recon/nerf/poses.h"
#include "recon/sci_ops.h"
#include "recon/solver.h"

static int on_progress(const sci_trace_entry *e, void *user)
{
    (void)user;
    if (!isnan(e->psnr_peak1))
        printf("curve %d %.1f %.3f %.5f %.4f\n", e->iter, e->wall_s, e->psnr_peak1, e->meas_residual, e->max_weight);
    fflush(stdout);
    return 0;
}

/* The "clean" line (header): the result's fit to the noise-free measurement y0 and to the noise y − y0. */
static int print_clean_fit(const char *dir, const sci_problem *p, const sci_cube *x)
{
    sci_error err = {0};
    sci_problem **cp = NULL;
    int k = 0;
    if (sci_source_read(dir, &cp, &k, &err) < 0) {
        fprintf(stderr, "clean=%s: %s\n", dir, err.msg);
        return -1;
    }
    const sci_cube *y = p->meas, *y0 = cp[0]->meas;
    sci_cube *ax = NULL;
    int rc = -1;
    const sci_cube *m = p->mask, *m0 = cp[0]->mask;
    if (y0->w != y->w || y0->h != y->h || m0->n != m->n ||
        memcmp(m0->data, m->data, sizeof(float) * (size_t)m->w * m->h * m->n) != 0)
        fprintf(stderr, "clean=%s: not the same scene (shape or masks differ)\n", dir);
    else if (sci_cube_new(&ax, y->w, y->h, 1, &err) == 0) {
        sci_op_forward(p->mask, x, ax);
        double nn = 0, yy = 0, y0y0 = 0, dd = 0, nd = 0;
        for (size_t i = 0; i < (size_t)y->w * y->h; i++) {
            const double n = (double)y->data[i] - y0->data[i], d = (double)ax->data[i] - y0->data[i];
            nn += n * n, yy += (double)y->data[i] * y->data[i], y0y0 += (double)y0->data[i] * y0->data[i];
            dd += d * d, nd += n * d;
        }
        printf("clean noise_floor=%.5f signal_res=%.5f noise_fit=%.4f\n", sqrt(nn / yy), sqrt(dd / y0y0),
               nn > 0 ? nd / nn : NAN);
        rc = 0;
    }
    sci_cube_free(ax);
    sci_problem_array_free(cp, k);
    return rc;
}

/* Adds "key=value" to the settings object `obj` (sci_json_set_kv); a malformed argument ends the program (2). */
static void add_key(json_t *obj, const char *arg)
{
    if (sci_json_set_kv(obj, arg) < 0) {
        fprintf(stderr, "bad argument %s (key=value)\n", arg);
        exit(2);
    }
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* the BLAS kernels and OpenMP waiting that scicap and scicapd run with */
    if (argc < 3) { /* `make bench` runs every program bare: say how to use this one */
        fprintf(argc == 1 ? stdout : stderr, "usage: %s PROBLEM METHOD [key=value ...] (the recipe study; not part "
                "of make bench)\n", argv[0]);
        return argc == 1 ? 0 : 2;
    }
    sci_error err = {0};
    const solver_ops *m = solver_find_err(argv[2], &err);
    if (!m) {
        fprintf(stderr, "%s\n", err.msg);
        return 2;
    }
    void *settings = solver_settings_new(m);
    if (!settings) return 1;
    /* one settings object, applied as `scicap recon` applies a file's: the preset first, the keys in order, then
     * the method's rules (rayformer's patch=8 without patches_per_step keeps the rays per step) */
    json_t *obj = json_object();
    const char *clean = NULL;
    add_key(obj, "metrics_every=100");
    add_key(obj, "ssim_every=0");
    for (int i = 3; i < argc; i++)
        if (strncmp(argv[i], "clean=", 6) == 0)
            clean = argv[i] + 6;
        else
            add_key(obj, argv[i]);
    if (solver_settings_from_json(m, settings, obj, NULL, "arguments", &err) < 0) {
        fprintf(stderr, "%s\n", err.msg);
        return 2;
    }
    json_decref(obj);
    sci_problem **probs = NULL;
    int k = 0;
    if (sci_source_read(argv[1], &probs, &k, &err) < 0) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    sci_result res = {0};
    const int n = probs[0]->mask->n;
    double(*poses)[12] = probs[0]->camera ? calloc((size_t)n, sizeof *poses) : NULL;
    const solver_io io = {.progress = on_progress, .poses_out = poses};
    int rc = solver_run(m, probs[0], settings, &io, &res);
    if (rc < 0 && rc != SCI_ECANCELED) {
        fprintf(stderr, "%s\n", res.error.msg);
        sci_result_free_contents(&res);
        sci_problem_array_free(probs, k);
        return 1;
    }
    const sci_trace_entry *e = &res.trace.e[res.trace.len - 1];
    char load[48];
    bench_loadavg(load, sizeof load);
    char pose[96] = "";
    nerf_poses *pp;
    if (poses && nerf_poses_new(&pp, NERF_POSES_PER_FRAME, n, (const double(*)[12])poses, 0, 0, 0, NULL) == 0) {
        nerf_pose_error pe = nerf_poses_relative_error(pp, (const double(*)[12])probs[0]->camera->pose);
        snprintf(pose, sizeof pose, " pose_rot=%.4f pose_trans=%.4f", pe.rot_rad, pe.trans_scaled);
        nerf_poses_free(pp);
    }
    free(poses);
    printf("final %s it=%d wall=%.1f psnr1=%.3f ssim=%.4f meas_res=%.5f max_w=%.4f%s load=%s\n", m->name, e->iter,
           e->wall_s, e->psnr_peak1, e->ssim, e->meas_residual, e->max_weight, pose, load);
    if (clean && print_clean_fit(clean, probs[0], res.frames) < 0) rc = -1;
    sci_result_free_contents(&res);
    sci_problem_array_free(probs, k);
    solver_settings_free(settings);
    return rc < 0 && rc != SCI_ECANCELED ? 1 : 0;
}
