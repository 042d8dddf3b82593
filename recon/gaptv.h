/* recon/gaptv.h — GAP-TV: generalized alternating projection with the anisotropic TV denoiser, exactly as the
 * MATLAB reference (liuyang12/PnP-SCI algorithms/gapdenoise.m; docs/conventions.md §2–§3).
 *
 *   x⁰ = Aᵀ(y), ȳ = 0; each iteration: ŷ = A(x);
 *     accelerated: ȳ ← ȳ + (y − ŷ);  x ← x + λ Aᵀ((ȳ − ŷ) ⊘ Φ_sum)
 *     plain:                          x ← x + λ Aᵀ((y − ŷ) ⊘ Φ_sum)
 *     x ← TV(x, weight, tv_iters)
 *
 * Defaults (sci_gaptv_params_default) are the reference benchmark script's: accelerated, λ = 1, 100 iterations,
 * TV weight 0.07, 5 TV passes — on /255 data. (gapdenoise.m's own function default is λ = 0.2.)
 *
 * sci_gaptv_solve follows the solver contract of docs/architecture.md (Contracts: Solvers): it validates the
 * problem, fills result->frames and result->trace, calls `progress` after every iteration, and returns 0,
 * SCI_ECANCELED (result holds the estimate so far), SCI_EDIVERGED, or a validation error; the message is in
 * result->error. `result` must be zeroed by the caller and is freed with sci_result_free_contents. Blocks; uses
 * OpenMP threads; reentrant.
 */
#ifndef SCICAP_RECON_GAPTV_H
#define SCICAP_RECON_GAPTV_H

#include "recon/problem.h"
#include "recon/solver.h"

typedef struct sci_gaptv_params {
    int iters;         /* outer iterations, >= 1 */
    double lambda;     /* step size λ, > 0 */
    int accelerate;    /* 1: accelerated GAP (ȳ accumulation), 0: plain */
    double tv_weight;  /* TV weight on the data's scale, >= 0 */
    int tv_iters;      /* TV passes, >= 1 */
    int metrics_every; /* PSNR against truth every k iterations (0: only at the end) */
    int ssim_every;    /* SSIM every k iterations (0: only at the end) */
} sci_gaptv_params;

void sci_gaptv_params_default(sci_gaptv_params *p);
/* -EINVAL with a message naming the parameter and its value when out of range. */
int sci_gaptv_params_check(const sci_gaptv_params *p, sci_error *err);

int sci_gaptv_solve(const sci_problem *problem, const sci_gaptv_params *params, sci_result *result,
                    sci_progress_fn progress, void *user);

/* The method's row in the solver table (settings: sci_gaptv_params). */
extern const solver_ops sci_gaptv_solver;
/* Shared with ADMM-TV (same knobs): the presets — fast 80 iterations, balanced 130, best 300, 5 TV passes each,
 * from the measured curves (gaptv.c) — and the bench grids (iterations × TV passes, and the presets). */
void sci_tv_solver_preset(int *iters, int *tv_iters, solver_preset p);
extern const char *const sci_tv_solver_bench_quick[];
extern const char *const sci_tv_solver_bench_full[];

#endif
