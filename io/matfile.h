/* io/matfile.h — the standard SCI benchmark .mat files (PnP-SCI layout) through libmatio.
 *
 * Variables: `mask` H×W×N, `meas` H×W×k, optional `orig` H×W×(k·N) (any numeric class, MATLAB v5 or v7.3).
 * MATLAB stores column-major: element (r, c, f) at r + H·c + H·W·f; this is the one place that converts it to the
 * project's frame-major cube (base/cube.h). sci_mat_read divides meas and truth by `scale` (255 for the benchmark:
 * truth on [0, 1], docs/conventions.md §1; 0 means 255) and keeps the masks as stored; sci_mat_read_opts infers
 * the scales (below).
 *
 * A file with k measurements gives k problems; problem j's truth is orig(:, :, N·j + 1 ... N·j + N) when orig
 * has at least N·(j+1) frames.
 *
 * Before libmatio sees a file, io/mat_verify.h checks its header, element chain, sizes and the adler32 of every
 * compressed variable, and the sizes the variables declare are held against io/limits.h before one is read.
 *
 * Errors (message names the file and the fault): -ENOENT/-EACCES, SCI_EFORMAT (not a MAT file, truncated, corrupt,
 * missing variable, non-numeric or complex variable), SCI_ESHAPE (sizes that disagree), SCI_ENONFINITE, -EFBIG
 * (over a limit of io/limits.h).
 */
#ifndef SCICAP_IO_MATFILE_H
#define SCICAP_IO_MATFILE_H

#include "io/limits.h"
#include "recon/problem.h"

int sci_mat_read(const char *path, double scale, sci_problem ***out, int *k, sci_error *err);

/* Any .mat: variable names, a separate mask file, the frames used and the scales (`scicap recon --mask FILE
 * --mask-var V --meas-var V --truth-var V --frames N --scale auto|N --mask-scale auto|N`, docs/formats.md).
 *
 * Names: NULL takes the benchmark's ("mask", "meas", "orig"). The truth is optional unless truth_var is given.
 * With mask_path and no mask_var, a mask file whose only numeric variable has another name is read anyway.
 * A missing variable is SCI_EFORMAT with a message that lists every variable present (name, H×W×..., class)
 * and names the option that picks another (--mask-var, --meas-var, --truth-var).
 *
 * Masks: H×W×N shared by every snapshot, or per snapshot as H×W×N×k, or H×W×(N·k) when the truth says N
 * (truth frames / k = N ≠ mask frames). `frames` > 0 keeps the first `frames` masks of each set (a capture that
 * used the first CR frames of a longer mask sequence); more than the set holds is SCI_ESHAPE. A truth whose frame
 * count is not a whole number of snapshots' frames (fewer than one set, or not a multiple of it and short of all
 * k) is SCI_ESHAPE naming both counts.
 *
 * Scales: the masks are divided by `mask_white` (0: inferred — their maximum when it is above 1, so measured grey
 * masks such as 0–113 land on [0, 1]; binary or already-normalised masks are kept). Meas and truth are divided by
 * `white` (0 or SCI_MAT_WHITE_AUTO: inferred): with a truth, the usual full scale at or above its maximum (1, 255,
 * 1023, 4095, 65535), and the measurement by the same unless it disagrees with the truth through the masks by more
 * than 20 % (then by what fits it, said in `how`); without a truth, from the measurement over the sum of the
 * normalised masks (a weighted mean of the frames at each pixel, so never above their maximum; its 99.9th
 * percentile over the well-lit pixels) rounded up to the same full scales, so that the frames land on [0, 1].
 * Every problem's peak is 1. `info` (may be NULL) receives the scales and frames used, one sentence saying what
 * was inferred and why (`how`), and a warning when the data look inconsistent — e.g. the measurement matches
 * fewer mask frames than it is given (the high-pass of meas correlates best with the sum of the first few masks):
 * "" otherwise. Errors as sci_mat_read. Blocks on file I/O; reentrant. */
#define SCI_MAT_WHITE_AUTO (-1.0)

typedef struct sci_mat_options {
    const char *mask_path; /* file holding the masks; NULL: the data file */
    const char *mask_var;  /* NULL: "mask" */
    const char *meas_var;  /* NULL: "meas" */
    const char *truth_var; /* NULL: "orig", optional */
    double white;          /* 0 or SCI_MAT_WHITE_AUTO: inferred; else > 0, the value of white in meas and truth */
    double mask_white;     /* 0: inferred; else > 0, the value of a fully open mask pixel */
    int frames;            /* 0: every mask frame; else the first `frames` of each mask set */
    const struct sci_io_limits *limits; /* NULL: the defaults (io/limits.h); checked on the declared sizes
                                         * before any variable is read: -EFBIG */
} sci_mat_options;

typedef struct sci_mat_info {
    double white;          /* the white level divided out of meas and truth */
    double meas_white;     /* the one divided out of meas (≠ white only when it disagreed with the truth) */
    double mask_white;     /* the level divided out of the masks */
    int frames;            /* frames per snapshot used */
    int mask_frames;       /* frames per snapshot the mask variable holds */
    int mask_per_snapshot; /* 1 when each snapshot has its own masks */
    char mask_var[64];     /* the mask variable actually read */
    char how[512];         /* what was inferred and why, one sentence; "" when everything was given */
    char warning[512];     /* what looks wrong with the data, or "" */
} sci_mat_info;

int sci_mat_read_opts(const char *path, const sci_mat_options *opts, sci_problem ***out, int *k,
                      sci_mat_info *info, sci_error *err);

/* The sizes a .mat declares, from the variables' headers alone (after io/mat_verify.h's checks; no data read):
 * *w × *h pixels, *n frames per snapshot, *k snapshots, as sci_mat_read_opts would split them. For limits
 * checked before the work starts. 0, or the errors of sci_mat_read. */
int sci_mat_probe(const char *path, const sci_mat_options *opts, long long *w, long long *h, long long *n,
                  long long *k, sci_error *err);

/* List the variables of a .mat file as "name HxWxN class, ..." into buf (for messages). 0 or SCI_EFORMAT. */
int sci_mat_list(const char *path, char *buf, size_t n);

/* Write problems as a benchmark-layout .mat (v5, compressed): mask, meas, and orig when every problem has truth.
 * Values multiplied by `scale` (0 → 255). */
int sci_mat_write(const char *path, sci_problem *const *problems, int k, double scale, sci_error *err);

#endif
