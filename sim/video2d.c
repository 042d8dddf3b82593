#include "sim/video2d.h"

#include "base/json_fields.h"
#include "recon/demosaic.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const shapes[] = {"rect", "disc", "polygon", NULL};

static int get_pair(const sci_json_doc *doc, const json_t *obj, const char *path, const char *key, double *a,
                    double *b, sci_error *err)
{
    const json_t *v = json_object_get(obj, key);
    if (!v)
        return 1;
    char p[1024];
    sci_json_path_key(p, sizeof p, path, key);
    if (!json_is_array(v) || json_array_size(v) != 2 || !json_is_number(json_array_get(v, 0)) ||
        !json_is_number(json_array_get(v, 1)))
        return sci_json_fail(doc, err, p, "must be an array of two numbers");
    *a = json_number_value(json_array_get(v, 0));
    *b = json_number_value(json_array_get(v, 1));
    if (!isfinite(*a) || !isfinite(*b) || fabs(*a) > 1e7 || fabs(*b) > 1e7)
        return sci_json_fail(doc, err, p, "numbers must be finite and within ±1e7");
    return 0;
}

/* An optional [r, g, b] in [0, 1]: 1 when absent, 0 when read. */
static int get_rgb(const sci_json_doc *doc, const json_t *obj, const char *path, const char *key, double out[3],
                   sci_error *err)
{
    const json_t *v = json_object_get(obj, key);
    if (!v)
        return 1;
    char p[1024];
    sci_json_path_key(p, sizeof p, path, key);
    if (!json_is_array(v) || json_array_size(v) != 3)
        return sci_json_fail(doc, err, p, "must be an array of three numbers [r, g, b] in [0, 1]");
    for (size_t i = 0; i < 3; i++) {
        const json_t *e = json_array_get(v, i);
        double x = json_is_number(e) ? json_number_value(e) : -1;
        if (!(x >= 0 && x <= 1))
            return sci_json_fail(doc, err, p, "must be an array of three numbers [r, g, b] in [0, 1]");
        out[i] = x;
    }
    return 0;
}

/* A layer's motion and order; its shape, size, position, velocity and texture are read by hand (pairs, lists). */
static const sci_json_field layer_fields[] = {
    {"angle_rad", SCI_JSON_DOUBLE, offsetof(sim_layer, angle_rad), -1e3, 1e3, .help = "rotation at frame 0"},
    {"spin_rad", SCI_JSON_DOUBLE, offsetof(sim_layer, spin_rad), -10, 10, .help = "rotation per frame"},
    {"scale", SCI_JSON_DOUBLE, offsetof(sim_layer, scale), 1e-3, 1e3, .help = "size multiplier at frame 0"},
    {"scale_rate", SCI_JSON_DOUBLE, offsetof(sim_layer, scale_rate), -10, 10, .help = "scale change per frame"},
    {"depth", SCI_JSON_DOUBLE, offsetof(sim_layer, depth), -1e9, 1e9, .help = "larger is nearer (file order)"},
};

static int parse_layer(const sci_json_doc *doc, const json_t *o, const char *path, const char *base_dir, int w,
                       int h, uint64_t seed, int index, sim_layer *L, sci_error *err)
{
    static const char *const allowed[] = {"shape", "texture", "size", "sides", "vertices", "position",
                                          "velocity", "angle_rad", "spin_rad", "scale", "scale_rate", "depth",
                                          "color", NULL};
    int rc, shape = 0;
    memset(L, 0, sizeof *L);
    L->size_w = w;
    L->size_h = h;
    L->x = 0.5 * w;
    L->y = 0.5 * h;
    L->scale = 1;
    L->depth = -index; /* file order: later layers in front */
    L->color[0] = L->color[1] = L->color[2] = 1;
    if ((rc = sci_json_check_keys(doc, o, path, allowed, err)) < 0)
        return rc;
    if ((rc = sci_json_get_enum(doc, o, path, "shape", 0, shapes, &shape, err)) < 0)
        return rc;
    L->shape = (sim_shape)shape;
    if ((rc = get_pair(doc, o, path, "size", &L->size_w, &L->size_h, err)) < 0)
        return rc;
    if (!(L->size_w > 0 && L->size_h > 0)) {
        char p[1024];
        return sci_json_fail(doc, err, sci_json_path_key(p, sizeof p, path, "size"), "must be > 0");
    }
    if ((rc = get_pair(doc, o, path, "position", &L->x, &L->y, err)) < 0 ||
        (rc = get_pair(doc, o, path, "velocity", &L->vx, &L->vy, err)) < 0 ||
        (rc = sci_json_fields_read(doc, o, path, layer_fields, SCI_JSON_FIELDS_COUNT(layer_fields), L, err)) < 0)
        return rc;
    if (L->shape == SIM_SHAPE_POLYGON) {
        const json_t *vs = json_object_get(o, "vertices");
        char p[1024];
        if (vs) {
            sci_json_path_key(p, sizeof p, path, "vertices");
            if (!json_is_array(vs) || json_array_size(vs) < 3 || json_array_size(vs) > SIM_POLY_MAX)
                return sci_json_fail(doc, err, p, "must be an array of 3 to %d [x, y] pairs", SIM_POLY_MAX);
            L->npoly = (int)json_array_size(vs);
            for (int i = 0; i < L->npoly; i++) {
                const json_t *e = json_array_get(vs, (size_t)i);
                char q[1100];
                sci_json_path_index(q, sizeof q, p, (size_t)i);
                if (!json_is_array(e) || json_array_size(e) != 2 || !json_is_number(json_array_get(e, 0)) ||
                    !json_is_number(json_array_get(e, 1)))
                    return sci_json_fail(doc, err, q, "must be an array of two numbers [x, y] (pixels from the centre)");
                L->poly[2 * i] = json_number_value(json_array_get(e, 0));
                L->poly[2 * i + 1] = json_number_value(json_array_get(e, 1));
            }
        } else {
            long long sides = 0;
            if ((rc = sci_json_get_int(doc, o, path, "sides", 0, 3, SIM_POLY_MAX, &sides, err)) < 0)
                return rc;
            if (rc == 1)
                return sci_json_fail(doc, err, path, "a polygon needs \"vertices\" or \"sides\"");
            L->npoly = (int)sides;
            for (int i = 0; i < L->npoly; i++) {
                double a = 2 * M_PI * i / L->npoly - M_PI / 2;
                L->poly[2 * i] = 0.5 * L->size_w * cos(a);
                L->poly[2 * i + 1] = 0.5 * L->size_h * sin(a);
            }
        }
    }
    if ((rc = get_rgb(doc, o, path, "color", L->color, err)) < 0)
        return rc;
    const json_t *tex = json_object_get(o, "texture");
    char p[1024];
    sci_json_path_key(p, sizeof p, path, "texture");
    if (!tex)
        return sci_json_fail(doc, err, p, "required key is missing");
    /* Each texture gets its own noise seed, derived from the scene seed and the layer's index. */
    uint64_t tseed = seed * 0x9e3779b97f4a7c15ULL + 0x1000u + (uint64_t)index;
    if ((rc = sim_texture_parse(doc, tex, p, base_dir, tseed, &L->tex, err)) < 0)
        return rc;
    if (L->tex.image && !json_object_get(o, "size")) /* an image layer defaults to the image's own size */
        sim_texture_extent(&L->tex, &L->size_w, &L->size_h);
    return 0;
}

static int by_depth(const void *a, const void *b)
{
    const sim_layer *x = a, *y = b;
    return x->depth < y->depth ? -1 : x->depth > y->depth ? 1 : 0;
}

int sim_video2d_parse(const sci_json_doc *doc, const json_t *root, const char *base_dir, int w, int h,
                      uint64_t seed, sim_video2d *v, sci_error *err)
{
    memset(v, 0, sizeof *v);
    int rc;
    if ((rc = sci_json_get_double(doc, root, "", "background", 0, 0, 1, &v->background, err)) < 0)
        return rc;
    v->background_rgb[0] = v->background_rgb[1] = v->background_rgb[2] = v->background;
    if ((rc = get_rgb(doc, root, "", "background_color", v->background_rgb, err)) < 0)
        return rc;
    const json_t *layers = json_object_get(root, "layers");
    if (!layers)
        return sci_json_fail(doc, err, "layers", "required key is missing (a video2d scene needs layers)");
    if (!json_is_array(layers) || json_array_size(layers) < 1 || json_array_size(layers) > SIM_LAYERS_MAX)
        return sci_json_fail(doc, err, "layers", "must be an array of 1 to %d layer objects", SIM_LAYERS_MAX);
    for (size_t i = 0; i < json_array_size(layers); i++) {
        char p[64];
        sci_json_path_index(p, sizeof p, "layers", i);
        rc = parse_layer(doc, json_array_get(layers, i), p, base_dir, w, h, seed, (int)i, &v->layer[i], err);
        v->nlayers = (int)i + 1;
        if (rc < 0) {
            sim_video2d_clear(v);
            return rc;
        }
    }
    /* Near to far by a stable insertion sort (few layers). */
    for (int i = 1; i < v->nlayers; i++) {
        sim_layer tmp = v->layer[i];
        int j = i - 1;
        while (j >= 0 && by_depth(&v->layer[j], &tmp) > 0) {
            v->layer[j + 1] = v->layer[j];
            j--;
        }
        v->layer[j + 1] = tmp;
    }
    /* Equal depths: file order says later is in front, i.e. nearer; the stable sort kept file order, so reverse
     * runs of equal depth. */
    for (int i = 0; i < v->nlayers;) {
        int j = i;
        while (j + 1 < v->nlayers && v->layer[j + 1].depth == v->layer[i].depth)
            j++;
        for (int a = i, b = j; a < b; a++, b--) {
            sim_layer tmp = v->layer[a];
            v->layer[a] = v->layer[b];
            v->layer[b] = tmp;
        }
        i = j + 1;
    }
    return 0;
}

void sim_video2d_clear(sim_video2d *v)
{
    for (int i = 0; i < v->nlayers; i++)
        sim_texture_clear(&v->layer[i].tex);
    v->nlayers = 0;
}

/* Per-layer placement at one instant, precomputed so the per-sample work is a few multiplies. */
typedef struct placed {
    double cx, cy, c, s, inv_scale;
} placed;

static int inside(const sim_layer *L, double qx, double qy)
{
    switch (L->shape) {
    case SIM_SHAPE_RECT:
        return fabs(qx) <= 0.5 * L->size_w && fabs(qy) <= 0.5 * L->size_h;
    case SIM_SHAPE_DISC: {
        double r = 0.5 * L->size_w;
        return qx * qx + qy * qy <= r * r;
    }
    case SIM_SHAPE_POLYGON: {
        /* Even-odd rule. */
        int in = 0;
        for (int i = 0, j = L->npoly - 1; i < L->npoly; j = i++) {
            double xi = L->poly[2 * i], yi = L->poly[2 * i + 1], xj = L->poly[2 * j], yj = L->poly[2 * j + 1];
            if ((yi > qy) != (yj > qy) && qx < (xj - xi) * (qy - yi) / (yj - yi) + xi)
                in = !in;
        }
        return in;
    }
    }
    return 0;
}

void sim_video2d_render(const sim_video2d *v, int w, int h, int s, double t, float *out)
{
    sim_video2d_render_color(v, w, h, s, t, SCI_CFA_NONE, -1, out);
}

void sim_video2d_render_color(const sim_video2d *v, int w, int h, int s, double t, int cfa, int channel, float *out)
{
    const int colour = channel >= 0 || cfa != SCI_CFA_NONE;
    placed pl[SIM_LAYERS_MAX];
    for (int i = 0; i < v->nlayers; i++) {
        const sim_layer *L = &v->layer[i];
        double sc = L->scale + L->scale_rate * t, a = L->angle_rad + L->spin_rad * t;
        sc = sc < 0.01 ? 0.01 : sc;
        pl[i] = (placed){L->x + L->vx * t, L->y + L->vy * t, cos(a), sin(a), 1 / sc};
    }
    double inv_s2 = 1.0 / ((double)s * s);
#pragma omp parallel for schedule(static)
    for (int y = 0; y < h; y++) {
        for (int x = 0; x < w; x++) {
            double acc = 0;
            const int ch = channel >= 0 ? channel : cfa != SCI_CFA_NONE ? sci_cfa_color((sci_cfa)cfa, x, y) : 0;
            for (int j = 0; j < s; j++)
                for (int i = 0; i < s; i++) {
                    double px = x + (i + 0.5) / s, py = y + (j + 0.5) / s;
                    double val = colour ? v->background_rgb[ch] : v->background;
                    for (int l = 0; l < v->nlayers; l++) {
                        const placed *P = &pl[l];
                        double dx = px - P->cx, dy = py - P->cy;
                        /* Rotate by −angle into the layer's frame, then undo its scale. */
                        double qx = (P->c * dx + P->s * dy) * P->inv_scale;
                        double qy = (-P->s * dx + P->c * dy) * P->inv_scale;
                        const sim_layer *L = &v->layer[l];
                        if (inside(L, qx, qy)) {
                            val = sim_texture_eval(&L->tex, qx + 0.5 * L->size_w, qy + 0.5 * L->size_h);
                            if (colour)
                                val *= L->color[ch];
                            break;
                        }
                    }
                    acc += val;
                }
            out[(size_t)y * w + x] = (float)(acc * inv_s2);
        }
    }
}
