#include "sim/texture.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "io/image.h"

static const char *const kinds[] = {"constant", "checkerboard", "gradient", "radial", "noise", "image", NULL};

static int parse_values(const sci_json_doc *doc, const json_t *obj, const char *path, sim_texture *t,
                        sci_error *err)
{
    char p[1024];
    const json_t *v = json_object_get(obj, "values");
    if (!v)
        return 0;
    sci_json_path_key(p, sizeof p, path, "values");
    if (!json_is_array(v) || json_array_size(v) != 2)
        return sci_json_fail(doc, err, p, "must be an array of two numbers in [0, 1]");
    double *dst[2] = {&t->a, &t->b};
    for (size_t i = 0; i < 2; i++) {
        const json_t *e = json_array_get(v, i);
        double x = json_is_number(e) ? json_number_value(e) : NAN;
        if (!(x >= 0 && x <= 1)) {
            char q[1040];
            return sci_json_fail(doc, err, sci_json_path_index(q, sizeof q, p, i), "must be a number in [0, 1]");
        }
        *dst[i] = x;
    }
    return 0;
}

int sim_texture_parse(const sci_json_doc *doc, const json_t *obj, const char *path, const char *base_dir,
                      uint64_t seed, sim_texture *t, sci_error *err)
{
    static const char *const allowed[] = {"type", "value", "values", "cell", "angle_rad", "length", "center",
                                          "octaves", "path", "texel", "repeat", NULL};
    memset(t, 0, sizeof *t);
    t->a = 0.2;
    t->b = 0.8;
    t->cell = 16;
    t->length = 64;
    t->octaves = 4;
    t->texel = 1;
    t->repeat = 1;
    t->seed = seed;
    int rc, kind = 0;
    if ((rc = sci_json_check_keys(doc, obj, path, allowed, err)) < 0)
        return rc;
    if ((rc = sci_json_get_enum(doc, obj, path, "type", 1, kinds, &kind, err)) < 0)
        return rc;
    t->kind = (sim_texture_kind)kind;
    if ((rc = parse_values(doc, obj, path, t, err)) < 0)
        return rc;
    if (t->kind == SIM_TEX_CONSTANT) {
        t->a = 0.5;
        if ((rc = sci_json_get_double(doc, obj, path, "value", 0, 0, 1, &t->a, err)) < 0)
            return rc;
        t->b = t->a;
    }
    if ((rc = sci_json_get_double(doc, obj, path, "cell", 0, 1e-6, 1e9, &t->cell, err)) < 0 ||
        (rc = sci_json_get_double(doc, obj, path, "angle_rad", 0, -1e3, 1e3, &t->angle_rad, err)) < 0 ||
        (rc = sci_json_get_double(doc, obj, path, "length", 0, 1e-6, 1e9, &t->length, err)) < 0 ||
        (rc = sci_json_get_double(doc, obj, path, "texel", 0, 1e-6, 1e6, &t->texel, err)) < 0 ||
        (rc = sci_json_get_bool(doc, obj, path, "repeat", 0, &t->repeat, err)) < 0)
        return rc;
    long long oct = t->octaves;
    if ((rc = sci_json_get_int(doc, obj, path, "octaves", 0, 1, 12, &oct, err)) < 0)
        return rc;
    t->octaves = (int)oct;
    const json_t *c = json_object_get(obj, "center");
    if (c) {
        char p[1024];
        sci_json_path_key(p, sizeof p, path, "center");
        if (!json_is_array(c) || json_array_size(c) != 2 || !json_is_number(json_array_get(c, 0)) ||
            !json_is_number(json_array_get(c, 1)))
            return sci_json_fail(doc, err, p, "must be an array of two numbers [u, v]");
        t->cu = json_number_value(json_array_get(c, 0));
        t->cv = json_number_value(json_array_get(c, 1));
    }
    if (t->kind == SIM_TEX_IMAGE) {
        const char *file = NULL;
        if ((rc = sci_json_get_string(doc, obj, path, "path", 1, &file, err)) < 0)
            return rc;
        char full[4096];
        if (file[0] != '/' && base_dir && *base_dir)
            snprintf(full, sizeof full, "%s/%s", base_dir, file);
        else
            snprintf(full, sizeof full, "%s", file);
        int bits = 8;
        sci_cube *img = NULL;
        if ((rc = sci_image_read(full, &img, &bits, err)) < 0) {
            char p[1024];
            char msg[SCI_ERROR_MSG_MAX];
            snprintf(msg, sizeof msg, "%s", err ? err->msg : "cannot read image");
            return sci_json_fail(doc, err, sci_json_path_key(p, sizeof p, path, "path"), "%s", msg);
        }
        if (bits == 8 || bits == 16)
            sci_cube_scale(img, (float)(1.0 / ((1 << bits) - 1)));
        /* Keep only the first page; clamp float images to [0, 1]. */
        size_t fs = sci_cube_frame_size(img);
        for (size_t i = 0; i < fs; i++)
            img->data[i] = img->data[i] < 0 ? 0 : img->data[i] > 1 ? 1 : img->data[i];
        img->n = 1;
        t->image = img;
    }
    return 0;
}

void sim_texture_clear(sim_texture *t)
{
    sci_cube_free(t->image);
    memset(t, 0, sizeof *t);
}

void sim_texture_extent(const sim_texture *t, double *wu, double *hu)
{
    *wu = t->image ? t->image->w * t->texel : 0;
    *hu = t->image ? t->image->h * t->texel : 0;
}

/* Lattice value in [0, 1) from a hash of (seed, octave, i, j): no table, no state. */
static double lattice(uint64_t seed, int oct, int64_t i, int64_t j)
{
    uint64_t z = seed ^ ((uint64_t)oct * 0x9e3779b97f4a7c15ULL) ^ ((uint64_t)i * 0xbf58476d1ce4e5b9ULL) ^
                 ((uint64_t)j * 0x94d049bb133111ebULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

static double smooth(double x) { return x * x * (3 - 2 * x); }

static double value_noise(const sim_texture *t, double u, double v)
{
    double sum = 0, amp = 1, norm = 0, f = 1 / t->cell;
    for (int o = 0; o < t->octaves; o++) {
        double x = u * f, y = v * f, fx = floor(x), fy = floor(y);
        int64_t i = (int64_t)fx, j = (int64_t)fy;
        double sx = smooth(x - fx), sy = smooth(y - fy);
        double v00 = lattice(t->seed, o, i, j), v10 = lattice(t->seed, o, i + 1, j);
        double v01 = lattice(t->seed, o, i, j + 1), v11 = lattice(t->seed, o, i + 1, j + 1);
        double top = v00 + (v10 - v00) * sx, bot = v01 + (v11 - v01) * sx;
        sum += amp * (top + (bot - top) * sy);
        norm += amp;
        amp *= 0.5;
        f *= 2;
    }
    return sum / norm;
}

static float image_at(const sci_cube *img, int x, int y, int repeat)
{
    if (repeat) {
        x %= img->w;
        y %= img->h;
        x += x < 0 ? img->w : 0;
        y += y < 0 ? img->h : 0;
    } else {
        x = x < 0 ? 0 : x >= img->w ? img->w - 1 : x;
        y = y < 0 ? 0 : y >= img->h ? img->h - 1 : y;
    }
    return img->data[(size_t)y * img->w + x];
}

static double clamp01(double x) { return x < 0 ? 0 : x > 1 ? 1 : x; }

float sim_texture_eval(const sim_texture *t, double u, double v)
{
    double s;
    switch (t->kind) {
    case SIM_TEX_CONSTANT:
        return (float)t->a;
    case SIM_TEX_CHECKERBOARD: {
        int64_t i = (int64_t)floor(u / t->cell), j = (int64_t)floor(v / t->cell);
        return (float)(((i + j) & 1) ? t->b : t->a);
    }
    case SIM_TEX_GRADIENT:
        s = clamp01((u * cos(t->angle_rad) + v * sin(t->angle_rad)) / t->length);
        break;
    case SIM_TEX_RADIAL:
        s = clamp01(hypot(u - t->cu, v - t->cv) / t->length);
        break;
    case SIM_TEX_NOISE:
        s = value_noise(t, u, v);
        break;
    case SIM_TEX_IMAGE: {
        /* Bilinear between texel centres. */
        double x = u / t->texel - 0.5, y = v / t->texel - 0.5, fx = floor(x), fy = floor(y);
        int i = (int)fx, j = (int)fy;
        double ax = x - fx, ay = y - fy;
        const sci_cube *img = t->image;
        double top = image_at(img, i, j, t->repeat) * (1 - ax) + image_at(img, i + 1, j, t->repeat) * ax;
        double bot = image_at(img, i, j + 1, t->repeat) * (1 - ax) + image_at(img, i + 1, j + 1, t->repeat) * ax;
        return (float)(top * (1 - ay) + bot * ay);
    }
    default:
        return 0;
    }
    return (float)(t->a + (t->b - t->a) * s);
}
