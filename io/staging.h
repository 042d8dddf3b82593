/* io/staging.h — publish-on-success for output folders: write everything into a staging folder beside the
 * destination, then rename it into place in one step, so a reader (or a shell loop) sees the whole output or
 * nothing; on any failure or interruption the staging folder is removed.
 *
 *     char tmp[4096];
 *     sci_staging_name(tmp, sizeof tmp, out);          // "OUT.tmp-<pid>", any leftover of ours removed
 *     ... write into tmp ...
 *     rc = sci_staging_publish(tmp, out, force ? SCI_STAGING_OVERWRITE : 0, &stop_flag, &err);
 *     // or sci_staging_remove(tmp) on failure
 *
 * `stop` is a signal handler's flag (SIGINT, SIGTERM, SIGHUP, SIGQUIT): once nonzero nothing is published. The
 * check and the rename run with those four blocked in the calling thread, so a signal is seen either before the
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

/* How sci_staging_publish publishes (or'ed). */
enum {
    SCI_STAGING_OVERWRITE = 1, /* replace an existing `dir` (else -EEXIST, "use --force") */
    /* durable before it returns 0: the staged tree is fsync'd before the rename, the folder holding `dir` after
     * it — for callers that forget the work that made the folder once it is published (the daemon with
     * storage.fsync) */
    SCI_STAGING_DURABLE = 2,
};

/* Rename `tmp` to `dir` as `flags` say. An existing `dir` is replaced only with SCI_STAGING_OVERWRITE; the old
 * one is moved aside first and removed after. `stop` (may be NULL): when *stop is nonzero, SCI_ECANCELED. On
 * every error `tmp` is removed. */
int sci_staging_publish(const char *tmp, const char *dir, int flags, const volatile sig_atomic_t *stop,
                        sci_error *err);

/* What sci_staging_sync syncs besides `path` itself (or'ed). */
enum {
    SCI_SYNC_TREE = 1,   /* a folder's regular files and folders, at any depth (to 16 levels), first */
    SCI_SYNC_PARENT = 2, /* then the folder holding `path`, which holds its name (after a rename or a create) */
};

/* fsync `path` (a regular file or a folder; a symlink is not followed: -ELOOP), and what `how` adds. Inside a
 * tree, symlinks, FIFOs and sockets are skipped (never opened: a FIFO would block), and an entry that disappears
 * during the walk (another writer's staging folder renamed) is skipped. 0, or -errno of the first failure (the
 * remaining entries are still synced); -ENOENT when `path` is missing. */
int sci_staging_sync(const char *path, int how);

/* Remove a folder tree this process created (staging or replaced output). Symlinks are removed, not followed.
 * 0 or -errno; a missing folder is 0. */
int sci_staging_remove(const char *dir);

#endif
