#include "cli/recon_color.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/json.h"
#include "cli/progress.h"
#include "io/image.h"
#include "io/recon_store.h"
#include "io/staging.h"
#include "recon/metrics.h"

typedef struct plane_ctx {
    const cli_color_job *job;
    int plane;
} plane_ctx;

static int solve_plane(const sci_problem *plane, sci_result *r, void *user)
{
    plane_ctx *c = user;
    const cli_color_job *job = c->job;
    cli_progress prog;
    cli_progress_init(&prog, job->quiet ? -1 : 2, solver_settings_iters(job->method, job->settings));
    prog.stop = job->stop;
    if (!job->quiet)
        fprintf(stderr, "scicap recon: plane %d/4 (%s)\n", c->plane + 1, plane->name);
    const solver_io io = {.progress = cli_progress_update, .user = &prog};
    int rc = solver_run(job->method, plane, job->settings, &io, r);
    cli_progress_done(&prog);
    c->plane++;
    return rc;
}

/* A method with SOLVER_BAYER: the whole mosaic in one run, RGB frames from the method. */
static int solve_whole(const cli_color_job *job, const sci_problem *p, sci_result *r, sci_cube **rgb)
{
    cli_progress prog;
    cli_progress_init(&prog, job->quiet ? -1 : 2, solver_settings_iters(job->method, job->settings));
    prog.stop = job->stop;
    const solver_io io = {.progress = cli_progress_update, .user = &prog, .cfa = (int)job->cfa,
                          .demosaic = (int)job->demosaic, .rgb_out = rgb};
    int rc = solver_run(job->method, p, job->settings, &io, r);
    cli_progress_done(&prog);
    if (rc == 0 && !*rgb)
        rc = sci_error_set(&r->error, -EINVAL, "%s handed out no RGB frames", job->method->name);
    return rc;
}

/* The four planes' traces one after another, each row naming its plane (iterations count from 1 in each; a
 * plane's metrics are its own), wall and CPU time accumulated: what the colour result cost. */
static int join_traces(const sci_result res[4], sci_trace *out)
{
    double wall = 0, cpu = 0;
    for (int i = 0; i < 4; i++) {
        double w_end = 0, c_end = 0;
        for (size_t e = 0; e < res[i].trace.len; e++) {
            sci_trace_entry t = res[i].trace.e[e];
            w_end = t.wall_s, c_end = t.cpu_s;
            t.wall_s += wall, t.cpu_s += cpu;
            t.plane = i + 1;
            if (sci_trace_push(out, &t) < 0)
                return -ENOMEM;
        }
        wall += w_end, cpu += c_end;
    }
    return 0;
}

/* Add the colour record to dir/result.json (replaced atomically). With an RGB truth the
 * top-level PSNR is the RGB one (what the user sees); the raw mosaic's metrics move under "mosaic". */
static int add_color_record(const char *dir, json_t *color, sci_error *err)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/result.json", dir);
    json_error_t je;
    json_t *j = json_load_file(path, 0, &je);
    if (!j)
        return sci_error_set(err, SCI_EFORMAT, "%s: %s", path, je.text);
    json_object_set(j, "color", color);
    if (json_object_get(color, "psnr_rgb_frame_max_db")) {
        static const char *const keys[] = {"psnr_frame_max_db", "psnr_peak1_db", "ssim"};
        json_t *mosaic = json_object();
        for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
            if (json_object_get(j, keys[i])) {
                json_object_set(mosaic, keys[i], json_object_get(j, keys[i]));
                json_object_del(j, keys[i]);
            }
        json_object_set_new(j, "mosaic", mosaic);
        json_object_set(j, "psnr_frame_max_db", json_object_get(color, "psnr_rgb_frame_max_db"));
        json_object_set(j, "psnr_peak1_db", json_object_get(color, "psnr_rgb_peak1_db"));
    }
    int rc = sci_json_write_atomic(path, j, JSON_INDENT(2), 0644, 0, err);
    json_decref(j);
    return rc;
}

int cli_recon_color(const cli_color_job *job, const sci_problem *p, const sci_cube *truth_rgb, const char *dir,
                    int force, sci_error *err)
{
    sci_result res[4] = {{0}};
    sci_cube *rgb = NULL, *raw = NULL;
    sci_result r = {0};
    json_t *color = NULL;
    int rc;
    const int whole = (job->method->caps & SOLVER_BAYER) != 0;
    if (whole) {
        /* the method reconstructs the mosaic itself (e.g. pnp-ffdnet: demosaic, colour denoiser, mosaic) */
        if ((rc = solve_whole(job, p, &r, &rgb)) < 0) {
            sci_error_set(err, rc, "%s", r.error.msg);
            sci_result_free_contents(&r);
            return rc;
        }
        raw = r.frames;
    } else {
        plane_ctx ctx = {job, 0};
        if ((rc = sci_bayer_solve(p, job->cfa, job->demosaic, solve_plane, &ctx, &rgb, &raw, res, err)) < 0)
            return rc;
        r.frames = raw;
        snprintf(r.method, sizeof r.method, "%s", res[0].method);
        for (int i = 0; i < 4; i++)
            r.iters_done += res[i].iters_done;
        if ((rc = join_traces(res, &r.trace)) < 0) {
            sci_error_set(err, rc, "out of memory");
            goto out;
        }
    }
    const int n = raw->n;
    const double solver_s = r.trace.len ? r.trace.e[r.trace.len - 1].wall_s : NAN;
    if (whole)
        printf("  colour: Bayer %s, %dx%d mosaic reconstructed whole, %d iterations in %.3f s solver time, %s "
               "demosaic in each\n", sci_cfa_name(job->cfa), p->mask->w, p->mask->h, r.iters_done, solver_s,
               sci_demosaic_name(job->demosaic));
    else
        printf("  colour: Bayer %s, 4 planes of %dx%d, %d iterations in %.3f s solver time, %s demosaic\n",
               sci_cfa_name(job->cfa), p->mask->w / 2, p->mask->h / 2, r.iters_done, solver_s,
               sci_demosaic_name(job->demosaic));
    color = json_pack("{s:s, s:s, s:s}", "cfa", sci_cfa_name(job->cfa), "demosaic", sci_demosaic_name(job->demosaic),
                      "frames", "rgb_NNN.exr (RGB float), preview_rgb_NNN.png");
    if (truth_rgb) {
        if (truth_rgb->w != rgb->w || truth_rgb->h != rgb->h || truth_rgb->n != rgb->n) {
            rc = sci_error_set(err, SCI_ESHAPE, "%s: the RGB truth is %dx%dx%d, the result %dx%dx%d", p->name,
                               truth_rgb->w, truth_rgb->h, truth_rgb->n, rgb->w, rgb->h, rgb->n);
            goto out;
        }
        double *v = calloc(3 * (size_t)n, sizeof *v);
        if (!v) {
            rc = sci_error_set(err, -ENOMEM, "out of memory");
            goto out;
        }
        double m0 = sci_psnr_rgb(rgb, truth_rgb, SCI_PEAK_FRAME_MAX, 0, v);
        double m1 = sci_psnr_rgb(rgb, truth_rgb, SCI_PEAK_FIXED, p->peak, v + n);
        printf("  frame   RGB PSNR dB (peak = frame max)   RGB PSNR dB (peak = %g)   (mean over R, G, B)\n", p->peak);
        json_t *a0 = json_array(), *a1 = json_array();
        for (int f = 0; f < n; f++) {
            printf("  %5d   %30.2f   %23.2f\n", f + 1, v[f], v[n + f]);
            json_array_append_new(a0, json_real(v[f]));
            json_array_append_new(a1, json_real(v[n + f]));
        }
        printf("  mean    %30.2f   %23.2f   RGB\n", m0, m1);
        json_object_set_new(color, "psnr_rgb_frame_max_db", json_pack("{s:f, s:o, s:s}", "mean", m0, "frames", a0,
                                                                      "peak", "per-frame max of each truth channel"));
        json_object_set_new(color, "psnr_rgb_peak1_db",
                            json_pack("{s:f, s:o, s:f}", "mean", m1, "frames", a1, "peak", p->peak));
        free(v);
    }
    /* Publish on success only: the grey store and the RGB files go into a staging folder renamed into place at
     * the end (io/staging.h), so an interrupted or failed run leaves no half-coloured DIR. */
    char stage[4096];
    if (sci_staging_name(stage, sizeof stage, dir) < 0) {
        rc = sci_error_set(err, -ENAMETOOLONG, "%s: name too long", dir);
        goto out;
    }
    const sci_recon_store_opts so = {.extra = job->extra, .stop = job->stop, .preview_auto = job->preview_auto};
    if ((rc = sci_recon_store_save(stage, p, &r, job->params, &so, err)) < 0)
        goto out;
    for (int f = 0; f < n && rc == 0; f++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/rgb_%03d.exr", stage, f);
        rc = sci_image_write_rgb(path, rgb, f, SCI_PIXEL_F32, 1.0, err);
        snprintf(path, sizeof path, "%s/preview_rgb_%03d.png", stage, f);
        if (rc == 0)
            rc = sci_image_write_rgb(path, rgb, f, SCI_PIXEL_U8, 255.0 / p->peak, err);
    }
    if (rc == 0)
        rc = add_color_record(stage, color, err);
    if (rc == 0)
        rc = sci_staging_publish(stage, dir, force ? SCI_STAGING_OVERWRITE : 0, job->stop, err);
    else
        sci_staging_remove(stage);
out:
    json_decref(color);
    for (int i = 0; i < 4; i++)
        sci_result_free_contents(&res[i]);
    sci_result_free_contents(&r); /* frees raw */
    sci_cube_free(rgb);
    return rc;
}
