/* io/problem_dir.h — a folder that holds SCI problems, the exchange format between `scicap sim`, the daemon's
 * capture folders and `scicap recon`.
 *
 * Layout (docs/formats.md):
 *     DIR/problem.json          manifest: {"format": "scicap-problem", "version": 1, "snapshots": k,
 *                               "w", "h", "n", "peak", "meas": "meas.json", "mask": "mask.json",
 *                               "truth": "truth.json" (optional), "camera": {...} (optional), "source": {...}}
 *     DIR/meas_000.exr ...      k measurements (a stack, float32 EXR: lossless)
 *     DIR/mask_000.exr ...      N masks shared by all snapshots (a stack)
 *     DIR/truth_000.exr ...     k·N truth frames, snapshot-major (a stack), when known
 *     DIR/preview_*.png, preview_truth.gif   8-bit previews of measurements, masks and truth (not read back)
 * "camera" (static3d scenes): {"fx","fy","cx","cy","near","far","poses": [[12 numbers] × k·N]}, poses
 * camera-to-world row-major 3×4, NeRF axes (recon/problem.h).
 *
 * Reading yields k problems that each own their cubes (the mask is copied per problem).
 */
#ifndef SCICAP_IO_PROBLEM_DIR_H
#define SCICAP_IO_PROBLEM_DIR_H

#include <jansson.h>

#include "io/limits.h"
#include "recon/problem.h"

/* Colour (Bayer) problems: the problems hold the raw mosaic (meas, masks and the mosaicked truth, so every grey
 * tool still works on them); the manifest adds "cfa": "RGGB" (or BGGR, GRBG, GBRG) and, when known, "truth_rgb":
 * "truth_rgb.json", a stack of k·N RGB frames as 3·k·N planes (frame f's channel c at 3f + c, recon/bayer.h),
 * previewed in colour as preview_truth_rgb_NNN.png (the first snapshot's frames). */
typedef struct sci_problem_color {
    int cfa;                           /* sci_cfa (recon/demosaic.h), not SCI_CFA_NONE */
    sci_cube *const *truth_rgb;        /* k cubes of w×h×3N, or NULL when unknown; borrowed */
} sci_problem_color;

/* How to write a problem folder; NULL opts: overwrite 0, previews 1, no shared masks, grey. */
typedef struct sci_problem_dir_opts {
    int overwrite;          /* replace an existing DIR (else -EEXIST) */
    int previews;           /* write the preview_*.png / preview_truth.gif files (most of the CPU cost of a
                             * write: the daemon's storage.previews switch) */
    /* A folder written by sci_problem_dir_write_masks with problems[0]'s masks (NULL: none): its mask.json,
     * mask_*.exr (and preview_mask_*.png with previews) are hard-linked into DIR instead of written again — a
     * folder per snapshot then costs no mask encoding. The caller vouches that the folder holds these masks; a
     * link that fails (another file system, no hard links) falls back to writing the files. Borrowed. */
    const char *masks_from;
    const sci_problem_color *color; /* a colour folder (NULL: grey); borrowed */
} sci_problem_dir_opts;

/* Write problems[0..k-1] (all the same w, h, n; same masks: problems[0]'s are written) to DIR, creating it.
 * `source` (may be NULL, borrowed) is stored under "source" (e.g. the scene and effects that made it).
 * Writes into DIR.tmp-<pid> and renames it to DIR at the end, so a reader never sees a half-written folder;
 * an existing DIR is replaced only with opts->overwrite (else -EEXIST). Returns 0 or a negative code. */
int sci_problem_dir_save(const char *dir, sci_problem *const *problems, int k, const json_t *source,
                         const sci_problem_dir_opts *opts, sci_error *err);

/* Earlier names, thin wrappers over sci_problem_dir_save for their remaining callers (cli/sim.c, cli/bench.c,
 * python/pyio.c, tests); new code calls sci_problem_dir_save. write: previews on; write_opt: previews chosen;
 * write_color: a colour folder. */
int sci_problem_dir_write(const char *dir, sci_problem *const *problems, int k, const json_t *source,
                          int overwrite, sci_error *err);
int sci_problem_dir_write_opt(const char *dir, sci_problem *const *problems, int k, const json_t *source,
                              int overwrite, int previews, sci_error *err);
int sci_problem_dir_write_color(const char *dir, sci_problem *const *problems, int k, const json_t *source,
                                const sci_problem_color *color, int overwrite, int previews, sci_error *err);

/* The mask files of a problem folder alone — mask.json, mask_*.exr and preview_mask_*.png, exactly as
 * sci_problem_dir_save writes them — into `dir` (created if missing; files replaced atomically), for
 * sci_problem_dir_opts.masks_from. */
int sci_problem_dir_write_masks(const char *dir, const sci_cube *mask, sci_error *err);

/* The colour part of a folder: *cfa = SCI_CFA_NONE (0) for a grey folder; *truth_rgb (may be NULL) receives a
 * malloc'd array of k RGB cubes (free each and the array) or NULL when the folder has none. */
int sci_problem_dir_read_color(const char *dir, int *cfa, sci_cube ***truth_rgb, int *k, sci_error *err);

/* Read DIR (or DIR/problem.json). On success *out is a malloc'd array of *k problem pointers, freed with
 * sci_problem_array_free (recon/problem.h). */
int sci_problem_dir_read(const char *dir, sci_problem ***out, int *k, sci_error *err);

/* Same, with the manifest's and each sidecar's declared sizes checked against `lim` (io/limits.h; NULL: the
 * defaults) before anything is allocated: -EFBIG naming the file and the limit. sci_problem_dir_read applies no
 * limit (the daemon reads its own captures), but both check each stack's first frame against its sidecar before
 * allocating (io/image.h, sci_stack_read_opts). */
int sci_problem_dir_read_opts(const char *dir, const sci_io_limits *lim, sci_problem ***out, int *k,
                              sci_error *err);

#endif
