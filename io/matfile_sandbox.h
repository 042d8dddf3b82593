/* io/matfile_sandbox.h — MATLAB v7.3 (HDF5) files read in a child process (io/sandbox.h), internal to io/matfile.c.
 *
 * libhdf5 can overflow its heap on a malformed file; reading a v7.3 file in a fork turns such a crash (or a hang,
 * after SCI_MAT_SANDBOX_TIMEOUT_MS) into SCI_EFORMAT naming the file, and the caller's process is untouched. The
 * problems come back through a pipe as their cubes' floats; what the reader said (its error, sci_mat_info) too.
 */
#ifndef SCICAP_IO_MATFILE_SANDBOX_H
#define SCICAP_IO_MATFILE_SANDBOX_H

#include "io/matfile.h"
#include "recon/problem.h"

#define SCI_MAT_SANDBOX_TIMEOUT_MS 300000 /* 5 min: a real capture's v7.3 file of GBs reads in well under one */

/* 1 when path (or, when given, mask_path) starts with a MATLAB v7.3 header (version 0x0200 at byte 124). */
int sci_mat_is_v73(const char *path, const char *mask_path);

/* The readers of io/matfile.c, run in a child: the same results and errors, or SCI_EFORMAT when the child
 * crashed, -ETIMEDOUT when it hung. `read` is the in-process reader to run there. */
typedef int (*sci_mat_read_fn)(const char *path, const sci_mat_options *o, double legacy, sci_problem ***out,
                               int *k, sci_mat_info *info, sci_error *err);
int sci_mat_read_sandboxed(sci_mat_read_fn read, const char *path, const sci_mat_options *o, double legacy,
                           sci_problem ***out, int *k, sci_mat_info *info, sci_error *err);
typedef int (*sci_mat_probe_fn)(const char *path, const sci_mat_options *o, long long *w, long long *h,
                                long long *n, long long *k, sci_error *err);
int sci_mat_probe_sandboxed(sci_mat_probe_fn probe, const char *path, const sci_mat_options *o, long long *w,
                            long long *h, long long *n, long long *k, sci_error *err);

#endif
