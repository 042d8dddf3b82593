/* sim/simulate.h — run a scene: render the truth, make the masks, measure through the listed effects, and hand
 * back sci_problems (the same type a .mat file or a capture folder gives), one per snapshot.
 *
 *     sim_scene *sc;  sci_problem **p;  int k;
 *     sim_scene_load_file(&sc, "scene.json", &err);
 *     sim_run(sc, &p, &k, NULL, NULL, NULL, &err);
 *     ... sci_problem_dir_write(dir, p, k, source, 0, &err) ...
 *     sci_problem_array_free(p, k);
 *
 * Scale (sim/effects.h): truth and masks in [0, 1], measurement on the forward model's scale, peak = 1. With no
 * effects, each problem's meas is exactly sci_op_forward(mask, truth). Problems of a static3d scene carry the
 * camera (intrinsics and that snapshot's N poses). Deterministic for a given seed, at any thread count.
 */
#ifndef SCICAP_SIM_SIMULATE_H
#define SCICAP_SIM_SIMULATE_H

#include <jansson.h>

#include "recon/problem.h"
#include "sim/scene.h"

/* Render the scene at time t (frames; frame g of the sequence is t = g) into out (w×h floats). */
int sim_render_frame(const sim_scene *sc, double t, float *out);
/* Render the N truth frames of snapshot `snapshot` into truth (w×h×N). */
int sim_render_truth(const sim_scene *sc, int snapshot, sci_cube *truth, sci_error *err);

/* Colour scenes ("cfa" set): the problems sim_run gives hold the raw Bayer mosaic (truth = the mosaicked truth
 * frames, what a colour sensor behind the DMD records); this renders snapshot `snapshot`'s full RGB truth into rgb
 * (w×h×3N, frame f's channel c at 3f + c; recon/bayer.h). -EINVAL for a grey scene. */
int sim_render_truth_rgb(const sim_scene *sc, int snapshot, sci_cube *rgb, sci_error *err);

/* Called after each rendered snapshot (done of total); nonzero cancels (SCI_ECANCELED). */
typedef int (*sim_progress_fn)(void *user, int done, int total);

/* Simulate every snapshot. *out receives a malloc'd array of *k problems (free with sci_problem_array_free from
 * io/problem_dir.h, or sci_problem_free each and free the array). stats (may be NULL) is zeroed and filled. */
int sim_run(const sim_scene *sc, sci_problem ***out, int *k, sim_stats *stats, sim_progress_fn progress,
            void *user, sci_error *err);

/* The provenance record written as the problem folder's "source": the scene as loaded, the listed effects in
 * the order they were applied, the scale convention and the stats. New reference; NULL on no memory. */
json_t *sim_record_new(const sim_scene *sc, const sim_stats *stats);

#endif
