#include "io/limits.h"

#include <errno.h>
#include <stdio.h>

void sci_io_limits_default(sci_io_limits *lim)
{
    *lim = (sci_io_limits){.input_bytes = SCI_IO_LIMIT_INPUT_BYTES,
                           .output_bytes = SCI_IO_LIMIT_OUTPUT_BYTES,
                           .output_files = SCI_IO_LIMIT_OUTPUT_FILES};
}

void sci_io_limits_none(sci_io_limits *lim) { *lim = (sci_io_limits){0}; }

static const sci_io_limits *or_default(const sci_io_limits *lim, sci_io_limits *tmp)
{
    if (lim)
        return lim;
    sci_io_limits_default(tmp);
    return tmp;
}

/* Sizes in doubles: a claim of 2^31 × 2^31 × 2^31 must compare as too large, not wrap. */
static int check_bytes(const sci_io_limits *l, const char *what, const char *claim, double bytes, sci_error *err)
{
    if (l->input_bytes && bytes > (double)l->input_bytes)
        return sci_error_set(err, -EFBIG,
                             "%s: %s: %.3g GB to hold in memory, over the input limit of %.3g GB "
                             "(--allow-large lifts the limits)",
                             what, claim, bytes / 1e9, (double)l->input_bytes / 1e9);
    return 0;
}

int sci_io_limits_check_input(const sci_io_limits *lim, const char *what, long long w, long long h, long long n,
                              long long k, sci_error *err)
{
    sci_io_limits tmp;
    const sci_io_limits *l = or_default(lim, &tmp);
    if (w < 1 || h < 1 || n < 1 || k < 1)
        return 0;
    /* each of the k problems holds its own copy of the n masks, its measurement and its n truth frames (float32);
     * the shared masks are read once more */
    const double frames = (double)n + (double)k + 2.0 * (double)n * (double)k;
    char claim[160];
    snprintf(claim, sizeof claim, "declares %lld snapshot(s) of %lldx%lld pixels with %lld frames each", k, w, h, n);
    return check_bytes(l, what, claim, frames * (double)w * (double)h * 4.0, err);
}

int sci_io_limits_check_cube(const sci_io_limits *lim, const char *what, long long w, long long h, long long n,
                             sci_error *err)
{
    sci_io_limits tmp;
    const sci_io_limits *l = or_default(lim, &tmp);
    if (w < 1 || h < 1 || n < 1)
        return 0;
    char claim[128];
    snprintf(claim, sizeof claim, "declares %lldx%lldx%lld", w, h, n);
    return check_bytes(l, what, claim, (double)w * (double)h * (double)n * 4.0, err);
}

int sci_io_limits_check_output(const sci_io_limits *lim, const char *what, double bytes, double files,
                               sci_error *err)
{
    sci_io_limits tmp;
    const sci_io_limits *l = or_default(lim, &tmp);
    if (l->output_files && files > (double)l->output_files)
        return sci_error_set(err, -EFBIG,
                             "%s: would create %.0f files and folders, over the limit of %zu "
                             "(--allow-large lifts the limits)",
                             what, files, l->output_files);
    if (l->output_bytes && bytes > (double)l->output_bytes)
        return sci_error_set(err, -EFBIG,
                             "%s: would write about %.3g GB, over the output limit of %.3g GB "
                             "(--allow-large lifts the limits)",
                             what, bytes / 1e9, (double)l->output_bytes / 1e9);
    return 0;
}
