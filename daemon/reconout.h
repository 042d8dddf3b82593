/* daemon/reconout.h — the reconstruction folders of a capture: CAPTURE/recon/METHOD for the first reconstruction
 * by a method, then METHOD.2, METHOD.3, ... (docs/capture-folder.md), so that a later request — the same user's or
 * another's — never replaces an earlier result.
 *
 * The name is chosen when the output is published, not when the job is queued, so jobs that fail or are canceled
 * leave no hole; it is one past the largest ordinal present (on disk or reserved), so numbers follow publication
 * order even after a folder was deleted. Workers that finish at once reserve their names here, in memory under a
 * lock: the store's lock file already makes the daemon the only writer of its storage, so the folders on disk and
 * these reservations are the whole truth. The caller publishes without replacing (io/staging.h): a folder that
 * appeared anyway (someone writing into the store by hand) fails that one publish rather than being lost.
 *
 *     char name[96];
 *     if (scicapd_reconout_reserve(ro, capdir, "gap-tv", name, sizeof name, &err) == 0) {  // "gap-tv", "gap-tv.2"
 *         ... write and publish CAPDIR/recon/<name> ...
 *         scicapd_reconout_release(ro, capdir, name);
 *     }
 *
 * Cost: a reservation reads the capture's recon/ folder once (a few entries). Thread-safe.
 */
#ifndef SCICAP_DAEMON_RECONOUT_H
#define SCICAP_DAEMON_RECONOUT_H

#include <stddef.h>

#include "base/error.h"

typedef struct scicapd_reconout scicapd_reconout;

/* 0 or -ENOMEM. */
int scicapd_reconout_new(scicapd_reconout **out);
/* Forgets the reservations; NULL is harmless. */
void scicapd_reconout_free(scicapd_reconout *r);

/* The next folder name for `method` under capdir/recon into name (n bytes) and reserve it until released.
 * -ENOMEM, -ENAMETOOLONG, or -errno when capdir/recon exists but cannot be read (err names it). */
int scicapd_reconout_reserve(scicapd_reconout *r, const char *capdir, const char *method, char *name, size_t n,
                             sci_error *err);
/* Drop the reservation of capdir/recon/name (published or not). */
void scicapd_reconout_release(scicapd_reconout *r, const char *capdir, const char *name);

/* The ordinal of folder `name` among `method`'s: 1 for "METHOD", k for "METHOD.k" (k >= 2), 0 when it is not
 * one of them (another method's, a temporary, "METHOD.x"). */
int scicapd_reconout_ordinal(const char *name, const char *method);
/* 1 when a folder of `method` under capdir/recon holds a result.json whose "job"."queue_entry" is `entry` (the
 * queued job saved as `entry` published it: daemon/reconq.h), else 0. */
int scicapd_reconout_published_by(const char *capdir, const char *method, const char *entry);

#endif
