/* sim/texture.h — 2D textures for scene surfaces: procedural patterns and image files.
 *
 * A texture is a function value(u, v) in [0, 1] of texture coordinates in *texture units* (video2d layers: the
 * layer's own pixels; static3d objects: scene units × the object's uv_scale). Kinds and keys (docs/scene-format.md):
 *   "constant"     value
 *   "checkerboard" cell (units), values [a, b]
 *   "gradient"     angle_rad, length (units), values [a, b]: a at the origin line, b at `length` along angle
 *   "radial"       center [u, v], length: a at the centre, b at distance `length` and beyond
 *   "noise"        cell (feature size, units), octaves, values [a, b]: smooth value noise (fBm), seeded
 *   "image"        path (read through OpenImageIO, luminance, scaled to [0, 1] by its bit depth),
 *                  texel (units per image pixel), repeat (tile or clamp): bilinear sampling
 * Procedural textures need no memory and no random stream: the noise lattice is a hash of (seed, cell), so
 * evaluating a texture is a pure, thread-safe function.
 */
#ifndef SCICAP_SIM_TEXTURE_H
#define SCICAP_SIM_TEXTURE_H

#include <stdint.h>

#include "base/cube.h"
#include "base/json.h"

typedef enum sim_texture_kind {
    SIM_TEX_CONSTANT,
    SIM_TEX_CHECKERBOARD,
    SIM_TEX_GRADIENT,
    SIM_TEX_RADIAL,
    SIM_TEX_NOISE,
    SIM_TEX_IMAGE,
} sim_texture_kind;

typedef struct sim_texture {
    sim_texture_kind kind;
    double a, b;          /* the two values the pattern runs between, each in [0, 1] */
    double cell;          /* checkerboard cell / noise feature size, texture units */
    double angle_rad;     /* gradient direction */
    double length;        /* gradient / radial ramp length, texture units */
    double cu, cv;        /* radial centre */
    int octaves;          /* noise */
    uint64_t seed;        /* noise lattice seed */
    sci_cube *image;      /* image: 1 frame, values in [0, 1]; owned */
    double texel;         /* image: texture units per image pixel */
    int repeat;           /* image: 1 tile, 0 clamp to edge */
} sim_texture;

/* Parse the texture object at `path` (member of the scene). `seed` seeds noise textures (the scene derives a
 * distinct one per texture). Relative image paths are taken from `base_dir` (the scene file's folder; NULL =
 * current folder). Errors: SCI_ECONFIG with the position and key; image read errors name the file. */
int sim_texture_parse(const sci_json_doc *doc, const json_t *obj, const char *path, const char *base_dir,
                      uint64_t seed, sim_texture *out, sci_error *err);
/* Free what the texture holds (its image); leaves a constant 0 texture. */
void sim_texture_clear(sim_texture *t);
/* Value at (u, v), in [0, 1]. */
float sim_texture_eval(const sim_texture *t, double u, double v);
/* Size of an image texture in texture units (0, 0 for procedural ones). */
void sim_texture_extent(const sim_texture *t, double *wu, double *hu);

#endif
