/* io/recon_store.h — write one reconstruction to a folder, as `scicap recon` and the daemon's recon/<method>/ do:
 *
 *     DIR/frame_000.exr ...   the N frames, float32 EXR (uncompressed: they compress by 2 %), on the problem's
 *                             scale (+ frame.json sidecar)
 *     DIR/preview_000.png ... 8-bit previews, value/peak·255 clamped (or auto-contrast: value/top·255, top the
 *                             frames' 99.5th percentile; the range is stated in each PNG's description and in
 *                             result.json "preview")
 *     DIR/compare.png         with a truth: truth | reconstruction | difference (|x − truth|·4), a row per frame
 *     DIR/preview.gif         animated preview of the N frames
 *     DIR/trace.csv           the solver trace (iteration, wall and CPU time, residual, PSNR, SSIM)
 *     DIR/result.json         method, parameters, status, final metrics (both PSNR conventions named), timings,
 *                             the frames' levels ("levels": 1st and 99th percentile, fraction of white) and
 *                             "warnings" when they sit far below or above white (a wrong scale)
 *
 * The folder is written under DIR.tmp-<pid> and renamed at the end (io/staging.h): a reader sees all of it or
 * nothing, and on any failure the temporary is removed. An existing DIR is replaced only with
 * SCI_STAGING_OVERWRITE. The GIF is scaled down for large frames
 * (io/image.h, SCI_GIF_MAX_PIXELS).
 */
#ifndef SCICAP_IO_RECON_STORE_H
#define SCICAP_IO_RECON_STORE_H

#include <jansson.h>
#include <signal.h>

#include "io/staging.h"
#include "recon/problem.h"

/* How to write: every field may stay zero (NULL opts: all zero). */
typedef struct sci_recon_store_opts {
    /* Members added at the top level of result.json (may be NULL, borrowed): the daemon records there which
     * queued job wrote the folder ("job": {"id", "queue_entry"}), so that a restart after a crash between
     * publishing and forgetting the job sees the job done (daemon/reconq.h). */
    const json_t *extra;
    int flags; /* SCI_STAGING_* of io/staging.h: OVERWRITE an existing DIR (else -EEXIST); DURABLE: on disk, name
                * included, before it returns 0 */
    /* Polled between files (may be NULL, e.g. a SIGTERM handler's flag): once it is nonzero the temporary is
     * removed and SCI_ECANCELED returned — an interrupted write never publishes DIR. */
    const volatile sig_atomic_t *stop;
    int preview_auto; /* 1: previews auto-contrast (top = the 99.5th percentile); 0: [0, peak] */
} sci_recon_store_opts;

/* Write the reconstruction `r` of `p` to DIR as laid out above. `params` (may be NULL, borrowed) is copied into
 * result.json; `o` may be NULL. Returns 0 or a negative code with err naming the folder or file. */
int sci_recon_store_save(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                         const sci_recon_store_opts *o, sci_error *err);

/* Earlier names, thin wrappers over sci_recon_store_save for their remaining callers (python/pyio.c,
 * daemon/workers.c); new code calls sci_recon_store_save. */
int sci_recon_store_write(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                          int overwrite, sci_error *err);
int sci_recon_store_write_ex(const char *dir, const sci_problem *p, const sci_result *r, const json_t *params,
                             const json_t *extra, int flags, const volatile sig_atomic_t *stop, sci_error *err);

/* The levels of a reconstruction against its white (p->peak): *p1 and *p99 the 1st and 99th percentiles of the
 * frames over peak (NaN without frames), and into buf (n bytes) a warning when the frames are nearly black
 * (p99 < 0.05) or far above white (p99 > 2), else "". Returns 1 when it wrote a warning. */
int sci_recon_levels(const sci_problem *p, const sci_cube *frames, double *p1, double *p99, char *buf, size_t n);

/* What sci_recon_store_save makes for `snapshots` reconstructions of w×h×n: *bytes (an upper estimate: float
 * EXR frames uncompressed, 8-bit previews, a block of file-system overhead per file) and *files (files and
 * folders). For io/limits.h, before the work starts. */
void sci_recon_store_estimate(long long w, long long h, long long n, long long snapshots, double *bytes,
                              double *files);

/* The summary that goes into result.json, as a new JSON object (caller json_decrefs). */
json_t *sci_recon_summary(const sci_problem *p, const sci_result *r, const json_t *params);

#endif
