/* recon/wnnm.h — the weighted-nuclear-norm (WNNM) video denoiser of DeSCI (Liu, Yuan, Suo, Brady, Dai, "Rank
 * minimization for snapshot compressive imaging", TPAMI 2019; liuyang12/DeSCI packages/denoiser/WNNM/wnnm_vdenoise:
 * v2patch.m, vblockmatch.m, vpatchestimate.m, wnnm.m, patch2v.m), one pass as gapwnnm_int.m runs it.
 *
 * For every key patch of every frame (recon/blockmatch.h), its group: the `group` most similar p×p patches within
 * ±window positions in all frames, as the columns of a p² × n matrix Y. Per group:
 *     Ȳ = the mean patch;  Y − Ȳ = U S Vᵀ;  C0 = c·√n·2σ²;  Δᵢ = (sᵢ + ε)² − 4·C0;
 *     ŝᵢ = max((sᵢ − ε + √Δᵢ)/2, 0) where Δᵢ > 0, else 0;  X = U diag(ŝ) Vᵀ + Ȳ
 * (the closed form of Gu et al., IJCV 2017, that wnnm.m uses; ε is MATLAB's eps, 2.2e-16, so it only matters
 * for exact zeros). Overlapping estimates are averaged per pixel (patch2v.m; every pixel is covered because each
 * key belongs to its own group).
 *
 * The SVD goes through the smaller Gram matrix: (Y − Ȳ)(Y − Ȳ)ᵀ (p² × p²) when p² ≤ n, else its n × n transpose
 * product, whose eigenpairs are the squared singular values and singular vectors; only those with λ = s² above the
 * threshold (2√C0 − ε)² are computed (Householder reduction to tridiagonal form, Sturm counts and bisection, LAPACK's
 * sstein for the vectors), then X − Ȳ = U_k diag(ŝ/s) U_kᵀ (Y − Ȳ). Float throughout; against a double-precision
 * SVD the estimate agrees to about 1e-6 of the data's range (tests/unit/test_wnnm.c).
 *
 * Where DeSCI's paper and code differ, this follows the code as test_desci.m runs it: WNNM is one pass (iternum
 * = 1), so the per-patch noise estimate of v2patch.m (vlambda·√|mean((est − noisy)²) − σ²|) is never used: every
 * group is shrunk with σ itself; no iterative regularisation (delta) and no reweighting (reweighit is unused in
 * wnnm.m); the weights are the IJCV closed form, not the CVPR'14 estimate kept commented out in wnnm.m.
 *
 *     sci_wnnm_params q;
 *     sci_wnnm_params_for_sigma(&q, 25);                    // σ on the 0–255 scale: patch 7, 90 patches, ...
 *     sci_wnnm *wn;
 *     rc = sci_wnnm_new(&wn, w, h, n, &q, threads, err);
 *     rc = sci_wnnm_match(wn, x->data, NULL);               // block matching on x (redo every so often)
 *     rc = sci_wnnm_denoise(wn, x->data, 25.0 / 255, x->data, NULL);   // σ on the data's scale; in place
 *     sci_wnnm_free(wn);
 *
 * Plan/execute: sci_wnnm_new allocates everything (groups, per-thread workspaces and accumulators: about
 * (threads + 1) · w·h·n doubles besides the groups' 8 bytes per member); match and denoise allocate nothing.
 * A plan serves one caller at a time. Results are deterministic for a given thread count; the per-thread
 * accumulation order makes the last bits depend on it.
 *
 * Errors: 0 or a negative code with a message (-EINVAL for bad sizes or parameters, -ENOMEM); the run functions
 * return SCI_ECANCELED when `cancel` (nullable) became nonzero, and -EIO when LAPACK failed on a group (that
 * group's patches are kept as they were; the output is complete).
 */
#ifndef SCICAP_RECON_WNNM_H
#define SCICAP_RECON_WNNM_H

#include <stdatomic.h>

#include "base/error.h"

typedef struct sci_wnnm_params {
    int patch;  /* patch side p in pixels */
    int group;  /* patches per group n (the key included) */
    int step;   /* key grid step in pixels */
    int window; /* search radius in pixel positions (±), over all frames */
    double c;   /* weight constant c (√2) */
} sci_wnnm_params;

/* DeSCI's vparaconfig.m by σ on the 0–255 scale: σ ≤ 20: patch 6, 70 patches; ≤ 40: 7, 90; ≤ 60: 8, 120; above:
 * 9, 140; step ⌊p/2 − 1⌋ (at least 1), window 30, c = √2. (Its vlambda, 0.54 … 0.58, only scales the per-patch
 * noise estimate, which the one-pass WNNM of DeSCI never uses; see above.) */
void sci_wnnm_params_for_sigma(sci_wnnm_params *p, double sigma255);
/* The key step vparaconfig.m derives from a patch size: ⌊p/2 − 1⌋, at least 1. */
int sci_wnnm_step_for_patch(int patch);

/* --- one group -------------------------------------------------------------------------------------------- */

/* Scratch for groups of up to d_max pixels × n_max patches (LAPACK's workspace sized once). */
typedef struct sci_wnnm_ws sci_wnnm_ws;
int sci_wnnm_ws_new(sci_wnnm_ws **out, int d_max, int n_max, sci_error *err);
void sci_wnnm_ws_free(sci_wnnm_ws *ws);

/* x = the WNNM estimate of group y: d × n column-major (column j = patch j's d pixels), mean patch removed and
 * added back as described above; sigma on the data's scale (>= 0), c > 0. x may alias y. Returns the number of
 * singular values kept (>= 0), or -EIO when LAPACK failed (x = y then). d <= d_max and n <= n_max of ws. */
int sci_wnnm_group(sci_wnnm_ws *ws, const float *y, int d, int n, double c, double sigma, float *x);

/* --- the video denoiser ----------------------------------------------------------------------------------- */

typedef struct sci_wnnm sci_wnnm;

/* A plan for frames of w×h×n with parameters p (patch >= 1 and no larger than the frame, group >= 1, step >= 1,
 * window >= 0, c > 0). threads: OpenMP threads of match and denoise, 0 = the default. */
int sci_wnnm_new(sci_wnnm **out, int w, int h, int n, const sci_wnnm_params *p, int threads, sci_error *err);
void sci_wnnm_free(sci_wnnm *wn);
/* The parameters in use (the group size clamped to what the search window holds). */
sci_wnnm_params sci_wnnm_params_of(const sci_wnnm *wn);

/* Block matching on `frames` (w×h×n, frame-major; only read): the groups the next denoise calls use. */
int sci_wnnm_match(sci_wnnm *wn, const float *frames, const atomic_int *cancel);
/* out = WNNM(in) with noise σ (data scale, >= 0) on the groups of the last match (matched on `in` first if there
 * was none). in and out: w×h×n; out may alias in. On SCI_ECANCELED out is left as it was. */
int sci_wnnm_denoise(sci_wnnm *wn, const float *in, double sigma, float *out, const atomic_int *cancel);

#endif
