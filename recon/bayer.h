/* recon/bayer.h — colour SCI with a Bayer sensor: the colour filter array (CFA), the mask × mosaic forward model,
 * and reconstruction per colour plane.
 *
 * A colour SCI prototype measures one Bayer-mosaicked snapshot: y = Σ_f M_f ⊙ B(x_f), where x_f is the RGB frame
 * f and B keeps at each pixel the colour its filter passes. The 2×2 CFA tile is named by its four colours in
 * reading order (RGGB: R at (0, 0), G at (1, 0) and (0, 1), B at (1, 1); x right, y down).
 *
 * Reconstruction (the usual route, e.g. PnP-SCI's colour benchmark): the four CFA sites of the tile are four
 * sub-sampled grey SCI problems of (w/2)×(h/2) — plane (dx, dy) holds the pixels (2i + dx, 2j + dy) of y, of every
 * mask and of the mosaicked truth — each solved by any grey method (GAP-TV, ADMM-TV), merged back into the
 * full-resolution raw mosaic frames, then demosaiced into RGB (recon/demosaic.h).
 *
 * RGB cubes: w×h×(3N), frame f's channel c (0 R, 1 G, 2 B) is frame 3f + c of the cube (planar, so every per-frame
 * tool — PSNR, stacks, EXR of one channel — works on it unchanged).
 *
 * Errors: 0 or -errno / SCI_ESHAPE with a message. Sizes must be even (-> SCI_ESHAPE). Reentrant; no globals.
 *
 *     sci_cfa cfa;  sci_cfa_parse("RGGB", &cfa);
 *     sci_bayer_solve(problem, cfa, SCI_DEMOSAIC_MHC, solve_plane, &opts, &rgb, planes, &err);
 */
#ifndef SCICAP_RECON_BAYER_H
#define SCICAP_RECON_BAYER_H

#include "recon/demosaic.h"
#include "recon/problem.h"

/* Parse "RGGB", "BGGR", "GRBG", "GBRG" (case-insensitive) or "none". 0 or -EINVAL. */
int sci_cfa_parse(const char *s, sci_cfa *out);
const char *sci_cfa_name(sci_cfa cfa); /* "RGGB", ..., "none" */

/* Mosaic an RGB cube (w×h×3N) into raw frames (w×h×N): each pixel keeps the channel its filter passes. Shapes
 * must agree (asserted). */
void sci_cfa_mosaic(sci_cfa cfa, const sci_cube *rgb, sci_cube *raw);

/* Split a full-resolution mosaic problem (meas, mask, optional raw truth; w and h even) into its four CFA-site
 * problems, planes[i] for the site (i & 1, i >> 1). Each owns its cubes and keeps the peak; names get "/R", "/Gr",
 * "/Gb" or "/B". Free with sci_problem_free. */
int sci_bayer_split(const sci_problem *p, sci_cfa cfa, sci_problem *planes[4], sci_error *err);

/* Put the four site cubes ((w/2)×(h/2)×N each) back into the raw mosaic cube (w×h×N). */
void sci_bayer_merge(sci_cube *const planes[4], sci_cube *raw);

/* Solve one grey SCI problem into r (r->frames owned by r afterwards), as the solvers do; user is passed on. */
typedef int (*sci_plane_solve_fn)(const sci_problem *plane, sci_result *r, void *user);

/* Split, solve the four planes with `solve` in turn, merge, demosaic. On success *rgb is a new w×h×3N cube (caller
 * frees) and, if raw is not NULL, *raw the merged mosaic frames (caller frees); plane_results (may be NULL)
 * receives the four results (caller frees their contents) — their traces are the cost of the reconstruction.
 * A plane's error is returned as is, its message in err. */
int sci_bayer_solve(const sci_problem *p, sci_cfa cfa, sci_demosaic_method dm, sci_plane_solve_fn solve,
                    void *user, sci_cube **rgb, sci_cube **raw, sci_result plane_results[4], sci_error *err);

#endif
