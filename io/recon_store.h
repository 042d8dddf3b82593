/* io/recon_store.h — write one reconstruction to a folder, as `scicap recon` and the daemon's recon/<method>/ do:
 *
 *     DIR/frame_000.exr ...   the N frames, float32 EXR, on the problem's scale (+ frame.json sidecar)
 *     DIR/preview_000.png ... 8-bit previews, value/peak·255 clamped
 *     DIR/preview.gif         animated preview of the N frames
 *     DIR/trace.csv           the solver trace (iteration, wall and CPU time, residual, PSNR, SSIM)
 *     DIR/result.json         method, parameters, status, final metrics (both PSNR conventions named), timings
 *
 * The folder is written under DIR.tmp-<pid> and renamed at the end: a reader sees all of it or nothing.
 * `params` (may be NULL, borrowed) is copied into result.json. An existing DIR is replaced only if `overwrite`.
 */
#ifndef SCICAP_IO_RECON_STORE_H
#define SCICAP_IO_RECON_STORE_H

#include <jansson.h>

#include "recon/problem.h"

int sci_recon_store_write(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                          int overwrite, sci_error *err);

/* The summary that goes into result.json, as a new JSON object (caller json_decrefs). */
json_t *sci_recon_summary(const sci_problem *p, const sci_result *r, const json_t *params);

#endif
