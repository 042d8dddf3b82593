/* sim/video2d.h — the CACTI setting: textured layers moving in front of a fixed camera.
 *
 * Each layer is a shape (rectangle, disc or polygon) filled with a texture, placed by its centre (pixels), angle
 * (radians) and scale, each moving linearly in time: at time t (in frames) the centre is position + velocity·t,
 * the angle angle + spin·t, the scale scale + scale_rate·t (kept ≥ 0.01). Frame k of the whole sequence (all
 * snapshots, snapshot-major) is the instant t = k: the centre of its sub-frame, which spans [k − ½, k + ½].
 * Layers are drawn in depth order (larger depth is farther; equal depths keep file order, later in front), so
 * nearer layers occlude farther ones; where no layer covers a pixel the background value shows.
 * Coordinates: x right, y down, pixel (x, y) covers [x, x+1) × [y, y+1). Each pixel averages s×s samples
 * (s = the scene's supersample factor) at the centres of an s×s grid inside it.
 */
#ifndef SCICAP_SIM_VIDEO2D_H
#define SCICAP_SIM_VIDEO2D_H

#include "base/json.h"
#include "sim/texture.h"

#define SIM_POLY_MAX 32
#define SIM_LAYERS_MAX 64

typedef enum sim_shape { SIM_SHAPE_RECT, SIM_SHAPE_DISC, SIM_SHAPE_POLYGON } sim_shape;

typedef struct sim_layer {
    sim_texture tex;
    sim_shape shape;
    double size_w, size_h;      /* pixels at scale 1 (disc: diameter size_w) */
    int npoly;                  /* polygon vertices, relative to the centre, pixels at scale 1 */
    double poly[2 * SIM_POLY_MAX];
    double x, y, vx, vy;        /* centre at t = 0 (pixels) and its velocity (pixels per frame) */
    double angle_rad, spin_rad; /* angle at t = 0 and per frame */
    double scale, scale_rate;   /* scale at t = 0 and its change per frame */
    double depth;               /* larger is farther */
    double color[3];            /* RGB tint of the texture in colour scenes ("color", default white) */
} sim_layer;

typedef struct sim_video2d {
    int nlayers;
    sim_layer layer[SIM_LAYERS_MAX]; /* sorted near to far after parsing */
    double background;               /* value where no layer covers */
    double background_rgb[3];        /* colour scenes: "background_color", default the grey background */
} sim_video2d;

/* Parse the "layers" array and "background" of the scene object `root`. w, h give layer defaults (a layer
 * without size covers the frame). Texture seeds derive from `seed`. */
int sim_video2d_parse(const sci_json_doc *doc, const json_t *root, const char *base_dir, int w, int h,
                      uint64_t seed, sim_video2d *out, sci_error *err);
void sim_video2d_clear(sim_video2d *v);
/* Render the scene at time t (frames) into `out` (w×h floats, row-major) with s×s samples per pixel.
 * Reentrant; OpenMP over rows. */
void sim_video2d_render(const sim_video2d *v, int w, int h, int s, double t, float *out);
/* Colour: render channel `channel` (0 R, 1 G, 2 B: texture value × the layer's colour) of every pixel, or with
 * channel −1 the raw Bayer mosaic under `cfa` (recon/demosaic.h: each pixel its filter's channel). Same cost as
 * the grey render; sim_video2d_render is this with no colour at all. */
void sim_video2d_render_color(const sim_video2d *v, int w, int h, int s, double t, int cfa, int channel, float *out);

#endif
