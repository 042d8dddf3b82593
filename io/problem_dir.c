#include "io/problem_dir.h"

#include "recon/bayer.h"

#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "io/image.h"
#include "io/staging.h"

static json_t *camera_to_json(const sci_camera *c, sci_problem *const *problems, int k)
{
    json_t *poses = json_array();
    for (int j = 0; j < k; j++) {
        const sci_camera *cj = problems[j]->camera;
        for (int f = 0; f < cj->n; f++) {
            json_t *p = json_array();
            for (int e = 0; e < 12; e++)
                json_array_append_new(p, json_real(cj->pose[f][e]));
            json_array_append_new(poses, p);
        }
    }
    return json_pack("{s:f, s:f, s:f, s:f, s:f, s:f, s:o}", "fx", c->fx, "fy", c->fy, "cx", c->cx, "cy", c->cy,
                     "near", c->near_m, "far", c->far_m, "poses", poses);
}

int sci_problem_dir_write(const char *dir, sci_problem *const *problems, int k, const json_t *source,
                          int overwrite, sci_error *err)
{
    const sci_problem_dir_opts o = {.overwrite = overwrite, .previews = 1};
    return sci_problem_dir_save(dir, problems, k, source, &o, err);
}

int sci_problem_dir_write_opt(const char *dir, sci_problem *const *problems, int k, const json_t *source,
                              int overwrite, int previews, sci_error *err)
{
    const sci_problem_dir_opts o = {.overwrite = overwrite, .previews = previews};
    return sci_problem_dir_save(dir, problems, k, source, &o, err);
}

/* Mask previews on [0, 1] × 255, the scale every writer of a problem folder uses for them. */
static int mask_previews_write(const char *dir, const sci_cube *mask, sci_error *err)
{
    char pv[4200];
    int rc = 0;
    for (int f = 0; f < mask->n && rc == 0; f++) {
        snprintf(pv, sizeof pv, "%s/preview_mask_%03d.png", dir, f);
        rc = sci_image_write(pv, mask, f, SCI_PIXEL_U8, 255.0, NULL, err);
    }
    return rc;
}

int sci_problem_dir_write_masks(const char *dir, const sci_cube *mask, sci_error *err)
{
    int rc = sci_stack_write(dir, "mask", "exr", mask, SCI_PIXEL_F32, 1.0, NULL, err);
    return rc < 0 ? rc : mask_previews_write(dir, mask, err);
}

/* Hard-link the mask files of `from` (sci_problem_dir_write_masks) into `to`: 0, or -errno at the first file
 * that cannot be linked (the caller then writes them all: `to` is its own temporary folder). */
static int masks_link(const char *from, const char *to, int n, int previews)
{
    char a[4200], b[4200];
    for (int f = -1; f < n; f++) {
        for (int pv = 0; pv <= previews; pv++) {
            if (f < 0 && pv) /* no preview of the sidecar */
                continue;
            const char *name = f < 0 ? "mask.json" : pv ? "preview_mask_%03d.png" : "mask_%03d.exr";
            char file[64];
            snprintf(file, sizeof file, name, f);
            snprintf(a, sizeof a, "%s/%s", from, file);
            snprintf(b, sizeof b, "%s/%s", to, file);
            if (link(a, b) != 0)
                return -errno;
        }
    }
    return 0;
}

int sci_problem_dir_write_color(const char *dir, sci_problem *const *problems, int k, const json_t *source,
                                const sci_problem_color *color, int overwrite, int previews, sci_error *err)
{
    const sci_problem_dir_opts o = {.overwrite = overwrite, .previews = previews, .color = color};
    return sci_problem_dir_save(dir, problems, k, source, &o, err);
}

int sci_problem_dir_save(const char *dir, sci_problem *const *problems, int k, const json_t *source,
                         const sci_problem_dir_opts *opts, sci_error *err)
{
    static const sci_problem_dir_opts defaults = {.previews = 1};
    if (!opts)
        opts = &defaults;
    const int overwrite = opts->overwrite, previews = opts->previews;
    const sci_problem_color *color = opts->color;
    if (k < 1)
        return sci_error_set(err, -EINVAL, "%s: no problems to write", dir);
    const sci_problem *p0 = problems[0];
    int have_truth = 1, have_camera = 1;
    for (int j = 0; j < k; j++) {
        const sci_problem *p = problems[j];
        if (p->mask->w != p0->mask->w || p->mask->h != p0->mask->h || p->mask->n != p0->mask->n)
            return sci_error_set(err, SCI_ESHAPE, "%s: problems of different sizes cannot share a folder", dir);
        have_truth &= p->truth != NULL;
        have_camera &= p->camera != NULL;
    }
    struct stat st;
    if (stat(dir, &st) == 0 && !overwrite)
        return sci_error_set(err, -EEXIST, "%s: already exists (use --force to replace it)", dir);

    char tmp[4096];
    if (sci_staging_name(tmp, sizeof tmp, dir) < 0)
        return sci_error_set(err, -ENAMETOOLONG, "%s: name too long", dir);
    const int w = p0->mask->w, h = p0->mask->h, n = p0->mask->n;
    sci_cube *meas = NULL, *truth = NULL, *rgb = NULL;
    int rc = sci_cube_new(&meas, w, h, k, err);
    if (rc == 0 && color && color->truth_rgb) {
        if ((rc = sci_cube_new(&rgb, w, h, 3 * n * k, err)) == 0)
            for (int j = 0; j < k && rc == 0; j++) {
                const sci_cube *c = color->truth_rgb[j];
                if (c->w != w || c->h != h || c->n != 3 * n)
                    rc = sci_error_set(err, SCI_ESHAPE, "%s: RGB truth %d is %dx%dx%d, not %dx%dx%d", dir, j, c->w,
                                       c->h, c->n, w, h, 3 * n);
                else
                    memcpy(sci_cube_frame(rgb, 3 * n * j), c->data, sci_cube_count(c) * sizeof(float));
            }
    }
    if (rc == 0 && have_truth)
        rc = sci_cube_new(&truth, w, h, n * k, err);
    if (rc < 0)
        goto out;
    const size_t fs = sci_cube_frame_size(meas);
    for (int j = 0; j < k; j++) {
        memcpy(sci_cube_frame(meas, j), problems[j]->meas->data, fs * sizeof(float));
        if (truth)
            memcpy(sci_cube_frame(truth, j * n), problems[j]->truth->data, fs * n * sizeof(float));
    }
    if ((rc = sci_stack_write(tmp, "meas", "exr", meas, SCI_PIXEL_F32, 1.0, NULL, err)) < 0)
        goto out;
    /* the masks: linked from a folder that holds them when the caller has one, else written here (a partial
     * link is harmless: every write below goes to a temporary name and is renamed over it) */
    const int masks_linked = opts->masks_from && masks_link(opts->masks_from, tmp, n, previews) == 0;
    const int masks_previewed = masks_linked && previews;
    if ((!masks_linked && (rc = sci_stack_write(tmp, "mask", "exr", p0->mask, SCI_PIXEL_F32, 1.0, NULL, err)) < 0) ||
        (truth && (rc = sci_stack_write(tmp, "truth", "exr", truth, SCI_PIXEL_F32, 1.0, NULL, err)) < 0) ||
        (rgb && (rc = sci_stack_write(tmp, "truth_rgb", "exr", rgb, SCI_PIXEL_F32, 1.0, NULL, err)) < 0))
        goto out;
    /* Viewable 8-bit previews beside the lossless stacks: truth and masks on [0, peak], measurements scaled by
     * their own maximum (they sum up to N frames). */
    char pv[4200];
    float lo, hi;
    sci_cube_minmax(meas, &lo, &hi);
    for (int j = 0; previews && j < k && rc == 0; j++) {
        snprintf(pv, sizeof pv, "%s/preview_meas_%03d.png", tmp, j);
        rc = sci_image_write(pv, meas, j, SCI_PIXEL_U8, hi > 0 ? 255.0 / hi : 1.0, NULL, err);
    }
    if (previews && !masks_previewed && rc == 0)
        rc = mask_previews_write(tmp, p0->mask, err);
    if (previews && rc == 0 && truth) {
        snprintf(pv, sizeof pv, "%s/preview_truth.gif", tmp);
        rc = sci_image_write_gif(pv, truth, 255.0 / p0->peak, 125, err);
    }
    char pvc[4200];
    for (int f = 0; previews && rgb && f < n && rc == 0; f++) {
        snprintf(pvc, sizeof pvc, "%s/preview_truth_rgb_%03d.png", tmp, f);
        rc = sci_image_write_rgb(pvc, rgb, f, SCI_PIXEL_U8, 255.0 / p0->peak, err);
    }
    if (rc < 0)
        goto out;
    json_t *man = json_pack("{s:s, s:i, s:i, s:i, s:i, s:i, s:f, s:s, s:s}", "format", "scicap-problem", "version", 1,
                            "snapshots", k, "w", w, "h", h, "n", n, "peak", p0->peak, "meas", "meas.json", "mask",
                            "mask.json");
    if (truth)
        json_object_set_new(man, "truth", json_string("truth.json"));
    if (have_camera)
        json_object_set_new(man, "camera", camera_to_json(p0->camera, problems, k));
    if (color)
        json_object_set_new(man, "cfa", json_string(sci_cfa_name((sci_cfa)color->cfa)));
    if (rgb)
        json_object_set_new(man, "truth_rgb", json_string("truth_rgb.json"));
    if (source)
        json_object_set_new(man, "source", json_deep_copy(source));
    json_object_set_new(man, "name", json_string(p0->name));
    char path[4200];
    snprintf(path, sizeof path, "%s/problem.json", tmp);
    if (json_dump_file(man, path, JSON_INDENT(2)) != 0)
        rc = sci_error_set(err, -EIO, "%s: cannot write", path);
    json_decref(man);
    if (rc < 0)
        goto out;
    /* an old DIR is put back if the new one cannot take its place */
    rc = sci_staging_publish(tmp, dir, overwrite ? SCI_STAGING_OVERWRITE : 0, NULL, err);
out:
    if (rc < 0)
        sci_staging_remove(tmp);
    sci_cube_free(meas);
    sci_cube_free(truth);
    sci_cube_free(rgb);
    return rc;
}

/* The manifest of problem folder dir (which may name its problem.json): the folder into base[4096], the manifest's
 * path into path[4200], and the parsed manifest (the caller's), or NULL with je set. */
static json_t *manifest_load(const char *dir, char *base, char *path, json_error_t *je)
{
    snprintf(base, 4096, "%s", dir);
    size_t bl = strlen(base);
    if (bl > 13 && strcmp(base + bl - 13, "/problem.json") == 0)
        base[bl - 13] = 0;
    snprintf(path, 4200, "%s/problem.json", base);
    return json_load_file(path, 0, je);
}

int sci_problem_dir_read_color(const char *dir, int *cfa, sci_cube ***truth_rgb, int *k, sci_error *err)
{
    *cfa = SCI_CFA_NONE;
    *k = 0;
    if (truth_rgb)
        *truth_rgb = NULL;
    char base[4096], path[4200];
    json_error_t je;
    json_t *man = manifest_load(dir, base, path, &je);
    if (!man)
        return sci_error_set(err, SCI_EFORMAT, "%s: %s", path, je.text);
    int rc = 0;
    const char *c = json_string_value(json_object_get(man, "cfa"));
    const char *rgb_f = json_string_value(json_object_get(man, "truth_rgb"));
    const json_int_t snaps = json_integer_value(json_object_get(man, "snapshots"));
    const json_int_t n = json_integer_value(json_object_get(man, "n"));
    sci_cfa parsed = SCI_CFA_NONE;
    if (c && (sci_cfa_parse(c, &parsed) < 0 || parsed == SCI_CFA_NONE)) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: cfa \"%s\" is not RGGB, BGGR, GRBG or GBRG", path, c);
        goto out;
    }
    *cfa = (int)parsed;
    if (rgb_f && parsed != SCI_CFA_NONE && (snaps < 1 || snaps > 1 << 24 || n < 1 || n > 1 << 24)) {
        rc = sci_error_set(err, SCI_ESHAPE, "%s: snapshots = %lld, n = %lld: not usable counts", path,
                           (long long)snaps, (long long)n);
        goto out;
    }
    *k = (int)snaps;
    if (truth_rgb && rgb_f && parsed != SCI_CFA_NONE) {
        char sub[4400];
        snprintf(sub, sizeof sub, "%s/%s", base, rgb_f);
        sci_cube *all = NULL;
        if ((rc = sci_stack_read(sub, &all, NULL, err)) < 0)
            goto out;
        if (snaps < 1 || n < 1 || all->n != 3 * n * snaps) {
            rc = sci_error_set(err, SCI_ESHAPE, "%s: %d RGB planes, expected 3 × %lld × %lld", sub, all->n,
                               (long long)n, (long long)snaps);
            sci_cube_free(all);
            goto out;
        }
        sci_cube **arr = calloc((size_t)snaps, sizeof *arr);
        for (int j = 0; arr && j < snaps; j++) {
            if ((rc = sci_cube_new(&arr[j], all->w, all->h, 3 * (int)n, err)) < 0)
                break;
            memcpy(arr[j]->data, sci_cube_frame(all, 3 * (int)n * j), sci_cube_count(arr[j]) * sizeof(float));
        }
        sci_cube_free(all);
        if (!arr || rc < 0) {
            for (int j = 0; arr && j < snaps; j++)
                sci_cube_free(arr[j]);
            free(arr);
            rc = rc < 0 ? rc : sci_error_set(err, -ENOMEM, "%s: out of memory", sub);
            goto out;
        }
        *truth_rgb = arr;
    }
out:
    json_decref(man);
    return rc;
}

static int camera_from_json(const json_t *cam, int frame0, int n, const char *path, sci_camera **out,
                            sci_error *err)
{
    sci_camera *c = sci_camera_new(n);
    if (!c)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
    json_t *poses = NULL;
    json_error_t je;
    if (json_unpack_ex((json_t *)cam, &je, 0, "{s:F, s:F, s:F, s:F, s:F, s:F, s:o}", "fx", &c->fx, "fy", &c->fy, "cx",
                       &c->cx, "cy", &c->cy, "near", &c->near_m, "far", &c->far_m, "poses", &poses) != 0) {
        sci_camera_free(c);
        return sci_error_set(err, SCI_EFORMAT, "%s: camera: %s", path, je.text);
    }
    for (int f = 0; f < n; f++) {
        json_t *p = json_array_get(poses, (size_t)(frame0 + f));
        if (!json_is_array(p) || json_array_size(p) != 12) {
            sci_camera_free(c);
            return sci_error_set(err, SCI_EFORMAT, "%s: camera.poses[%d] must be 12 numbers", path, frame0 + f);
        }
        for (int e = 0; e < 12; e++) {
            json_t *v = json_array_get(p, (size_t)e);
            if (!json_is_number(v)) {
                sci_camera_free(c);
                return sci_error_set(err, SCI_EFORMAT, "%s: camera.poses[%d][%d] is not a number", path, frame0 + f, e);
            }
            c->pose[f][e] = json_number_value(v);
        }
    }
    *out = c;
    return 0;
}

int sci_problem_dir_read(const char *dir, sci_problem ***out, int *k, sci_error *err)
{
    sci_io_limits none;
    sci_io_limits_none(&none);
    return sci_problem_dir_read_opts(dir, &none, out, k, err);
}

int sci_problem_dir_read_opts(const char *dir, const sci_io_limits *lim, sci_problem ***out, int *k,
                              sci_error *err)
{
    sci_io_limits deflim;
    if (!lim) {
        sci_io_limits_default(&deflim);
        lim = &deflim;
    }
    *out = NULL;
    *k = 0;
    char base[4096], path[4200];
    json_error_t je;
    json_t *man = manifest_load(dir, base, path, &je);
    if (!man) {
        if (access(path, R_OK) != 0)
            return sci_error_set(err, -errno, "%s: %s (not a scicap problem folder?)", path, strerror(errno));
        return sci_error_set(err, SCI_EFORMAT, "%s:%d:%d: %s", path, je.line, je.column, je.text);
    }
    int rc = 0, nsnap = 0;
    sci_cube *meas = NULL, *mask = NULL, *truth = NULL;
    sci_problem **probs = NULL;
    const char *format = "", *meas_f = NULL, *mask_f = NULL;
    json_int_t snaps = 0;
    double peak = 1;
    if (json_unpack_ex(man, &je, 0, "{s:s, s:I, s:F, s:s, s:s}", "format", &format, "snapshots", &snaps, "peak",
                       &peak, "meas", &meas_f, "mask", &mask_f) != 0 ||
        strcmp(format, "scicap-problem") != 0) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: not a scicap problem manifest (%s)", path, je.text);
        goto out;
    }
    if (snaps < 1 || snaps > INT_MAX) {
        rc = sci_error_set(err, SCI_ESHAPE, "%s: snapshots = %lld is not a usable count", path, (long long)snaps);
        goto out;
    }
    /* The manifest's own claim first (w, h, n are written by every writer; older folders may lack them). */
    const json_int_t mw = json_integer_value(json_object_get(man, "w")),
                     mh = json_integer_value(json_object_get(man, "h")),
                     mn = json_integer_value(json_object_get(man, "n"));
    if ((rc = sci_io_limits_check_input(lim, path, mw, mh, mn, snaps, err)) < 0)
        goto out;
    char sub[4400];
    snprintf(sub, sizeof sub, "%s/%s", base, meas_f);
    if ((rc = sci_stack_read_opts(sub, lim, &meas, NULL, err)) < 0)
        goto out;
    snprintf(sub, sizeof sub, "%s/%s", base, mask_f);
    if ((rc = sci_stack_read_opts(sub, lim, &mask, NULL, err)) < 0)
        goto out;
    const char *truth_f = json_string_value(json_object_get(man, "truth"));
    if (truth_f) {
        snprintf(sub, sizeof sub, "%s/%s", base, truth_f);
        if ((rc = sci_stack_read_opts(sub, lim, &truth, NULL, err)) < 0)
            goto out;
    }
    const int n = mask->n;
    if (meas->w != mask->w || meas->h != mask->h || meas->n != snaps ||
        (truth && (truth->w != mask->w || truth->h != mask->h || truth->n != n * snaps))) {
        rc = sci_error_set(err, SCI_ESHAPE, "%s: stacks disagree with each other or with snapshots = %lld", path,
                           (long long)snaps);
        goto out;
    }
    probs = calloc((size_t)snaps, sizeof *probs);
    if (!probs) {
        rc = sci_error_set(err, -ENOMEM, "%s: out of memory", path);
        goto out;
    }
    const json_t *cam = json_object_get(man, "camera");
    const char *name = json_string_value(json_object_get(man, "name"));
    const size_t fs = sci_cube_frame_size(mask);
    for (int j = 0; j < snaps; j++) {
        sci_problem *p = calloc(1, sizeof *p);
        if (!p) {
            rc = sci_error_set(err, -ENOMEM, "%s: out of memory", path);
            goto out;
        }
        probs[nsnap++] = p;
        p->peak = peak;
        snprintf(p->name, sizeof p->name, "%s#%d", name ? name : base, j + 1);
        if ((rc = sci_cube_new(&p->meas, mask->w, mask->h, 1, err)) < 0 || (rc = sci_cube_clone(&p->mask, mask, err)) < 0)
            goto out;
        memcpy(p->meas->data, sci_cube_frame(meas, j), fs * sizeof(float));
        if (truth) {
            if ((rc = sci_cube_new(&p->truth, mask->w, mask->h, n, err)) < 0)
                goto out;
            memcpy(p->truth->data, sci_cube_frame(truth, j * n), fs * n * sizeof(float));
        }
        if (cam && (rc = camera_from_json(cam, j * n, n, path, &p->camera, err)) < 0)
            goto out;
        if ((rc = sci_problem_validate(p, err)) < 0)
            goto out;
    }
    *out = probs;
    *k = nsnap;
    probs = NULL;
out:
    sci_problem_array_free(probs, nsnap);
    sci_cube_free(meas);
    sci_cube_free(mask);
    sci_cube_free(truth);
    json_decref(man);
    return rc;
}
