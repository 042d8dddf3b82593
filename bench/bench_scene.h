/* bench/bench_scene.h — the first snapshot of a scene file as the simulator makes it, for the NeRF benchmarks
 * (bench_nerf_compare, bench_nerf_recon). Header-only: the benchmarks are single-file programs. */
#ifndef SCICAP_BENCH_SCENE_H
#define SCICAP_BENCH_SCENE_H

#include <stdlib.h>

#include "sim/simulate.h"

/* Simulates the scene file at `path` and returns its first snapshot (the caller frees it with sci_problem_free),
 * or NULL with err set when the file does not load or the simulation fails. */
static inline sci_problem *bench_scene_first(const char *path, sci_error *err)
{
    sim_scene *sc = NULL;
    if (sim_scene_load_file(&sc, path, err) < 0)
        return NULL;
    sci_problem **p;
    int k;
    int rc = sim_run(sc, &p, &k, NULL, NULL, NULL, err);
    sim_scene_free(sc);
    if (rc < 0)
        return NULL;
    for (int i = 1; i < k; i++)
        sci_problem_free(p[i]);
    sci_problem *one = p[0];
    free(p);
    return one;
}

#endif
