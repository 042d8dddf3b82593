#include "sim/static3d.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "base/json_fields.h"
#include "sim/pose.h"

static const char *const kinds[] = {"plane", "box", "sphere", NULL};

static int get_vec(const sci_json_doc *doc, const json_t *obj, const char *path, const char *key, int n,
                   double *out, sci_error *err)
{
    const json_t *v = json_object_get(obj, key);
    if (!v)
        return 1;
    char p[1024];
    sci_json_path_key(p, sizeof p, path, key);
    if (!json_is_array(v) || (int)json_array_size(v) != n)
        return sci_json_fail(doc, err, p, "must be an array of %d numbers", n);
    for (int i = 0; i < n; i++) {
        const json_t *e = json_array_get(v, (size_t)i);
        if (!json_is_number(e) || !isfinite(json_number_value(e)) || fabs(json_number_value(e)) > 1e9) {
            char q[1100];
            return sci_json_fail(doc, err, sci_json_path_index(q, sizeof q, p, (size_t)i),
                                 "must be a finite number within ±1e9");
        }
        out[i] = json_number_value(e);
    }
    return 0;
}

static int parse_object(const sci_json_doc *doc, const json_t *o, const char *path, const char *base_dir,
                        uint64_t seed, int index, sim_object *ob, sci_error *err)
{
    static const char *const allowed[] = {"type", "center", "rotation_rad", "size", "radius", "uv_scale",
                                          "texture", NULL};
    int rc, kind = 0;
    memset(ob, 0, sizeof *ob);
    double rot[3] = {0, 0, 0}, size[3] = {1, 1, 1};
    ob->uv_scale = 32;
    if ((rc = sci_json_check_keys(doc, o, path, allowed, err)) < 0 ||
        (rc = sci_json_get_enum(doc, o, path, "type", 1, kinds, &kind, err)) < 0)
        return rc;
    ob->kind = (sim_object_kind)kind;
    if ((rc = get_vec(doc, o, path, "center", 3, ob->center, err)) < 0 ||
        (rc = get_vec(doc, o, path, "rotation_rad", 3, rot, err)) < 0 ||
        (rc = sci_json_get_double(doc, o, path, "uv_scale", 0, 1e-6, 1e6, &ob->uv_scale, err)) < 0)
        return rc;
    char p[1024];
    if (ob->kind == SIM_OBJ_SPHERE) {
        if ((rc = sci_json_get_double(doc, o, path, "radius", 1, 1e-9, 1e9, &size[0], err)) < 0)
            return rc;
    } else {
        int n = ob->kind == SIM_OBJ_PLANE ? 2 : 3;
        if ((rc = get_vec(doc, o, path, "size", n, size, err)) < 0)
            return rc;
        if (rc == 1)
            return sci_json_fail(doc, err, sci_json_path_key(p, sizeof p, path, "size"),
                                 "required key is missing (%s: [%s])", kinds[kind], n == 2 ? "w, h" : "w, h, d");
        for (int i = 0; i < n; i++)
            if (!(size[i] > 0))
                return sci_json_fail(doc, err, sci_json_path_key(p, sizeof p, path, "size"),
                                     "every extent must be > 0");
    }
    for (int i = 0; i < 3; i++)
        ob->half[i] = 0.5 * size[i];
    if (ob->kind == SIM_OBJ_SPHERE)
        ob->half[0] = size[0];
    sim_rot_exp(rot, ob->R);
    const json_t *tex = json_object_get(o, "texture");
    sci_json_path_key(p, sizeof p, path, "texture");
    if (!tex)
        return sci_json_fail(doc, err, p, "required key is missing");
    return sim_texture_parse(doc, tex, p, base_dir, seed * 0x9e3779b97f4a7c15ULL + 0x2000u + (uint64_t)index,
                             &ob->tex, err);
}

static int parse_pose(const sci_json_doc *doc, const json_t *o, const char *path, double T[12], sci_error *err)
{
    static const char *const allowed[] = {"position", "look_at", "up", "rotation_rad", "matrix", NULL};
    int rc;
    if ((rc = sci_json_check_keys(doc, o, path, allowed, err)) < 0)
        return rc;
    if (json_object_get(o, "matrix")) {
        if ((rc = get_vec(doc, o, path, "matrix", 12, T, err)) < 0)
            return rc;
        /* Check the rotation part is orthonormal with det +1. */
        double md = 0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double d = T[4 * i] * T[4 * j] + T[4 * i + 1] * T[4 * j + 1] + T[4 * i + 2] * T[4 * j + 2];
                md = fmax(md, fabs(d - (i == j)));
            }
        double det = T[0] * (T[5] * T[10] - T[6] * T[9]) - T[1] * (T[4] * T[10] - T[6] * T[8]) +
                     T[2] * (T[4] * T[9] - T[5] * T[8]);
        char p[1024];
        if (md > 1e-6 || det < 0)
            return sci_json_fail(doc, err, sci_json_path_key(p, sizeof p, path, "matrix"),
                                 "the 3×3 part must be a rotation (orthonormal to 1e-6, det +1)");
        return 0;
    }
    double pos[3] = {0, 0, 0}, at[3], up[3] = {0, 1, 0}, rot[3] = {0, 0, 0};
    if ((rc = get_vec(doc, o, path, "position", 3, pos, err)) < 0)
        return rc;
    if (rc == 1)
        return sci_json_fail(doc, err, path, "a pose needs \"position\" (with \"look_at\" or \"rotation_rad\") or \"matrix\"");
    if ((rc = get_vec(doc, o, path, "up", 3, up, err)) < 0)
        return rc;
    if ((rc = get_vec(doc, o, path, "look_at", 3, at, err)) < 0)
        return rc;
    if (rc == 0) {
        if (json_object_get(o, "rotation_rad"))
            return sci_json_fail(doc, err, path, "give either \"look_at\" or \"rotation_rad\", not both");
        if (sim_pose_look_at(pos, at, up, T) < 0)
            return sci_json_fail(doc, err, path, "look_at equals position, or up is parallel to the view line");
        return 0;
    }
    if ((rc = get_vec(doc, o, path, "rotation_rad", 3, rot, err)) < 0)
        return rc;
    double R[9];
    sim_rot_exp(rot, R);
    for (int i = 0; i < 3; i++) {
        T[4 * i] = R[3 * i];
        T[4 * i + 1] = R[3 * i + 1];
        T[4 * i + 2] = R[3 * i + 2];
        T[4 * i + 3] = pos[i];
    }
    return 0;
}

/* The camera's intrinsics after fx (fy defaults to fx, so fx is read first) and its clip range. */
static const sci_json_field camera_fields[] = {
    {"fy", SCI_JSON_DOUBLE, offsetof(sim_static3d, fy), 1e-3, 1e7, .help = "focal length, pixels (default fx)"},
    {"cx", SCI_JSON_DOUBLE, offsetof(sim_static3d, cx), -1e6, 1e6, .help = "principal point, pixels"},
    {"cy", SCI_JSON_DOUBLE, offsetof(sim_static3d, cy), -1e6, 1e6, .help = "principal point, pixels"},
    {"near", SCI_JSON_DOUBLE, offsetof(sim_static3d, near_m), 0, 1e9, .help = "near clip, scene units"},
    {"far", SCI_JSON_DOUBLE, offsetof(sim_static3d, far_m), 0, 1e12, .help = "far clip, scene units"},
};

static int parse_camera(const sci_json_doc *doc, const json_t *root, int w, int h, int frames, sim_static3d *s,
                        sci_error *err)
{
    static const char *const allowed[] = {"fx", "fy", "cx", "cy", "near", "far", "start", "end", "poses", NULL};
    const json_t *c = json_object_get(root, "camera");
    if (!c)
        return sci_json_fail(doc, err, "camera", "required key is missing (a static3d scene needs a camera)");
    int rc;
    s->fx = s->fy = w;
    s->cx = 0.5 * w;
    s->cy = 0.5 * h;
    s->near_m = 0.05;
    s->far_m = 100;
    if ((rc = sci_json_check_keys(doc, c, "camera", allowed, err)) < 0 ||
        (rc = sci_json_get_double(doc, c, "camera", "fx", 0, 1e-3, 1e7, &s->fx, err)) < 0)
        return rc;
    s->fy = s->fx;
    if ((rc = sci_json_fields_read(doc, c, "camera", camera_fields, SCI_JSON_FIELDS_COUNT(camera_fields), s, err)) <
        0)
        return rc;
    if (!(s->far_m > s->near_m))
        return sci_json_fail(doc, err, "camera.far", "must be greater than near (%g)", s->near_m);
    s->pose = calloc((size_t)frames, sizeof *s->pose);
    if (!s->pose)
        return sci_error_set(err, -ENOMEM, "out of memory for %d camera poses", frames);
    s->npose = frames;
    const json_t *poses = json_object_get(c, "poses"), *start = json_object_get(c, "start"),
                 *end = json_object_get(c, "end");
    if (poses) {
        if (start || end)
            return sci_json_fail(doc, err, "camera.poses", "give either \"poses\" or \"start\" and \"end\", not both");
        if (!json_is_array(poses) || (int)json_array_size(poses) != frames)
            return sci_json_fail(doc, err, "camera.poses",
                                 "must be an array of %d poses (frames per snapshot × snapshots)", frames);
        for (int i = 0; i < frames; i++) {
            char p[64];
            sci_json_path_index(p, sizeof p, "camera.poses", (size_t)i);
            if ((rc = parse_pose(doc, json_array_get(poses, (size_t)i), p, s->pose[i], err)) < 0)
                return rc;
        }
        return 0;
    }
    if (!start)
        return sci_json_fail(doc, err, "camera.start", "required key is missing (or give \"poses\")");
    double T0[12], T1[12];
    if ((rc = parse_pose(doc, start, "camera.start", T0, err)) < 0)
        return rc;
    memcpy(T1, T0, sizeof T1);
    if (end && (rc = parse_pose(doc, end, "camera.end", T1, err)) < 0)
        return rc;
    /* τ_g = g/(K·N − 1), so g = 0 and g = K·N − 1 are the end poses themselves (docs/conventions.md §12). */
    for (int g = 0; g < frames; g++)
        sim_pose_interp(T0, T1, frames > 1 ? (double)g / (frames - 1) : 0, s->pose[g]);
    return 0;
}

int sim_static3d_parse(const sci_json_doc *doc, const json_t *root, const char *base_dir, int w, int h,
                       int frames, uint64_t seed, sim_static3d *s, sci_error *err)
{
    memset(s, 0, sizeof *s);
    int rc;
    if ((rc = sci_json_get_double(doc, root, "", "background", 0, 0, 1, &s->background, err)) < 0)
        goto fail;
    const json_t *light = json_object_get(root, "light");
    if (light) {
        static const char *const allowed[] = {"direction", "ambient", NULL};
        s->lit = 1;
        s->ambient = 0.3;
        double d[3] = {0.3, 1, 0.5};
        if ((rc = sci_json_check_keys(doc, light, "light", allowed, err)) < 0 ||
            (rc = get_vec(doc, light, "light", "direction", 3, d, err)) < 0 ||
            (rc = sci_json_get_double(doc, light, "light", "ambient", 0, 0, 1, &s->ambient, err)) < 0)
            goto fail;
        double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(n > 0)) {
            rc = sci_json_fail(doc, err, "light.direction", "must not be the zero vector");
            goto fail;
        }
        for (int i = 0; i < 3; i++)
            s->light_dir[i] = d[i] / n;
    }
    const json_t *objs = json_object_get(root, "objects");
    if (!objs) {
        rc = sci_json_fail(doc, err, "objects", "required key is missing (a static3d scene needs objects)");
        goto fail;
    }
    if (!json_is_array(objs) || json_array_size(objs) < 1 || json_array_size(objs) > SIM_OBJECTS_MAX) {
        rc = sci_json_fail(doc, err, "objects", "must be an array of 1 to %d objects", SIM_OBJECTS_MAX);
        goto fail;
    }
    for (size_t i = 0; i < json_array_size(objs); i++) {
        char p[64];
        sci_json_path_index(p, sizeof p, "objects", i);
        rc = parse_object(doc, json_array_get(objs, i), p, base_dir, seed, (int)i, &s->obj[i], err);
        s->nobjects = (int)i + 1;
        if (rc < 0)
            goto fail;
    }
    if ((rc = parse_camera(doc, root, w, h, frames, s, err)) < 0)
        goto fail;
    return 0;
fail:
    sim_static3d_clear(s);
    return rc;
}

void sim_static3d_clear(sim_static3d *s)
{
    for (int i = 0; i < s->nobjects; i++)
        sim_texture_clear(&s->obj[i].tex);
    free(s->pose);
    s->pose = NULL;
    s->nobjects = s->npose = 0;
}

void sim_static3d_pose_at(const sim_static3d *s, double t, double T[12])
{
    if (s->npose == 1) {
        memcpy(T, s->pose[0], sizeof(double[12]));
        return;
    }
    int i = (int)floor(t);
    i = i < 0 ? 0 : i > s->npose - 2 ? s->npose - 2 : i;
    sim_pose_interp(s->pose[i], s->pose[i + 1], t - i, T);
}

sci_camera *sim_static3d_camera(const sim_static3d *s, int first, int n)
{
    sci_camera *c = sci_camera_new(n);
    if (!c)
        return NULL;
    c->fx = s->fx;
    c->fy = s->fy;
    c->cx = s->cx;
    c->cy = s->cy;
    c->near_m = s->near_m;
    c->far_m = s->far_m;
    memcpy(c->pose, s->pose + first, (size_t)n * sizeof *c->pose);
    return c;
}

/* Nearest hit of ray o + t·d (world) with object ob for t in (tmin, tmax): returns t or INFINITY and fills the
 * texture coordinates (texture units) and the world normal. */
static double intersect(const sim_object *ob, const double o[3], const double d[3], double tmin, double tmax,
                        double *u, double *v, double nrm[3])
{
    const double *R = ob->R;
    double po[3], lo[3], ld[3], ln[3] = {0, 0, 0};
    for (int i = 0; i < 3; i++)
        po[i] = o[i] - ob->center[i];
    for (int i = 0; i < 3; i++) { /* world → object: Rᵀ */
        lo[i] = R[i] * po[0] + R[3 + i] * po[1] + R[6 + i] * po[2];
        ld[i] = R[i] * d[0] + R[3 + i] * d[1] + R[6 + i] * d[2];
    }
    const double *hh = ob->half;
    double t = INFINITY, uu = 0, vv = 0;
    switch (ob->kind) {
    case SIM_OBJ_PLANE: {
        if (ld[2] == 0)
            return INFINITY;
        double tt = -lo[2] / ld[2];
        if (!(tt > tmin && tt < tmax))
            return INFINITY;
        double x = lo[0] + tt * ld[0], y = lo[1] + tt * ld[1];
        if (fabs(x) > hh[0] || fabs(y) > hh[1])
            return INFINITY;
        t = tt;
        uu = x + hh[0];
        vv = hh[1] - y;
        ln[2] = 1;
        break;
    }
    case SIM_OBJ_BOX: {
        double t0 = tmin, t1 = tmax;
        int axis = -1;
        for (int a = 0; a < 3; a++) {
            if (ld[a] == 0) {
                if (fabs(lo[a]) > hh[a])
                    return INFINITY;
                continue;
            }
            double ta = (-hh[a] - lo[a]) / ld[a], tb = (hh[a] - lo[a]) / ld[a];
            if (ta > tb) {
                double x = ta;
                ta = tb;
                tb = x;
            }
            if (ta > t0) {
                t0 = ta;
                axis = a;
            }
            t1 = tb < t1 ? tb : t1;
            if (t0 > t1)
                return INFINITY;
        }
        if (axis < 0) /* origin inside the box, or entry before tmin: no visible outer face */
            return INFINITY;
        t = t0;
        double p[3] = {lo[0] + t * ld[0], lo[1] + t * ld[1], lo[2] + t * ld[2]};
        int a1 = axis == 0 ? 1 : 0, a2 = axis == 2 ? 1 : 2;
        uu = p[a1] + hh[a1];
        vv = p[a2] + hh[a2];
        ln[axis] = p[axis] > 0 ? 1 : -1;
        break;
    }
    case SIM_OBJ_SPHERE: {
        double r = hh[0], b = lo[0] * ld[0] + lo[1] * ld[1] + lo[2] * ld[2];
        double dd = ld[0] * ld[0] + ld[1] * ld[1] + ld[2] * ld[2];
        double c = lo[0] * lo[0] + lo[1] * lo[1] + lo[2] * lo[2] - r * r, disc = b * b - dd * c;
        if (disc < 0)
            return INFINITY;
        double sq = sqrt(disc), ta = (-b - sq) / dd, tb = (-b + sq) / dd;
        t = ta > tmin ? ta : tb;
        if (!(t > tmin && t < tmax))
            return INFINITY;
        double p[3] = {lo[0] + t * ld[0], lo[1] + t * ld[1], lo[2] + t * ld[2]};
        uu = (atan2(p[0], p[2]) + M_PI) * r;
        vv = (M_PI / 2 - asin(fmax(-1, fmin(1, p[1] / r)))) * r;
        for (int i = 0; i < 3; i++)
            ln[i] = p[i] / r;
        break;
    }
    }
    *u = uu * ob->uv_scale;
    *v = vv * ob->uv_scale;
    for (int i = 0; i < 3; i++) /* object → world: R */
        nrm[i] = R[3 * i] * ln[0] + R[3 * i + 1] * ln[1] + R[3 * i + 2] * ln[2];
    return t;
}

static double shade(const sim_static3d *s, const double o[3], const double d[3])
{
    double best = INFINITY, u = 0, v = 0, n[3] = {0, 0, 0};
    int hit = -1;
    for (int k = 0; k < s->nobjects; k++) {
        double uk = 0, vk = 0, nk[3] = {0, 0, 0};
        double t = intersect(&s->obj[k], o, d, s->near_m, best < s->far_m ? best : s->far_m, &uk, &vk, nk);
        if (t < best) {
            best = t;
            hit = k;
            u = uk;
            v = vk;
            memcpy(n, nk, sizeof n);
        }
    }
    if (hit < 0)
        return s->background;
    double albedo = sim_texture_eval(&s->obj[hit].tex, u, v);
    if (!s->lit)
        return albedo;
    /* Two-sided Lambert: orient the normal towards the viewer. */
    double dn = n[0] * d[0] + n[1] * d[1] + n[2] * d[2], sgn = dn > 0 ? -1 : 1;
    double nl = sgn * (n[0] * s->light_dir[0] + n[1] * s->light_dir[1] + n[2] * s->light_dir[2]);
    return albedo * (s->ambient + (1 - s->ambient) * (nl > 0 ? nl : 0));
}

void sim_static3d_render(const sim_static3d *s, int w, int h, int ss, double t, float *out)
{
    double T[12];
    sim_static3d_pose_at(s, t, T);
    double inv = 1.0 / ((double)ss * ss), o[3] = {T[3], T[7], T[11]};
#pragma omp parallel for schedule(dynamic, 4)
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double acc = 0;
            for (int j = 0; j < ss; j++)
                for (int i = 0; i < ss; i++) {
                    /* Camera-frame direction with z = −1, so the ray parameter is depth along −z. */
                    double dc[3] = {(x + (i + 0.5) / ss - s->cx) / s->fx, -(y + (j + 0.5) / ss - s->cy) / s->fy, -1};
                    double d[3];
                    for (int r = 0; r < 3; r++)
                        d[r] = T[4 * r] * dc[0] + T[4 * r + 1] * dc[1] + T[4 * r + 2] * dc[2];
                    acc += shade(s, o, d);
                }
            out[(size_t)y * w + x] = (float)(acc * inv);
        }
}
