#include "sim/simulate.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int sim_render_frame(const sim_scene *sc, double t, float *out)
{
    /* A colour scene's sensor sees the Bayer mosaic: every effect downstream works on raw pixels, as on a camera. */
    if (sc->kind == SIM_SCENE_VIDEO2D && sc->cfa)
        sim_video2d_render_color(&sc->video2d, sc->w, sc->h, sc->supersample, t, sc->cfa, -1, out);
    else if (sc->kind == SIM_SCENE_VIDEO2D)
        sim_video2d_render(&sc->video2d, sc->w, sc->h, sc->supersample, t, out);
    else
        sim_static3d_render(&sc->static3d, sc->w, sc->h, sc->supersample, t, out);
    return 0;
}

int sim_render_truth(const sim_scene *sc, int snapshot, sci_cube *truth, sci_error *err)
{
    if (truth->w != sc->w || truth->h != sc->h || truth->n != sc->n)
        return sci_error_set(err, SCI_ESHAPE, "truth cube is %dx%dx%d, scene %s needs %dx%dx%d", truth->w,
                             truth->h, truth->n, sc->name, sc->w, sc->h, sc->n);
    for (int k = 0; k < sc->n; k++) {
        int rc = sim_render_frame(sc, (double)snapshot * sc->n + k, sci_cube_frame(truth, k));
        if (rc < 0)
            return sci_error_set(err, rc, "%s: rendering frame %d failed", sc->name, snapshot * sc->n + k);
    }
    return 0;
}

int sim_render_truth_rgb(const sim_scene *sc, int snapshot, sci_cube *rgb, sci_error *err)
{
    if (!sc->cfa || sc->kind != SIM_SCENE_VIDEO2D)
        return sci_error_set(err, -EINVAL, "%s: not a colour scene (no \"cfa\")", sc->name);
    if (rgb->w != sc->w || rgb->h != sc->h || rgb->n != 3 * sc->n)
        return sci_error_set(err, SCI_ESHAPE, "RGB truth cube is %dx%dx%d, scene %s needs %dx%dx%d", rgb->w, rgb->h,
                             rgb->n, sc->name, sc->w, sc->h, 3 * sc->n);
    for (int k = 0; k < sc->n; k++)
        for (int c = 0; c < 3; c++)
            sim_video2d_render_color(&sc->video2d, sc->w, sc->h, sc->supersample, (double)snapshot * sc->n + k,
                                     sc->cfa, c, sci_cube_frame(rgb, 3 * k + c));
    return 0;
}

static int render_cb(void *user, double t, float *out) { return sim_render_frame(user, t, out); }

int sim_run(const sim_scene *sc, sci_problem ***out, int *kout, sim_stats *stats, sim_progress_fn progress,
            void *user, sci_error *err)
{
    *out = NULL;
    *kout = 0;
    if (stats)
        memset(stats, 0, sizeof *stats);
    sci_cube *mask = NULL;
    sim_effects *fx = NULL;
    int K = sc->snapshots, rc;
    sci_problem **p = calloc((size_t)K, sizeof *p);
    if (!p)
        return sci_error_set(err, -ENOMEM, "out of memory");
    if ((rc = sim_masks_make(&sc->masks, sc->w, sc->h, sc->n, sc->seed, &mask, err)) < 0)
        goto fail;
    if ((rc = sim_effects_new(&fx, &sc->fx, sc->w, sc->h, sc->n, sc->seed, err)) < 0)
        goto fail;
    for (int s = 0; s < K; s++) {
        sci_problem *q = calloc(1, sizeof *q);
        if (!q) {
            rc = sci_error_set(err, -ENOMEM, "out of memory");
            goto fail;
        }
        p[s] = q;
        q->peak = 1;
        snprintf(q->name, sizeof q->name, "%s", sc->name); /* readers append "#snapshot" */
        if ((rc = sci_cube_new(&q->truth, sc->w, sc->h, sc->n, err)) < 0 ||
            (rc = sci_cube_new(&q->meas, sc->w, sc->h, 1, err)) < 0 ||
            (rc = sci_cube_clone(&q->mask, mask, err)) < 0)
            goto fail;
        if ((rc = sim_render_truth(sc, s, q->truth, err)) < 0)
            goto fail;
        if ((rc = sim_effects_measure(fx, s, q->truth, q->mask, render_cb, (void *)sc, q->meas, stats, err)) < 0)
            goto fail;
        if (sc->kind == SIM_SCENE_STATIC3D && !(q->camera = sim_static3d_camera(&sc->static3d, s * sc->n, sc->n))) {
            rc = sci_error_set(err, -ENOMEM, "out of memory for the camera");
            goto fail;
        }
        if (progress && progress(user, s + 1, K)) {
            rc = sci_error_set(err, SCI_ECANCELED, "%s: cancelled after %d of %d snapshots", sc->name, s + 1, K);
            goto fail;
        }
    }
    sim_effects_free(fx);
    sci_cube_free(mask);
    *out = p;
    *kout = K;
    return 0;
fail:
    sim_effects_free(fx);
    sci_cube_free(mask);
    for (int s = 0; s < K; s++)
        sci_problem_free(p[s]);
    free(p);
    return rc;
}

json_t *sim_record_new(const sim_scene *sc, const sim_stats *stats)
{
    json_t *r = json_object(), *order = json_array();
    if (!r || !order) {
        json_decref(r);
        json_decref(order);
        return NULL;
    }
    for (int e = 0; e < SIM_FX_COUNT; e++)
        if (sim_fx_listed(&sc->fx, e))
            json_array_append_new(order, json_string(sim_fx_name(e)));
    json_object_set_new(r, "format", json_string("scicap-sim-record"));
    json_object_set_new(r, "version", json_integer(1));
    json_object_set_new(r, "generator", json_string("scicap sim " SCICAP_VERSION));
    json_object_set_new(r, "scene", json_deep_copy(sc->record));
    json_object_set_new(r, "kind", json_string(sim_scene_kind_name(sc->kind)));
    json_object_set_new(r, "seed", json_integer((json_int_t)sc->seed));
    json_object_set_new(r, "effects_applied", order);
    json_object_set_new(r, "scale",
                        json_string("truth and masks in [0,1]; meas on the forward-model scale (sum of mask*frame), "
                                    "peak 1; sensor effects in electrons = meas*photons_white, converted back"));
    json_t *sensor = json_pack("{s:f, s:f, s:f, s:i}", "photons_white", sc->fx.photons_white, "full_well_e",
                               sc->fx.full_well_e, "gain_e_per_dn", sc->fx.gain_e_per_dn, "bit_depth", sc->bit_depth);
    if (sensor)
        json_object_set_new(r, "sensor", sensor);
    if (stats) {
        json_t *st = json_object();
        for (int e = 0; st && e < SIM_FX_COUNT; e++)
            if (stats->passes[e] || stats->draws[e])
                json_object_set_new(st, sim_fx_name(e), json_pack("{s:I, s:I}", "passes", (json_int_t)stats->passes[e],
                                                                   "draws", (json_int_t)stats->draws[e]));
        if (st)
            json_object_set_new(r, "effect_stats", st);
    }
    return r;
}
