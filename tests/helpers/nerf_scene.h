/* tests/helpers/nerf_scene.h — the tiny static3d problem the NeRF solver tests share, and their baselines.
 *
 * For use inside cmocka tests: a failure to build the scene fails the calling test (fail_msg).
 */
#ifndef SCICAP_TESTS_NERF_SCENE_H
#define SCICAP_TESTS_NERF_SCENE_H

#include "recon/problem.h"

/* The test's seed: $SCICAP_TEST_SEED when set, else `dflt`; printed so that a failure can be replayed. */
unsigned long long test_seed_env(unsigned long long dflt);

/* A w×w×4 static3d scene (one snapshot, with truth and camera): a checkered sphere before a noise-textured wall,
 * the camera sliding 0.3 units and panning to keep the sphere in view. Caller owns the problem
 * (sci_problem_free). */
sci_problem *nerf_tiny_problem(int w, unsigned long long seed);

/* PSNR (peak = p->peak) of the mean-frame baseline: every frame = y ⊘ Σ M (0 where no mask is open). */
double nerf_mean_frame_psnr(const sci_problem *p);

#endif
