#include "sim/scene.h"

#include <errno.h>
#include <libgen.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const kinds[] = {"video2d", "static3d", NULL};

const char *sim_scene_kind_name(sim_scene_kind k) { return k <= SIM_SCENE_STATIC3D ? kinds[k] : NULL; }

static int parse(sim_scene *sc, const sci_json_doc *doc, const char *base_dir, sci_error *err)
{
    static const char *const allowed[] = {"version", "kind", "name", "description", "width", "height", "frames",
                                          "snapshots", "bit_depth", "seed", "supersample", "background", "layers",
                                          "objects", "camera", "light", "masks", "sensor", "effects", "cfa",
                                          "background_color", NULL};
    static const char *const only2d[] = {"layers", "cfa", "background_color", NULL}, *const only3d[] = {"objects", "camera", "light", NULL};
    const json_t *root = sci_json_doc_root(doc);
    int rc, kind = 0;
    long long w = 0, h = 0, n = 8, k = 1, bits = 12, ss = 1, seed = 1, version = 1;
    if ((rc = sci_json_check_keys(doc, root, "", allowed, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "version", 0, 1, 1, &version, err)) < 0 ||
        (rc = sci_json_get_enum(doc, root, "", "kind", 1, kinds, &kind, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "width", 1, 1, 16384, &w, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "height", 1, 1, 16384, &h, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "frames", 0, 1, 256, &n, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "snapshots", 0, 1, 1024, &k, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "bit_depth", 0, 1, 16, &bits, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "supersample", 0, 1, 16, &ss, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "seed", 0, 0, (1LL << 53), &seed, err)) < 0)
        return rc;
    const char *const *forbidden = kind == SIM_SCENE_VIDEO2D ? only3d : only2d;
    for (int i = 0; forbidden[i]; i++)
        if (json_object_get(root, forbidden[i]))
            return sci_json_fail(doc, err, forbidden[i], "belongs to %s scenes, this one is %s",
                                 kind == SIM_SCENE_VIDEO2D ? "static3d" : "video2d", kinds[kind]);
    if (w * h * n * k > (1LL << 31))
        return sci_json_fail(doc, err, "", "width × height × frames × snapshots = %lld is too large (max 2^31)",
                             w * h * n * k);
    const char *name = NULL;
    if ((rc = sci_json_get_string(doc, root, "", "name", 0, &name, err)) < 0)
        return rc;
    snprintf(sc->name, sizeof sc->name, "%s", name ? name : sci_json_doc_name(doc));
    sc->kind = (sim_scene_kind)kind;
    sc->w = (int)w;
    sc->h = (int)h;
    sc->n = (int)n;
    sc->snapshots = (int)k;
    sc->bit_depth = (int)bits;
    sc->supersample = (int)ss;
    sc->seed = (uint64_t)seed;
    static const char *const cfas[] = {"none", "RGGB", "BGGR", "GRBG", "GBRG", NULL};
    if ((rc = sci_json_get_enum(doc, root, "", "cfa", 0, cfas, &sc->cfa, err)) < 0)
        return rc;
    if (sc->cfa && (w % 2 || h % 2))
        return sci_json_fail(doc, err, "cfa", "a Bayer sensor needs an even width and height (got %lldx%lld)", w, h);
    if (kind == SIM_SCENE_VIDEO2D)
        rc = sim_video2d_parse(doc, root, base_dir, sc->w, sc->h, sc->seed, &sc->video2d, err);
    else
        rc = sim_static3d_parse(doc, root, base_dir, sc->w, sc->h, sc->n * sc->snapshots, sc->seed, &sc->static3d,
                                err);
    if (rc < 0)
        return rc;
    if ((rc = sim_masks_parse(doc, root, base_dir, sc->w, sc->h, &sc->masks, err)) < 0)
        return rc;
    if ((rc = sim_effects_parse(doc, root, base_dir, sc->n, sc->bit_depth, &sc->fx, err)) < 0)
        return rc;
    if (sim_fx_listed(&sc->fx, SIM_FX_BLUR) && sc->fx.psf && (sc->fx.psf->w > sc->w || sc->fx.psf->h > sc->h))
        return sci_json_fail(doc, err, "effects.blur.psf", "the PSF (%dx%d) is larger than the image (%dx%d)",
                             sc->fx.psf->w, sc->fx.psf->h, sc->w, sc->h);
    return 0;
}

static int load_doc(sim_scene **out, sci_json_doc *doc, const char *base_dir, sci_error *err)
{
    *out = NULL;
    sim_scene *sc = calloc(1, sizeof *sc);
    if (!sc) {
        sci_json_doc_free(doc);
        return sci_error_set(err, -ENOMEM, "out of memory for a scene");
    }
    int rc = parse(sc, doc, base_dir, err);
    if (rc == 0 && !(sc->record = json_deep_copy(sci_json_doc_root(doc))))
        rc = sci_error_set(err, -ENOMEM, "out of memory for the scene record");
    if (base_dir)
        snprintf(sc->base_dir, sizeof sc->base_dir, "%s", base_dir);
    sci_json_doc_free(doc);
    if (rc < 0) {
        sim_scene_free(sc);
        return rc;
    }
    *out = sc;
    return 0;
}

int sim_scene_load_file(sim_scene **out, const char *path, sci_error *err)
{
    *out = NULL;
    sci_json_doc *doc;
    int rc = sci_json_doc_load_file(&doc, path, err);
    if (rc < 0)
        return rc;
    char *copy = strdup(path);
    if (!copy) {
        sci_json_doc_free(doc);
        return sci_error_set(err, -ENOMEM, "out of memory");
    }
    rc = load_doc(out, doc, dirname(copy), err);
    free(copy);
    return rc;
}

int sim_scene_load_string(sim_scene **out, const char *name, const char *text, const char *base_dir,
                          sci_error *err)
{
    *out = NULL;
    sci_json_doc *doc;
    int rc = sci_json_doc_load_string(&doc, name, text, strlen(text), err);
    if (rc < 0)
        return rc;
    return load_doc(out, doc, base_dir, err);
}

void sim_scene_free(sim_scene *sc)
{
    if (!sc)
        return;
    sim_video2d_clear(&sc->video2d);
    sim_static3d_clear(&sc->static3d);
    sim_effects_spec_clear(&sc->fx);
    json_decref(sc->record);
    free(sc);
}

/* Overrides re-parse the updated record, so every derived value (texture seeds, camera path) follows. */
static int reload_with(sim_scene *sc, const char *key, json_t *value, sci_error *err)
{
    json_t *rec = json_deep_copy(sc->record);
    if (!rec) {
        json_decref(value);
        return sci_error_set(err, -ENOMEM, "out of memory");
    }
    json_object_set_new(rec, key, value);
    char *text = json_dumps(rec, JSON_INDENT(2));
    json_decref(rec);
    if (!text)
        return sci_error_set(err, -ENOMEM, "out of memory");
    sim_scene *fresh = NULL;
    char name[160];
    snprintf(name, sizeof name, "%s (with --%s)", sc->name, key);
    int rc = sim_scene_load_string(&fresh, name, text, sc->base_dir, err);
    free(text);
    if (rc < 0)
        return rc;
    snprintf(fresh->name, sizeof fresh->name, "%s", sc->name);
    /* Swap contents so the caller's pointer stays valid. */
    sim_scene old = *sc;
    *sc = *fresh;
    *fresh = old;
    sim_scene_free(fresh);
    return 0;
}

int sim_scene_set_seed(sim_scene *sc, uint64_t seed, sci_error *err)
{
    if (seed > (1ULL << 53))
        return sci_error_set(err, -EINVAL, "seed %llu is too large (max 2^53)", (unsigned long long)seed);
    return reload_with(sc, "seed", json_integer((json_int_t)seed), err);
}

int sim_scene_set_snapshots(sim_scene *sc, int snapshots, sci_error *err)
{
    if (snapshots < 1 || snapshots > 1024)
        return sci_error_set(err, -EINVAL, "snapshots must be in [1, 1024] (got %d)", snapshots);
    const json_t *cam = json_object_get(sc->record, "camera");
    if (snapshots != sc->snapshots && sc->kind == SIM_SCENE_STATIC3D && json_object_get(cam, "poses"))
        return sci_error_set(err, -EINVAL,
                             "%s lists %d explicit camera poses (frames × snapshots); the snapshot count cannot "
                             "change without new poses (use start/end for a path that stretches)",
                             sc->name, sc->static3d.npose);
    return reload_with(sc, "snapshots", json_integer(snapshots), err);
}
