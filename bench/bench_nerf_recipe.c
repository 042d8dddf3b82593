/* bench/bench_nerf_recipe.c — the recipe study of issue 15: one NeRF run with any setting changed by name, printing
 * PSNR, the measurement residual and the mean largest ray weight along the run, so each candidate of the recipe
 * can be kept or dropped by what it buys per second.
 *
 *   build/bench/bench_nerf_recipe PROBLEM rayformer|scinerf [preset=fast] [iters=400] [key=value ...]
 *
 * PROBLEM is anything `scicap recon` reads (a `scicap sim` folder). Keys: every field printed by `keys=1`, e.g.
 * spacing=linear|disparity|log distortion=0.01 depth_tv=0.1 prior_steps=200 prior_weight=1 density_bias=-2
 * zero_gates=1 net_lr_scale=1 sh_degree=1 ablation=0…4 patch=8 patches_per_step=4 samples=32 lr=1e-2 threads=1.
 * Output: one line per full render ("curve ITER WALL_S PSNR_PEAK1 MEAS_RESIDUAL MAX_WEIGHT") and a last line
 * "final NAME ..." with the same figures, the SSIM and the 1-minute load average. Not part of `make bench`: the
 * candidates it measured are in docs/nerf-methods.md ("The recipe").
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench/bench_load.h"
#include "io/source.h"
#include "recon/nerf/rayformer_solve.h"
#include "recon/nerf/scinerf_solve.h"

static int on_progress(const sci_trace_entry *e, void *user)
{
    (void)user;
    if (!isnan(e->psnr_peak1))
        printf("curve %d %.1f %.3f %.5f %.4f\n", e->iter, e->wall_s, e->psnr_peak1, e->meas_residual, e->max_weight);
    fflush(stdout);
    return 0;
}

static int spacing_of(const char *v)
{
    return strcmp(v, "disparity") == 0 ? NERF_SPACING_DISPARITY
           : strcmp(v, "log") == 0     ? NERF_SPACING_LOG
           : strcmp(v, "linear") == 0  ? NERF_SPACING_LINEAR
                                       : -1;
}

/* Apply key=value to the recipe shared by both methods; 1 if the key was one of its fields. */
static int set_recipe(nerf_recipe *r, const char *k, const char *v)
{
    if (strcmp(k, "spacing") == 0) {
        int s = spacing_of(v);
        if (s < 0) {
            fprintf(stderr, "spacing: linear, disparity or log\n");
            exit(2);
        }
        r->spacing = (nerf_spacing)s;
    } else if (strcmp(k, "distortion") == 0)
        r->distortion_weight = atof(v);
    else if (strcmp(k, "depth_tv") == 0)
        r->depth_tv_weight = atof(v);
    else if (strcmp(k, "c2f_steps") == 0)
        r->c2f_steps = atoi(v);
    else if (strcmp(k, "prior_steps") == 0)
        r->prior_steps = atoi(v);
    else if (strcmp(k, "prior_weight") == 0)
        r->prior_weight = atof(v);
    else if (strcmp(k, "density_bias") == 0)
        r->density_bias = atof(v);
    else
        return 0;
    return 1;
}

int main(int argc, char **argv)
{
    if (argc < 3) { /* `make bench` runs every program bare: say how to use this one */
        fprintf(argc == 1 ? stdout : stderr, "usage: %s PROBLEM rayformer|scinerf [key=value ...] (the recipe "
                "study; not part of make bench)\n", argv[0]);
        return argc == 1 ? 0 : 2;
    }
    const int rf = strcmp(argv[2], "rayformer") == 0;
    if (!rf && strcmp(argv[2], "scinerf") != 0) {
        fprintf(stderr, "method: rayformer or scinerf\n");
        return 2;
    }
    sci_rayformer_params rp;
    sci_scinerf_params sp;
    sci_rayformer_params_default(&rp);
    sci_scinerf_params_default(&sp);
    /* the preset first, whatever its position, then the other keys in order */
    for (int i = 3; i < argc; i++)
        if (strncmp(argv[i], "preset=", 7) == 0 &&
            (sci_rayformer_params_preset(&rp, argv[i] + 7) < 0 || sci_scinerf_params_preset(&sp, argv[i] + 7) < 0)) {
            fprintf(stderr, "unknown preset %s\n", argv[i] + 7);
            return 2;
        }
    rp.metrics_every = sp.metrics_every = 100;
    rp.ssim_every = sp.ssim_every = 0;
    for (int i = 3; i < argc; i++) {
        char key[64];
        const char *eq = strchr(argv[i], '=');
        if (!eq || eq - argv[i] >= (long)sizeof key) {
            fprintf(stderr, "bad argument %s (key=value)\n", argv[i]);
            return 2;
        }
        memcpy(key, argv[i], (size_t)(eq - argv[i]));
        key[eq - argv[i]] = 0;
        const char *v = eq + 1;
        if (strcmp(key, "preset") == 0)
            continue;
        if (set_recipe(rf ? &rp.recipe : &sp.recipe, key, v))
            continue;
        if (strcmp(key, "iters") == 0)
            rp.iters = sp.iters = atoi(v);
        else if (strcmp(key, "metrics_every") == 0)
            rp.metrics_every = sp.metrics_every = atoi(v);
        else if (strcmp(key, "threads") == 0)
            rp.threads = sp.threads = atoi(v);
        else if (strcmp(key, "lr") == 0)
            rp.lr = sp.lr = atof(v);
        else if (strcmp(key, "lr_final") == 0)
            rp.lr_final = sp.lr_final = atof(v);
        else if (strcmp(key, "samples") == 0)
            rp.samples = sp.samples = atoi(v);
        else if (strcmp(key, "sh_degree") == 0)
            rp.sh_degree = sp.sh_degree = atoi(v);
        else if (strcmp(key, "seed") == 0)
            rp.seed = sp.seed = strtoull(v, NULL, 10);
        else if (strcmp(key, "log2_table") == 0)
            rp.log2_table = sp.log2_table = atoi(v);
        else if (strcmp(key, "finest_res") == 0)
            rp.finest_res = sp.finest_res = atof(v);
        else if (rf && strcmp(key, "zero_gates") == 0)
            rp.zero_gates = atoi(v);
        else if (rf && strcmp(key, "blocks") == 0)
            rp.blocks = atoi(v);
        else if (rf && strcmp(key, "heads_full_lr") == 0)
            rp.heads_full_lr = atoi(v);
        else if (rf && strcmp(key, "net_lr_scale") == 0)
            rp.net_lr_scale = atof(v);
        else if (rf && strcmp(key, "tv_weight") == 0)
            rp.tv_weight = atof(v);
        else if (rf && strcmp(key, "patch") == 0)
            rp.patch = atoi(v);
        else if (rf && strcmp(key, "patches_per_step") == 0)
            rp.patches_per_step = atoi(v);
        else if (rf && strcmp(key, "ablation") == 0)
            sci_rayformer_params_ablation(&rp, atoi(v), rp.tv_weight);
        else if (!rf && strcmp(key, "rays_per_step") == 0)
            sp.rays_per_step = atoi(v);
        else if (!rf && strcmp(key, "fine_samples") == 0)
            sp.fine_samples = atoi(v);
        else {
            fprintf(stderr, "unknown key %s for %s\n", key, argv[2]);
            return 2;
        }
    }
    sci_problem **probs = NULL;
    int k = 0;
    sci_error err = {0};
    if (sci_source_read(argv[1], &probs, &k, &err) < 0) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    sci_result res = {0};
    int rc = rf ? sci_rayformer_solve(probs[0], &rp, &res, on_progress, NULL)
                : sci_scinerf_solve(probs[0], &sp, &res, on_progress, NULL);
    if (rc < 0 && rc != SCI_ECANCELED) {
        fprintf(stderr, "%s\n", res.error.msg);
        sci_result_free_contents(&res);
        sci_problem_array_free(probs, k);
        return 1;
    }
    const sci_trace_entry *e = &res.trace.e[res.trace.len - 1];
    char load[48];
    bench_loadavg(load, sizeof load);
    printf("final %s it=%d wall=%.1f psnr1=%.3f ssim=%.4f meas_res=%.5f max_w=%.4f load=%s\n", argv[2], e->iter,
           e->wall_s, e->psnr_peak1, e->ssim, e->meas_residual, e->max_weight, load);
    sci_result_free_contents(&res);
    sci_problem_array_free(probs, k);
    return 0;
}
