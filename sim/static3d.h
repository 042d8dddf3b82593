/* sim/static3d.h — the SCINeRF/RayFormer setting: a static 3D scene seen by a pinhole camera that moves during
 * the exposure, rendered by ray casting.
 *
 * Objects: finite planes (two-sided rectangles), boxes and spheres, each placed by centre and rotation vector
 * (radians), textured in texture units = scene units × uv_scale (planes and box faces: the face's own 2D
 * coordinates from a corner; spheres: longitude and latitude times the radius). Shading is view-independent
 * (what a radiance field can represent): albedo × (ambient + (1 − ambient)·max(0, n·l)) with a directional light,
 * or the bare albedo when the scene has no "light". Rays that hit nothing between near and far see `background`.
 *
 * Camera (recon/problem.h, sci_camera): NeRF axes (x right, y up, looking along −z), camera-to-world poses, pixel
 * centres at +0.5. Sample (i, j) of s×s in pixel (px, py) looks along ((px + (i+½)/s − cx)/fx,
 * −(py + (j+½)/s − cy)/fy, −1); with s = 1 that is exactly the pixel-centre ray of sci_camera.
 * Path: either "start"/"end" poses, with the K·N frame poses on the SE(3) geodesic, τ_g = g/(K·N − 1) (first and
 * last poses hit exactly; sim/pose.h), or K·N explicit poses. Frame g is the instant t = g (frames); in between,
 * the pose follows the geodesic between neighbouring poses (motion blur samples sub-frame instants).
 */
#ifndef SCICAP_SIM_STATIC3D_H
#define SCICAP_SIM_STATIC3D_H

#include "base/json.h"
#include "recon/problem.h"
#include "sim/texture.h"

#define SIM_OBJECTS_MAX 64

typedef enum sim_object_kind { SIM_OBJ_PLANE, SIM_OBJ_BOX, SIM_OBJ_SPHERE } sim_object_kind;

typedef struct sim_object {
    sim_object_kind kind;
    double center[3];
    double R[9];       /* object-to-world rotation, row-major */
    double half[3];    /* half extents: plane x, y; box x, y, z; sphere radius in half[0] */
    double uv_scale;   /* texture units per scene unit */
    sim_texture tex;
} sim_object;

typedef struct sim_static3d {
    int nobjects;
    sim_object obj[SIM_OBJECTS_MAX];
    double background;
    int lit;                 /* 0: unlit (radiance = albedo) */
    double light_dir[3];     /* unit vector towards the light, world */
    double ambient;
    double fx, fy, cx, cy;   /* pixels */
    double near_m, far_m;    /* scene units along −z */
    int npose;               /* K·N frame poses */
    double (*pose)[12];      /* owned */
} sim_static3d;

/* Parse "objects", "camera", "light" and "background" of `root` for a w×h image and `frames` = K·N frames. */
int sim_static3d_parse(const sci_json_doc *doc, const json_t *root, const char *base_dir, int w, int h,
                       int frames, uint64_t seed, sim_static3d *out, sci_error *err);
void sim_static3d_clear(sim_static3d *s);
/* Camera-to-world pose at time t (frames; t = g gives frame g's pose exactly). */
void sim_static3d_pose_at(const sim_static3d *s, double t, double T[12]);
/* Render the view at time t into out (w×h floats) with s×s rays per pixel. Reentrant; OpenMP over rows. */
void sim_static3d_render(const sim_static3d *s, int w, int h, int ss, double t, float *out);
/* Fill a new sci_camera with the intrinsics and frames [first, first + n) of the poses (NULL on no memory). */
sci_camera *sim_static3d_camera(const sim_static3d *s, int first, int n);

#endif
