/* io/limits.h — how much one input may make the tools allocate and write, checked before the work starts.
 *
 * A file is a claim, not a fact: a 2 KB .mat can declare a 1×1×2,000,000 mask (4,000,004 output files), a .mat
 * can declare 2,000,000 snapshots (2,000,000 output folders), a stack sidecar can claim 24576² pixels (2.4 GB
 * allocated before a pixel is read). The readers and writers of io/ compare what an input declares against these
 * limits first and refuse with -EFBIG and a message naming the input, the figure, the limit and the override
 * (`--allow-large` in the CLI, which passes sci_io_limits_none()).
 *
 *     sci_io_limits lim;
 *     sci_io_limits_default(&lim);             // or sci_io_limits_none(&lim) for --allow-large
 *     int rc = sci_io_limits_check_input(&lim, path, w, h, n, k, &err);   // before allocating
 *
 * The defaults leave every benchmark, simulated scene and capture we know of far inside (the largest, a 4096²
 * 8-frame reconstruction, writes about 0.7 GB in 19 files) and stop the absurd before it costs anything.
 * Plain data, no state: thread-safe.
 */
#ifndef SCICAP_IO_LIMITS_H
#define SCICAP_IO_LIMITS_H

#include <stddef.h>

#include "base/error.h"

typedef struct sci_io_limits {
    size_t input_bytes;  /* decoded input held in memory (float32 cubes of mask, meas, truth); 0: no limit */
    size_t output_bytes; /* estimated bytes one command writes; 0: no limit */
    size_t output_files; /* files and folders one command creates; 0: no limit */
} sci_io_limits;

#define SCI_IO_LIMIT_INPUT_BYTES ((size_t)2 << 30)   /* 2 GiB */
#define SCI_IO_LIMIT_OUTPUT_BYTES ((size_t)16 << 30) /* 16 GiB */
#define SCI_IO_LIMIT_OUTPUT_FILES ((size_t)100000)

/* The sizes above. */
void sci_io_limits_default(sci_io_limits *lim);
/* No limit at all (--allow-large). Sizes are still checked for arithmetic overflow (base/cube.h). */
void sci_io_limits_none(sci_io_limits *lim);

/* An input declaring k snapshots of w×h pixels with n frames each (each problem's copy of the masks, its
 * measurement and truth: 2·n·k + k + n float32 frames): 0, or -EFBIG naming `what` (a path) and the limit. lim NULL: the defaults. Non-positive sizes are the
 * caller's to refuse (they pass here). */
int sci_io_limits_check_input(const sci_io_limits *lim, const char *what, long long w, long long h, long long n,
                              long long k, sci_error *err);

/* Same for a single cube of w×h×n float32 about to be allocated (a stack sidecar's claim). */
int sci_io_limits_check_cube(const sci_io_limits *lim, const char *what, long long w, long long h, long long n,
                             sci_error *err);

/* A planned output of `bytes` in `files` files and folders: 0 or -EFBIG naming `what` (the output path). */
int sci_io_limits_check_output(const sci_io_limits *lim, const char *what, double bytes, double files,
                               sci_error *err);

#endif
