/* sim/bench_source.h — the scene side of the simulated bench: a frame source for the simulated camera
 * (sim/camera_sim.h) that integrates a scene over the camera's exposure window under whatever the simulated DMD
 * (sim/dmd_sim.h) showed at each moment.
 *
 * Time model: scene frame g is what the scene looks like during DMD pattern slot g, the interval
 * [t_start + g·slot_ns, t_start + (g+1)·slot_ns) after the DMD's last start (slot = exposure + dark time of one
 * pattern), looping over the scene's K·N frames. The exposure window [start_ns, end_ns) is cut at the grid of
 * `steps_per_slot` equal steps per slot; for each piece the DMD is asked which mask it shows at the piece's
 * middle (dark time and a finished sequence contribute nothing) and the piece adds
 *     (piece length / slot_ns) · M_shown ⊙ X_g
 * to the snapshot. So under ideal timing — exposure starting with the DMD sequence and lasting N slots — the
 * snapshot is the plain forward model Σ_k M_k ⊙ X_k; a wrong mask order, a late or missed trigger or a short
 * exposure shows in it exactly as on hardware. Counts = round(y · counts_white · gain/100), clamped to the
 * sample range (counts_white: counts for a white scene seen through an open mirror for one whole slot at gain 100).
 *
 * The DMD must have the camera's size (a mask pixel per sensor pixel). Rendered frames and masks are cached on
 * first use. Ownership: the scene and the dmd are borrowed and must outlive the source. Not thread-safe: it runs
 * on the camera's thread, inside camera_wait_frame.
 */
#ifndef SCICAP_SIM_BENCH_SOURCE_H
#define SCICAP_SIM_BENCH_SOURCE_H

#include <stdint.h>

#include "drivers/dmd.h"
#include "sim/camera_sim.h"
#include "sim/scene.h"

typedef struct sim_bench_source_options {
    int64_t slot_ns;       /* one DMD pattern slot (exposure + dark), ns; > 0 */
    int steps_per_slot;    /* integration pieces per slot; 0 = 8 */
    double counts_white;   /* counts per unit of y; 0 = (2^bits − 1)/N, so N white slots fill the range */
} sim_bench_source_options;

typedef struct sim_bench_source sim_bench_source;

int sim_bench_source_new(sim_bench_source **out, const sim_scene *scene, const dmd *device,
                         const sim_bench_source_options *opt, sci_error *err);
void sim_bench_source_free(sim_bench_source *s);

/* A camera_sim_source_fn: pass it with the source as `source_arg` in camera_sim_options. */
int sim_bench_source_fill(void *source, const camera_sim_exposure *e, uint16_t *samples, uint32_t w, uint32_t h,
                          int bits, sci_error *err);

/* The last snapshot before conversion to counts (w×h, forward-model scale); borrowed, NULL before the first
 * fill. Lets tests compare with sci_op_forward without the rounding to counts. */
const float *sim_bench_source_last(const sim_bench_source *s);

#endif
