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

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Percentiles q (ascending, in [0, 1]) of a cube's values, from at most 2^20 evenly strided samples. */
static int cube_percentiles(const sci_cube *c, const double *q, int nq, double *out)
{
    const size_t total = sci_cube_count(c), stride = total > (1u << 20) ? total / (1u << 20) + 1 : 1;
    const size_t m = (total + stride - 1) / stride;
    float *v = malloc(m * sizeof *v);
    if (!v || !m) {
        free(v);
        return -1;
    }
    for (size_t i = 0; i < m; i++)
        v[i] = c->data[i * stride];
    qsort(v, m, sizeof *v, cmp_float);
    for (int k = 0; k < nq; k++)
        out[k] = v[(size_t)(q[k] * (double)(m - 1))];
    free(v);
    return 0;
}

int sci_recon_levels(const sci_problem *p, const sci_cube *frames, double *p1, double *p99, char *buf, size_t n)
{
    static const double q[2] = {0.01, 0.99};
    double v[2] = {NAN, NAN};
    if (buf && n)
        buf[0] = 0;
    if (!frames || cube_percentiles(frames, q, 2, v) < 0)
        return *p1 = *p99 = NAN, 0;
    const double peak = p->peak > 0 ? p->peak : 1;
    *p1 = v[0] / peak;
    *p99 = v[1] / peak;
    if (!buf || !n || (*p99 >= 0.05 && *p99 <= 2))
        return 0;
    snprintf(buf, n, "the frames' 99th percentile is %.3g of white: they are %s; the input's scale looks wrong (give "
                     "--scale with the value of white, or look at the previews with --preview-range auto)",
             *p99, *p99 < 0.05 ? "nearly black" : "far above white (saturated previews)");
    return 1;
}

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
    double p1, p99;
    char warn[320];
    int warned = sci_recon_levels(p, r->frames, &p1, &p99, warn, sizeof warn);
    if (r->frames)
        json_object_set_new(s, "levels", json_pack("{s:o, s:o, s:s}", "p1", num_or_null(p1), "p99", num_or_null(p99),
                                                   "unit", "fraction of white"));
    if (warned)
        json_object_set_new(s, "warnings", json_pack("[s]", warn));
    if (params)
        json_object_set_new(s, "params", json_deep_copy(params));
    return s;
}

void sci_recon_store_estimate(long long w, long long h, long long n, long long snapshots, double *bytes,
                              double *files)
{
    const double px = (double)w * (double)h, block = 4096;
    const double gif_px = px < SCI_GIF_MAX_PIXELS ? px : SCI_GIF_MAX_PIXELS;
    /* per frame: EXR (4 B/px) + PNG (1 B/px) + a block each, and its row of compare.png (3 B/px); per snapshot:
     * gif, frame.json, trace, result, compare.png */
    const double per = (double)n * (8 * px + 2 * block) + (double)n * gif_px + 5 * block + 65536;
    *bytes = (double)snapshots * per;
    *files = (double)snapshots * (2.0 * (double)n + 6);
}

int sci_recon_store_write(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                          int overwrite, sci_error *err)
{
    const sci_recon_store_opts o = {.flags = overwrite ? SCI_STAGING_OVERWRITE : 0};
    return sci_recon_store_save(dir, p, r, params, &o, err);
}

int sci_recon_store_write_ex(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                             const json_t *extra, int flags, const volatile sig_atomic_t *stop, sci_error *err)
{
    const sci_recon_store_opts o = {.extra = extra, .flags = flags, .stop = stop};
    return sci_recon_store_save(dir, p, r, params, &o, err);
}

/* truth | reconstruction | |difference|·4, one row per frame, 8-bit on [0, peak]: one image to look at. */
static int write_compare(const char *path, const sci_problem *p, const sci_cube *x, sci_error *err)
{
    const int w = x->w, h = x->h, n = x->n;
    sci_cube *sheet = NULL;
    int rc = sci_cube_new(&sheet, 3 * w, h * n, 1, err);
    if (rc < 0)
        return rc;
    for (int k = 0; k < n; k++)
        for (int y = 0; y < h; y++) {
            const float *t = p->truth->data + ((size_t)k * h + y) * w, *e = x->data + ((size_t)k * h + y) * w;
            float *row = sheet->data + ((size_t)k * h + y) * 3 * (size_t)w;
            for (int c = 0; c < w; c++) {
                row[c] = t[c];
                row[w + c] = e[c];
                row[2 * w + c] = 4 * fabsf(e[c] - t[c]);
            }
        }
    rc = sci_image_write(path, sheet, 0, SCI_PIXEL_U8, 255.0 / p->peak,
                         "truth | reconstruction | difference x4, one row per frame, 0..white", err);
    sci_cube_free(sheet);
    return rc;
}

int sci_recon_store_save(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                         const sci_recon_store_opts *opts, sci_error *err)
{
    static const sci_recon_store_opts defaults = {0};
    const sci_recon_store_opts *o = opts ? opts : &defaults;
    struct stat st;
    const volatile sig_atomic_t *stop = o->stop;
    if (!r->frames)
        return sci_error_set(err, -EINVAL, "%s: no frames to write (%s)", dir,
                             r->error.msg[0] ? r->error.msg : "solver produced none");
    if (stat(dir, &st) == 0 && !(o->flags & SCI_STAGING_OVERWRITE))
        return sci_error_set(err, -EEXIST, "%s: already exists (use --force to replace it)", dir);
    char tmp[4096], path[4300], desc[160];
    if (sci_staging_name(tmp, sizeof tmp, dir) < 0)
        return sci_error_set(err, -ENAMETOOLONG, "%s: name too long", dir);
    json_t *prov = json_pack("{s:s, s:s}", "method", r->method, "problem", p->name);
    /* uncompressed: a solver's float frames hardly compress (2 %) and deflate costs 5-6 ms a 256×256 frame */
    int rc = sci_stack_write_ex(tmp, "frame", "exr", r->frames, SCI_PIXEL_F32, 1.0, prov, 1, err);
    json_decref(prov);
    /* The previews' top: white, or with auto-contrast the frames' 99.5th percentile (a few hot pixels clip). */
    double top = p->peak;
    if (o->preview_auto) {
        static const double q = 0.995;
        double v;
        if (cube_percentiles(r->frames, &q, 1, &v) == 0 && v > 0)
            top = v;
    }
    snprintf(desc, sizeof desc, "preview: 0..%.6g mapped to 0..255 (%s; white is %g)", top,
             o->preview_auto ? "auto-contrast, the frames' 99.5th percentile" : "fixed", p->peak);
    for (int k = 0; k < r->frames->n && rc == 0; k++) {
        if (stop && *stop) {
            rc = sci_error_set(err, SCI_ECANCELED, "%s: interrupted; not written", dir);
            break;
        }
        snprintf(path, sizeof path, "%s/preview_%03d.png", tmp, k);
        rc = sci_image_write(path, r->frames, k, SCI_PIXEL_U8, 255.0 / top, desc, err);
    }
    if (rc == 0 && stop && *stop)
        rc = sci_error_set(err, SCI_ECANCELED, "%s: interrupted; not written", dir);
    if (rc == 0) {
        snprintf(path, sizeof path, "%s/preview.gif", tmp);
        rc = sci_image_write_gif(path, r->frames, 255.0 / top, 125, err);
    }
    if (rc == 0 && p->truth && p->truth->w == r->frames->w && p->truth->h == r->frames->h &&
        p->truth->n == r->frames->n) {
        snprintf(path, sizeof path, "%s/compare.png", tmp);
        rc = write_compare(path, p, r->frames, err);
    }
    if (rc == 0) {
        snprintf(path, sizeof path, "%s/trace.csv", tmp);
        rc = sci_trace_write_csv(&r->trace, path, err);
    }
    if (rc == 0) {
        json_t *s = sci_recon_summary(p, r, params);
        json_object_set_new(s, "preview", json_pack("{s:s, s:[f, f]}", "mode", o->preview_auto ? "auto" : "fixed",
                                                    "range", 0.0, top));
        if (o->extra)
            json_object_update(s, (json_t *)o->extra);
        snprintf(path, sizeof path, "%s/result.json", tmp);
        if (json_dump_file(s, path, JSON_INDENT(2)) != 0)
            rc = sci_error_set(err, -EIO, "%s: cannot write", path);
        json_decref(s);
    }
    if (rc == 0)
        return sci_staging_publish(tmp, dir, o->flags, stop, err);
    sci_staging_remove(tmp);
    return rc;
}
