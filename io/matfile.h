/* io/matfile.h — the standard SCI benchmark .mat files (PnP-SCI layout) through libmatio.
 *
 * Variables: `mask` H×W×N, `meas` H×W×k, optional `orig` H×W×(k·N) (any numeric class, MATLAB v5 or v7.3).
 * MATLAB stores column-major: element (r, c, f) at r + H·c + H·W·f; this is the one place that converts it to the
 * project's frame-major cube (base/cube.h). Values are divided by `scale` (255 for the benchmark: truth on
 * [0, 1], sci-reconstruction.md §1); pass 0 to use 255.
 *
 * A file with k measurements gives k problems; problem j's truth is orig(:, :, N·j + 1 ... N·j + N) when orig
 * has at least N·(j+1) frames.
 *
 * Errors (message names the file and the fault): -ENOENT/-EACCES, SCI_EFORMAT (not a MAT file, truncated,
 * missing variable, non-numeric or complex variable), SCI_ESHAPE (sizes that disagree), SCI_ENONFINITE.
 */
#ifndef SCICAP_IO_MATFILE_H
#define SCICAP_IO_MATFILE_H

#include "recon/problem.h"

int sci_mat_read(const char *path, double scale, sci_problem ***out, int *k, sci_error *err);

/* Write problems as a benchmark-layout .mat (v5, compressed): mask, meas, and orig when every problem has truth.
 * Values multiplied by `scale` (0 → 255). */
int sci_mat_write(const char *path, sci_problem *const *problems, int k, double scale, sci_error *err);

#endif
