/* io/staging.h — publish-on-success for output folders: write everything into a staging folder beside the
 * destination, then rename it into place in one step, so a reader (or a shell loop) sees the whole output or
 * nothing; on any failure or interruption the staging folder is removed.
 *
 *     char tmp[4096];
 *     sci_staging_name(tmp, sizeof tmp, out);          // "OUT.tmp-<pid>", any leftover of ours removed
 *     ... write into tmp ...
 *     rc = sci_staging_publish(tmp, out, force, &stop_flag, &err);   // or sci_staging_remove(tmp) on failure
 *
 * `stop` is a signal handler's flag (e.g. SIGINT/SIGTERM): once nonzero nothing is published. The check and
 * the rename run with SIGINT and SIGTERM blocked in the calling thread, so a signal is seen either before the
 * rename (nothing published, SCI_ECANCELED) or after it (the output was complete when it came).
 * Blocks on file-system calls; reentrant (no state beyond the folders named).
 */
#ifndef SCICAP_IO_STAGING_H
#define SCICAP_IO_STAGING_H

#include <signal.h>
#include <stddef.h>

#include "base/error.h"

/* "<dir>.tmp-<pid>" into buf, and removes a folder of that name left by an earlier process with our pid.
 * Returns 0, or -ENAMETOOLONG. */
int sci_staging_name(char *buf, size_t n, const char *dir);

/* Rename `tmp` to `dir`. An existing `dir` is replaced only if `overwrite` (else -EEXIST, "use --force"); the
 * old one is moved aside first and removed after. `stop` (may be NULL): when *stop is nonzero, SCI_ECANCELED.
 * On every error `tmp` is removed. */
int sci_staging_publish(const char *tmp, const char *dir, int overwrite, const volatile sig_atomic_t *stop,
                        sci_error *err);

/* Make a published folder durable: fsync every regular file and folder under `dir`, then `dir` itself and its
 * parent folder (which holds the rename). For callers that promise durability (the daemon with storage.fsync)
 * before they forget the work that made the folder. Symlinks are not followed; an entry that disappears during
 * the walk (another writer's staging folder renamed) is skipped. 0, or -errno of the first failure (the
 * remaining entries are still synced); -ENOENT when `dir` itself is missing. */
int sci_staging_sync(const char *dir);

/* Remove a folder tree this process created (staging or replaced output). Symlinks are removed, not followed.
 * 0 or -errno; a missing folder is 0. */
int sci_staging_remove(const char *dir);

#endif
