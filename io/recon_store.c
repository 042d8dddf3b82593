#include "io/recon_store.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "io/image.h"
#include "io/staging.h"
#include "recon/metrics.h"

static json_t *num_or_null(double v) { return isfinite(v) ? json_real(v) : json_null(); }

json_t *sci_recon_summary(const sci_problem *p, const sci_result *r, const json_t *params)
{
    json_t *s = json_object();
    json_object_set_new(s, "method", json_string(r->method));
    json_object_set_new(s, "problem", json_string(p->name));
    json_object_set_new(s, "iterations", json_integer(r->iters_done));
    json_object_set_new(s, "status", json_string(r->stopped == 0 ? "complete"
                                                 : r->stopped == SCI_ECANCELED ? "canceled"
                                                 : r->stopped == SCI_EDIVERGED ? "diverged"
                                                                               : "error"));
    if (r->error.msg[0])
        json_object_set_new(s, "message", json_string(r->error.msg));
    if (r->trace.len) {
        const sci_trace_entry *e = &r->trace.e[r->trace.len - 1];
        json_object_set_new(s, "wall_s", json_real(e->wall_s));
        json_object_set_new(s, "cpu_s", json_real(e->cpu_s));
        json_object_set_new(s, "residual", num_or_null(e->residual));
    }
    if (p->truth && r->frames) {
        const int n = r->frames->n;
        double *pf = malloc(3 * (size_t)n * sizeof *pf);
        /* the solver's tracer computed them on these very frames at its last iteration: taken, not recomputed */
        const sci_trace_entry *last = r->trace.len ? &r->trace.e[r->trace.len - 1] : NULL;
        const int reuse = r->final_metrics && r->final_of == r->frames->data && r->final_n == n && last &&
                          last->iter == r->iters_done;
        if (pf && reuse)
            memcpy(pf, r->final_metrics, 3 * (size_t)n * sizeof *pf);
        if (pf) {
            double m0 = reuse ? last->psnr : sci_psnr(r->frames, p->truth, SCI_PEAK_FRAME_MAX, 0, pf);
            double m1 = reuse ? last->psnr_peak1 : sci_psnr(r->frames, p->truth, SCI_PEAK_FIXED, p->peak, pf + n);
            double ms = reuse ? last->ssim : sci_ssim(r->frames, p->truth, p->peak, pf + 2 * n);
            json_t *a0 = json_array(), *a1 = json_array(), *as = json_array();
            for (int k = 0; k < n; k++) {
                json_array_append_new(a0, num_or_null(pf[k]));
                json_array_append_new(a1, num_or_null(pf[n + k]));
                json_array_append_new(as, num_or_null(pf[2 * n + k]));
            }
            json_object_set_new(s, "psnr_frame_max_db",
                                json_pack("{s:o, s:o, s:s}", "mean", num_or_null(m0), "frames", a0, "peak",
                                          "per-frame max of truth"));
            json_object_set_new(s, "psnr_peak1_db", json_pack("{s:o, s:o, s:f}", "mean", num_or_null(m1), "frames",
                                                             a1, "peak", p->peak));
            json_object_set_new(s, "ssim", json_pack("{s:o, s:o, s:s}", "mean", num_or_null(ms), "frames", as,
                                                     "window", "gaussian 11x11 sigma 1.5"));
            free(pf);
        }
    }
    if (params)
        json_object_set_new(s, "params", json_deep_copy(params));
    return s;
}

void sci_recon_store_estimate(long long w, long long h, long long n, long long snapshots, double *bytes,
                              double *files)
{
    const double px = (double)w * (double)h, block = 4096;
    const double gif_px = px < SCI_GIF_MAX_PIXELS ? px : SCI_GIF_MAX_PIXELS;
    /* per frame: EXR (4 B/px) + PNG (1 B/px) + a block each; per snapshot: gif, frame.json, trace, result */
    const double per = (double)n * (5 * px + 2 * block) + (double)n * gif_px + 4 * block + 65536;
    *bytes = (double)snapshots * per;
    *files = (double)snapshots * (2.0 * (double)n + 5);
}

int sci_recon_store_write(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                          int overwrite, sci_error *err)
{
    return sci_recon_store_write_opt(dir, p, r, params, overwrite, NULL, err);
}

int sci_recon_store_write_opt(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                              int overwrite, const volatile sig_atomic_t *stop, sci_error *err)
{
    return sci_recon_store_write_ex(dir, p, r, params, NULL, overwrite ? SCI_STAGING_OVERWRITE : 0, stop, err);
}

int sci_recon_store_write_ex(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                             const json_t *extra, int flags, const volatile sig_atomic_t *stop, sci_error *err)
{
    struct stat st;
    if (!r->frames)
        return sci_error_set(err, -EINVAL, "%s: no frames to write (%s)", dir,
                             r->error.msg[0] ? r->error.msg : "solver produced none");
    if (stat(dir, &st) == 0 && !(flags & SCI_STAGING_OVERWRITE))
        return sci_error_set(err, -EEXIST, "%s: already exists (use --force to replace it)", dir);
    char tmp[4096], path[4300];
    if (sci_staging_name(tmp, sizeof tmp, dir) < 0)
        return sci_error_set(err, -ENAMETOOLONG, "%s: name too long", dir);
    json_t *prov = json_pack("{s:s, s:s}", "method", r->method, "problem", p->name);
    /* uncompressed: a solver's float frames hardly compress (2 %) and deflate costs 5-6 ms a 256×256 frame */
    int rc = sci_stack_write_ex(tmp, "frame", "exr", r->frames, SCI_PIXEL_F32, 1.0, prov, 1, err);
    json_decref(prov);
    for (int k = 0; k < r->frames->n && rc == 0; k++) {
        if (stop && *stop) {
            rc = sci_error_set(err, SCI_ECANCELED, "%s: interrupted; not written", dir);
            break;
        }
        snprintf(path, sizeof path, "%s/preview_%03d.png", tmp, k);
        rc = sci_image_write(path, r->frames, k, SCI_PIXEL_U8, 255.0 / p->peak, NULL, err);
    }
    if (rc == 0 && stop && *stop)
        rc = sci_error_set(err, SCI_ECANCELED, "%s: interrupted; not written", dir);
    if (rc == 0) {
        snprintf(path, sizeof path, "%s/preview.gif", tmp);
        rc = sci_image_write_gif(path, r->frames, 255.0 / p->peak, 125, err);
    }
    if (rc == 0) {
        snprintf(path, sizeof path, "%s/trace.csv", tmp);
        rc = sci_trace_write_csv(&r->trace, path, err);
    }
    if (rc == 0) {
        json_t *s = sci_recon_summary(p, r, params);
        if (extra)
            json_object_update(s, (json_t *)extra);
        snprintf(path, sizeof path, "%s/result.json", tmp);
        if (json_dump_file(s, path, JSON_INDENT(2)) != 0)
            rc = sci_error_set(err, -EIO, "%s: cannot write", path);
        json_decref(s);
    }
    if (rc == 0)
        return sci_staging_publish(tmp, dir, flags, stop, err);
    sci_staging_remove(tmp);
    return rc;
}
