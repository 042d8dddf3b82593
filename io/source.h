/* io/source.h — open any problem source by its path: a benchmark .mat file or a problem folder (written by
 * `scicap sim` or by the daemon's capture store). Dispatch is by what the path is: a .mat extension goes to
 * io/matfile.h (scales inferred), a folder or a problem.json to io/problem_dir.h. Anything else is SCI_EFORMAT with
 * a message that says what was expected. Result and errors as the underlying readers. */
#ifndef SCICAP_IO_SOURCE_H
#define SCICAP_IO_SOURCE_H

#include "io/matfile.h"
#include "recon/problem.h"

int sci_source_read(const char *path, sci_problem ***out, int *k, sci_error *err);

/* Same with the .mat options (io/matfile.h: variable names, mask file, white level; info may be NULL). Options
 * that are set for a problem folder are refused (-EINVAL): a folder names its parts and its scale itself; the
 * limits (opts->limits, io/limits.h) apply to both. sci_source_read applies the default limits. */
int sci_source_read_opts(const char *path, const sci_mat_options *opts, sci_problem ***out, int *k,
                         sci_mat_info *info, sci_error *err);
/* The sizes `path` declares, without reading its data: w × h pixels, n frames per snapshot, k snapshots (a .mat:
 * sci_mat_probe; a folder: its problem.json, 0 for what it does not state). For output limits checked before the
 * work starts. 0 or an error as the readers'. */
int sci_source_probe(const char *path, const sci_mat_options *opts, long long *w, long long *h, long long *n,
                     long long *k, sci_error *err);

/* 1 if sci_source_read would read `path` as a .mat file. */
int sci_source_is_mat(const char *path);

#endif
