/* recon/admmtv.h — ADMM-TV as the MATLAB reference (liuyang12/PnP-SCI algorithms/admmdenoise.m;
 * docs/conventions.md §4):
 *
 *   θ = Aᵀ(y), b = 0; each iteration:
 *     ŷ = A(θ + b);  v = (θ + b) + λ Aᵀ((y − ŷ) ⊘ (Φ_sum + γ));  θ = TV(v − b);  b ← b − (v − θ)
 *   returns v.
 *
 * Defaults: λ = 1, γ = 1e-3, 100 iterations, TV weight 0.07, 5 TV passes (PnP-SCI; the Python ports use
 * γ = 0.01). Contract as recon/gaptv.h.
 */
#ifndef SCICAP_RECON_ADMMTV_H
#define SCICAP_RECON_ADMMTV_H

#include "recon/problem.h"
#include "recon/solver.h"

typedef struct sci_admmtv_params {
    int iters;         /* >= 1 */
    double lambda;     /* > 0 */
    double gamma;      /* >= 0: added to Φ_sum in the data step */
    double tv_weight;  /* >= 0 */
    int tv_iters;      /* >= 1 */
    int metrics_every; /* as sci_gaptv_params */
    int ssim_every;
} sci_admmtv_params;

void sci_admmtv_params_default(sci_admmtv_params *p);
int sci_admmtv_params_check(const sci_admmtv_params *p, sci_error *err);

int sci_admmtv_solve(const sci_problem *problem, const sci_admmtv_params *params, sci_result *result,
                     sci_progress_fn progress, void *user);

/* The method's row in the solver table (settings: sci_admmtv_params; presets and bench grid as GAP-TV's). */
extern const solver_ops sci_admmtv_solver;

#endif
