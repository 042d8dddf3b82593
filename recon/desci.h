/* recon/desci.h — DeSCI: GAP with the weighted-nuclear-norm (WNNM) video denoiser (Liu, Yuan, Suo, Brady, Dai,
 * "Rank minimization for snapshot compressive imaging", TPAMI 2019; liuyang12/DeSCI test_desci.m and
 * algorithms/gapwnnm_int.m, the "integrated" GAP-WNNM that reuses block matching across iterations).
 *
 *   x⁰ = Aᵀy and ȳ = 0 (or tv_init iterations of GAP-TV and ȳ = A(x⁰)); for each σ stage, each iteration:
 *     ŷ = A(x);  ȳ ← ȳ + (y − ŷ) (accelerated);  x ← x + λ Aᵀ((ȳ − ŷ) ⊘ Φ_sum)
 *     every match_every-th iteration (counted over the whole run, from the first): block matching on x
 *     x ← WNNM(x, σ_stage)                       (recon/wnnm.h: one pass, groups across all frames)
 *   → returns x
 *
 * The best preset is test_desci.m's recipe: accelerated, λ = 1, σ = 100, 50, 25, 12, 6 (0–255 scale) × 60
 * iterations each (iters 300) from x⁰ = Aᵀy, block matching every 20 iterations; the WNNM parameters of each stage
 * from σ (vparaconfig.m, sci_wnnm_params_for_sigma: patch 9/8/7/6, 140/120/90/70 patches, key step ⌊p/2 − 1⌋,
 * search ±30 in all frames, c = √2) unless patch, group, step, window or c override them. fast and balanced (the
 * defaults) start from 100 iterations of GAP-TV and run σ 12 × 20, and σ 12, 6 × 30 each (desci.c has the
 * measurements: on drop40 snapshot 1, 40.84 dB in about half a minute, 43.22 in two to four minutes, and the
 * reference recipe 43.11 in about 20).
 *
 * Where this differs from gapwnnm_int.m, on purpose:
 * - iters counts all stages and is split evenly over them, the first stages taking the remainder (as pnp-ffdnet),
 *   so that progress displays know the run's length; 300 over 5 stages is the reference's 60 each;
 * - block matching is also redone when a stage changes the patch geometry (the reference re-matches on its global
 *   count only, which with 60 per stage lands on every stage change anyway; with other counts it would index the
 *   new patch size with the old groups);
 * - the key patch is always in its own group (recon/blockmatch.h says why);
 * - tv_init (0 in the reference) can warm-start from GAP-TV, as fast and balanced do; ȳ then starts at A(x⁰)
 *   instead of 0, so that the first step is the plain GAP step (from 0 it would throw the start away).
 *
 * σ is on the 0–255 scale of 8-bit data and applied as σ/255 · peak on the problem's scale (the reference runs on
 * /255 data with vrange 1). Contract as recon/gaptv.h: validates, fills result->frames and the trace (residual,
 * PSNR/SSIM with truth, wall time), calls progress after every iteration (a nonzero return cancels), and returns 0,
 * SCI_ECANCELED (result holds the last complete iterate), SCI_EDIVERGED or an error with a message. solver_io's
 * cancel flag is also watched inside an iteration (block matching and WNNM take seconds each on 256×256×8).
 * Blocks; OpenMP threads inside (`threads`, 0: all).
 */
#ifndef SCICAP_RECON_DESCI_H
#define SCICAP_RECON_DESCI_H

#include <stdatomic.h>

#include "recon/problem.h"
#include "recon/solver.h"

typedef struct sci_desci_params {
    int iters;            /* GAP iterations over all σ stages, >= number of stages */
    solver_values sigma;  /* WNNM σ per stage on the 0–255 scale, each in (0, 255] */
    int patch;            /* patch side p; 0: from σ */
    int group;            /* patches per group; 0: from σ */
    int step;             /* key grid step; 0: ⌊p/2 − 1⌋ */
    int window;           /* search radius in positions (±), over all frames */
    double c;             /* WNNM weight constant, > 0 */
    int match_every;      /* block matching every k iterations, >= 1 */
    double lambda;        /* GAP step λ, > 0 */
    int accelerate;       /* accumulate ȳ */
    int tv_init;          /* GAP-TV iterations for the starting point (0: x⁰ = Aᵀy) */
    int threads;          /* OpenMP threads; 0 = all */
    int metrics_every, ssim_every; /* as sci_gaptv_params */
} sci_desci_params;

/* The defaults: the balanced preset, λ = 1, accelerated, window 30, c = √2, block matching every 20. */
void sci_desci_params_default(sci_desci_params *p);
/* Overwrite the cost/accuracy fields (iters, sigma, tv_init, patch, group, step, window, match_every) with a
 * preset. */
void sci_desci_preset(sci_desci_params *p, solver_preset preset);
/* -EINVAL with a message naming the field when out of range. */
int sci_desci_params_check(const sci_desci_params *p, sci_error *err);

/* cancel (nullable): also stops inside an iteration; progress as sci_progress_fn. */
int sci_desci_solve(const sci_problem *problem, const sci_desci_params *params, sci_result *result,
                    sci_progress_fn progress, void *user, const atomic_int *cancel);

/* As sci_desci_solve with solver_io's checkpoint hooks (recon/solver.h): a checkpoint every checkpoint_every
 * iterations, at the end and on a cancel, holding x, ȳ, the iteration and the image the current groups were matched
 * on (about 2N + 1 frames of floats), so that a run resumed from it (io->resume) gives the same frames as one never
 * stopped. A blob of another problem size, measurement or setting (threads and metrics intervals aside) is refused
 * with -EINVAL saying which. io must not be NULL. */
int sci_desci_solve_io(const sci_problem *problem, const sci_desci_params *params, const solver_io *io,
                       sci_result *result);

/* The method's row in the solver table (settings: sci_desci_params). */
extern const solver_ops sci_desci_solver;

#endif
