#include "io/image.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/file.h"
#include "base/json.h"
#include "io/gif.h"
#include "io/oiio_shim.h"

const char *sci_pixel_type_name(sci_pixel_type t)
{
    switch (t) {
    case SCI_PIXEL_U8: return "u8";
    case SCI_PIXEL_U16: return "u16";
    case SCI_PIXEL_HALF: return "half";
    case SCI_PIXEL_F32: return "f32";
    }
    return NULL;
}

static int pixel_type_parse(const char *s, sci_pixel_type *t)
{
    for (int i = SCI_PIXEL_U8; i <= SCI_PIXEL_F32; i++)
        if (strcmp(s, sci_pixel_type_name((sci_pixel_type)i)) == 0) {
            *t = (sci_pixel_type)i;
            return 0;
        }
    return -EINVAL;
}

int sci_image_read(const char *path, sci_cube **out, int *bits, sci_error *err)
{
    *out = NULL;
    if (access(path, R_OK) != 0)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    float *data = NULL;
    int w, h, n, b;
    char msg[SCI_ERROR_MSG_MAX];
    int rc = sci_oiio_read(path, &data, &w, &h, &n, &b, msg, sizeof msg);
    if (rc < 0)
        return sci_error_set(err, rc, "%s", msg);
    sci_cube *c;
    rc = sci_cube_new(&c, w, h, n, err);
    if (rc == 0) {
        memcpy(c->data, data, sci_cube_count(c) * sizeof(float));
        *out = c;
        if (bits)
            *bits = b;
    }
    free(data);
    return rc;
}

/* Image files are parts of output folders that their writers stage and sync as a whole (io/staging.h), so each
 * file is replaced atomically without an fsync of its own. */
#define IMAGE_FILE_FLAGS SCI_FILE_NO_SYNC

typedef struct image_job {
    const float *buf;
    int w, h, channels, type, uncompressed;
    const char *description;
} image_job;

static int image_write_named(const char *tmp, void *user, sci_error *err)
{
    const image_job *j = user;
    char msg[SCI_ERROR_MSG_MAX];
    int rc = sci_oiio_write(tmp, j->buf, j->w, j->h, j->channels, j->type, j->description, j->uncompressed, msg,
                            sizeof msg);
    return rc < 0 ? sci_error_set(err, rc, "%s", msg) : 0;
}

/* One image from `channels` frames of `c` starting at `k0` (1: grey, 3: RGB), interleaved per pixel, scaled,
 * and for integer types rounded and clamped; written to a temporary name and renamed. */
static int write_frames(const char *path, const sci_cube *c, int k0, int channels, sci_pixel_type type, double scale,
                        const char *description, int uncompressed, sci_error *err)
{
    if (!sci_pixel_type_name(type))
        return sci_error_set(err, -EINVAL, "%s: invalid pixel type", path);
    const size_t fs = sci_cube_frame_size(c);
    float *buf = malloc((size_t)channels * fs * sizeof *buf);
    if (!buf)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
    const double hi = type == SCI_PIXEL_U8 ? 255 : 65535;
    for (int ch = 0; ch < channels; ch++) {
        const float *src = sci_cube_frame(c, k0 + ch);
        for (size_t i = 0; i < fs; i++) {
            double v = (double)src[i] * scale;
            if (type == SCI_PIXEL_U8 || type == SCI_PIXEL_U16) {
                v = isnan(v) ? 0 : nearbyint(v);
                v = v < 0 ? 0 : (v > hi ? hi : v);
            }
            buf[(size_t)channels * i + ch] = (float)v;
        }
    }
    const image_job job = {buf, c->w, c->h, channels, (int)type, uncompressed, description};
    int rc = sci_file_write_atomic_named(path, 0644, IMAGE_FILE_FLAGS, image_write_named, (void *)&job, err);
    free(buf);
    return rc;
}

int sci_image_write(const char *path, const sci_cube *c, int k, sci_pixel_type type, double scale,
                    const char *description, sci_error *err)
{
    if (k < 0 || k >= c->n)
        return sci_error_set(err, -EINVAL, "%s: frame %d out of range (cube has %d)", path, k, c->n);
    return write_frames(path, c, k, 1, type, scale, description, 0, err);
}

int sci_image_write_rgb(const char *path, const sci_cube *rgb, int f, sci_pixel_type type, double scale,
                        sci_error *err)
{
    if (f < 0 || 3 * f + 2 >= rgb->n)
        return sci_error_set(err, -EINVAL, "%s: RGB frame %d out of range (cube has %d channels)", path, f, rgb->n);
    return write_frames(path, rgb, 3 * f, 3, type, scale, NULL, 0, err);
}

void sci_image_exr_threads(int threads) { sci_oiio_exr_threads(threads); }

/* A preview value (already scaled) as 8 bits: NaN black, rounded, clamped to [0, 255]. */
static unsigned char grey8(double v)
{
    v = isnan(v) ? 0 : nearbyint(v);
    return (unsigned char)(v < 0 ? 0 : (v > 255 ? 255 : v));
}

/* The smallest f with ceil(w/f)·ceil(h/f) <= SCI_GIF_MAX_PIXELS and both sides <= 65535. */
static int gif_factor(int w, int h)
{
    int f = 1;
    for (;; f++) {
        const long long gw = (w + f - 1) / f, gh = (h + f - 1) / f;
        if (gw * gh <= SCI_GIF_MAX_PIXELS && gw <= 65535 && gh <= 65535)
            return f;
    }
}

int sci_image_write_gif(const char *path, const sci_cube *c, double scale, int delay_ms, sci_error *err)
{
    return sci_image_write_gif_opt(path, c, scale, delay_ms, NULL, err);
}

typedef struct gif_job {
    const unsigned char *buf;
    int w, h, n, delay_ms;
} gif_job;

static int gif_write_named(const char *tmp, void *user, sci_error *err)
{
    const gif_job *j = user;
    return sci_gif_write_grey(tmp, j->buf, j->w, j->h, j->n, j->delay_ms, err);
}

int sci_image_write_gif_opt(const char *path, const sci_cube *c, double scale, int delay_ms, int *factor,
                            sci_error *err)
{
    const int f = gif_factor(c->w, c->h);
    const int gw = (c->w + f - 1) / f, gh = (c->h + f - 1) / f;
    const size_t gfs = (size_t)gw * (size_t)gh;
    unsigned char *buf = malloc(gfs * (size_t)c->n);
    if (!buf)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
    for (int k = 0; k < c->n && f == 1; k++) { /* full size: one pixel each, no block loops */
        const float *src = sci_cube_frame(c, k);
        unsigned char *dst = buf + (size_t)k * gfs;
        for (size_t i = 0; i < gfs; i++)
            dst[i] = grey8((double)src[i] * scale);
    }
    for (int k = 0; k < c->n && f > 1; k++) {
        const float *src = sci_cube_frame(c, k);
        for (int gy = 0; gy < gh; gy++)
            for (int gx = 0; gx < gw; gx++) {
                /* mean of the block (edge blocks are smaller); NaN counts as black */
                double acc = 0;
                int cnt = 0;
                for (int y = gy * f; y < gy * f + f && y < c->h; y++)
                    for (int x = gx * f; x < gx * f + f && x < c->w; x++, cnt++) {
                        const float v = src[(size_t)y * c->w + x];
                        acc += isnan(v) ? 0 : v;
                    }
                buf[(size_t)k * gfs + (size_t)gy * gw + gx] = grey8(acc / cnt * scale);
            }
    }
    const gif_job job = {buf, gw, gh, c->n, delay_ms};
    int rc = sci_file_write_atomic_named(path, 0644, IMAGE_FILE_FLAGS, gif_write_named, (void *)&job, err);
    free(buf);
    if (factor)
        *factor = f;
    return rc;
}

static int mkdir_p(const char *dir, sci_error *err)
{
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", dir);
    for (char *p = buf + 1; *p; p++) {
        if (*p != '/')
            continue;
        *p = 0;
        if (mkdir(buf, 0755) != 0 && errno != EEXIST)
            return sci_error_set(err, -errno, "%s: %s", buf, strerror(errno));
        *p = '/';
    }
    if (mkdir(buf, 0755) != 0 && errno != EEXIST)
        return sci_error_set(err, -errno, "%s: %s", buf, strerror(errno));
    return 0;
}

int sci_stack_write(const char *dir, const char *stem, const char *ext, const sci_cube *c, sci_pixel_type type,
                    double scale, const json_t *provenance, sci_error *err)
{
    return sci_stack_write_ex(dir, stem, ext, c, type, scale, provenance, 0, err);
}

int sci_stack_write_ex(const char *dir, const char *stem, const char *ext, const sci_cube *c, sci_pixel_type type,
                       double scale, const json_t *provenance, int uncompressed, sci_error *err)
{
    int rc = mkdir_p(dir, err);
    if (rc < 0)
        return rc;
    json_t *files = json_array();
    char name[512], path[4096];
    for (int k = 0; k < c->n && rc == 0; k++) {
        snprintf(name, sizeof name, "%s_%03d.%s", stem, k, ext);
        snprintf(path, sizeof path, "%s/%s", dir, name);
        rc = write_frames(path, c, k, 1, type, scale, NULL, uncompressed, err);
        json_array_append_new(files, json_string(name));
    }
    if (rc < 0) {
        json_decref(files);
        return rc;
    }
    json_t *side = json_pack("{s:s, s:i, s:i, s:i, s:i, s:s, s:f, s:o}", "format", "scicap-stack", "version", 1, "w",
                             c->w, "h", c->h, "n", c->n, "type", sci_pixel_type_name(type), "scale", scale, "files",
                             files);
    if (!side)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", dir);
    if (provenance)
        json_object_set_new(side, "provenance", json_deep_copy(provenance));
    snprintf(path, sizeof path, "%s/%s.json", dir, stem);
    rc = sci_json_write_atomic(path, side, JSON_INDENT(2) | JSON_SORT_KEYS, 0644, IMAGE_FILE_FLAGS, err);
    json_decref(side);
    return rc;
}

int sci_stack_read(const char *sidecar_path, sci_cube **out, json_t **provenance, sci_error *err)
{
    return sci_stack_read_opts(sidecar_path, NULL, out, provenance, err);
}

int sci_stack_read_opts(const char *sidecar_path, const sci_io_limits *lim, sci_cube **out, json_t **provenance,
                        sci_error *err)
{
    *out = NULL;
    if (provenance)
        *provenance = NULL;
    json_error_t je;
    json_t *side = json_load_file(sidecar_path, 0, &je);
    if (!side) {
        if (access(sidecar_path, R_OK) != 0)
            return sci_error_set(err, -errno, "%s: %s", sidecar_path, strerror(errno));
        return sci_error_set(err, SCI_EFORMAT, "%s:%d:%d: %s", sidecar_path, je.line, je.column, je.text);
    }
    int rc = 0;
    json_int_t w = 0, h = 0, n = 0;
    const char *type = NULL, *format = NULL;
    double scale = 1;
    json_t *files = NULL;
    if (json_unpack_ex(side, &je, 0, "{s:s, s:I, s:I, s:I, s:s, s:F, s:o}", "format", &format, "w", &w, "h", &h, "n",
                       &n, "type", &type, "scale", &scale, "files", &files) != 0) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: not a scicap stack sidecar (%s)", sidecar_path, je.text);
        goto out;
    }
    sci_pixel_type t;
    if (strcmp(format, "scicap-stack") != 0 || pixel_type_parse(type, &t) < 0 || !json_is_array(files) ||
        (json_int_t)json_array_size(files) != n || !(scale > 0) || !isfinite(scale)) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: inconsistent stack sidecar (format, type, scale or file list)",
                           sidecar_path);
        goto out;
    }
    if (w < 1 || h < 1 || n < 1 || w > 1 << 30 || h > 1 << 30 || n > 1 << 30) {
        rc = sci_error_set(err, SCI_ESHAPE, "%s: unusable size %lldx%lldx%lld", sidecar_path, (long long)w,
                           (long long)h, (long long)n);
        goto out;
    }
    if (lim && (rc = sci_io_limits_check_cube(lim, sidecar_path, w, h, n, err)) < 0)
        goto out;
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", sidecar_path);
    char *slash = strrchr(dir, '/');
    if (slash)
        slash[1] = 0;
    else
        dir[0] = 0;
    /* The first frame's header before the allocation: the sidecar's w×h is a claim, the file is the fact. */
    const char *first = json_string_value(json_array_get(files, 0));
    if (first && !strchr(first, '/')) {
        char fpath[8192], msg[SCI_ERROR_MSG_MAX];
        int fw = 0, fh = 0;
        snprintf(fpath, sizeof fpath, "%s%s", dir, first);
        if (access(fpath, R_OK) != 0) {
            rc = sci_error_set(err, -errno, "%s: %s", fpath, strerror(errno));
            goto out;
        }
        if ((rc = sci_oiio_probe(fpath, &fw, &fh, msg, sizeof msg)) < 0) {
            rc = sci_error_set(err, rc, "%s", msg);
            goto out;
        }
        if (fw != w || fh != h) {
            rc = sci_error_set(err, SCI_ESHAPE, "%s: is %dx%d but the sidecar %s says %lldx%lld", fpath, fw, fh,
                               sidecar_path, (long long)w, (long long)h);
            goto out;
        }
    }
    if ((rc = sci_cube_new(out, (int)w, (int)h, (int)n, err)) < 0)
        goto out;
    for (json_int_t k = 0; k < n && rc == 0; k++) {
        const char *name = json_string_value(json_array_get(files, (size_t)k));
        char path[8192];
        if (!name || strchr(name, '/')) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s: file entry %lld is not a plain file name", sidecar_path,
                               (long long)k);
            break;
        }
        snprintf(path, sizeof path, "%s%s", dir, name);
        sci_cube *img = NULL;
        if ((rc = sci_image_read(path, &img, NULL, err)) < 0)
            break;
        if (img->w != w || img->h != h || img->n != 1)
            rc = sci_error_set(err, SCI_ESHAPE, "%s: is %dx%dx%d but the sidecar %s says %lldx%lld", path, img->w,
                               img->h, img->n, sidecar_path, (long long)w, (long long)h);
        else
            for (size_t i = 0; i < sci_cube_frame_size(img); i++)
                sci_cube_frame(*out, (int)k)[i] = (float)(img->data[i] / scale);
        sci_cube_free(img);
    }
    if (rc == 0 && provenance) {
        json_t *p = json_object_get(side, "provenance");
        *provenance = p ? json_incref(p) : NULL;
    }
out:
    if (rc < 0) {
        sci_cube_free(*out);
        *out = NULL;
    }
    json_decref(side);
    return rc;
}
