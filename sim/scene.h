/* sim/scene.h — a simulator scene: parsed, validated, ready to render (docs/scene-format.md).
 *
 * A scene file is JSON: the common keys (kind, width, height, frames, snapshots, bit_depth, seed, supersample),
 * the kind's content (video2d layers, or static3d objects and camera), "masks", "sensor" and "effects".
 * Loading validates everything and reports the first problem as "file:line:col: key.path: reason"
 * (SCI_ECONFIG). The struct is visible because the renderers, tests and benchmarks read it; treat it as
 * read-only after loading except through the sim_scene_set_* overrides.
 *
 *     sim_scene *sc;
 *     if (sim_scene_load_file(&sc, "etc/scenes/cacti_disc.json", &err) < 0) ...
 *     sim_scene_free(sc);
 *
 * Ownership: the scene owns its textures, PSF, poses and its JSON record. Not thread-safe to modify; rendering
 * from several threads at once is fine.
 */
#ifndef SCICAP_SIM_SCENE_H
#define SCICAP_SIM_SCENE_H

#include <stdint.h>

#include <jansson.h>

#include "sim/effects.h"
#include "sim/masks.h"
#include "sim/static3d.h"
#include "sim/video2d.h"

typedef enum sim_scene_kind { SIM_SCENE_VIDEO2D, SIM_SCENE_STATIC3D } sim_scene_kind;

typedef struct sim_scene {
    char name[128];          /* file name or the name given to load_string */
    sim_scene_kind kind;
    int w, h;                /* pixels */
    int n;                   /* frames per snapshot */
    int snapshots;           /* K */
    int bit_depth;           /* sensor ADC bits, 1..16 */
    int supersample;         /* s: s×s samples (rays) per pixel */
    uint64_t seed;
    sim_video2d video2d;     /* kind == video2d */
    sim_static3d static3d;   /* kind == static3d */
    int cfa;                 /* sci_cfa (recon/demosaic.h): SCI_CFA_NONE for a grey sensor; video2d only */
    sim_mask_spec masks;
    sim_effects_spec fx;
    json_t *record;          /* the scene as loaded (a deep copy), for the output's provenance; owned */
    char base_dir[1024];     /* folder relative paths are resolved from ("" = current folder) */
} sim_scene;

/* Load and validate a scene file. Relative texture, mask and PSF paths are taken from the file's folder. */
int sim_scene_load_file(sim_scene **out, const char *path, sci_error *err);
/* Same from text; `name` stands for the file name in messages, `base_dir` (may be NULL) resolves paths. */
int sim_scene_load_string(sim_scene **out, const char *name, const char *text, const char *base_dir,
                          sci_error *err);
void sim_scene_free(sim_scene *sc);

/* Overrides from the command line. Changing the snapshot count of a static3d scene re-spreads a start/end camera
 * path over the new frame count; with explicit poses it is refused (-EINVAL). The record is updated too. */
int sim_scene_set_seed(sim_scene *sc, uint64_t seed, sci_error *err);
int sim_scene_set_snapshots(sim_scene *sc, int snapshots, sci_error *err);

/* "video2d" / "static3d". */
const char *sim_scene_kind_name(sim_scene_kind k);

#endif
