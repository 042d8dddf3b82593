/* daemon/import.h — captures made from a client's files: the "import" command (docs/protocol.md).
 *
 * The client opens its files itself and passes the open descriptors with the request line (SCM_RIGHTS, one
 * sendmsg): the daemon reads them through those descriptors only, so it reads exactly what the client may read
 * and nothing the client could not — it never opens a path a client names. What may be passed: one .mat (and a
 * second .mat holding the masks), or the files of a problem folder (problem.json, its *.json sidecars and
 * *.exr stacks). Each descriptor must be a regular file; their bytes are copied into a private staging folder,
 * ROOT/imports/.import-<job>/ (0700, removed afterwards, and at start after a crash), and read from there
 * with the readers `scicap recon` uses: io/matfile.h with the same options as its .mat input (--mask,
 * --mask-var, --meas-var, --truth-var, --scale auto|N) and the same input limits (io/limits.h), or
 * io/problem_dir.h. Each snapshot becomes one capture folder, as a bench capture does (no raw.tif, no
 * dmd_mask_*.png: meta.json says "imported" and from what), and may be reconstructed at once.
 *
 * Runs on a reconstruction worker (daemon/workers.h), never on the event loop. Not persisted: an import cut
 * short by a stop is reported canceled and leaves no capture half written.
 */
#ifndef SCICAP_DAEMON_IMPORT_H
#define SCICAP_DAEMON_IMPORT_H

#include <sys/types.h>

#include "base/error.h"
#include "daemon/import_args.h"
#include "daemon/store.h"
#include "io/matfile.h"

/* Copy the descriptors into ROOT/imports/.import-<job>/ and read the problems: *out (k problems, freed with
 * sci_problem_array_free) and, for a .mat, *info (white level and how it was chosen). The staging folder is
 * removed before returning. Errors of the readers (their messages name the option to use), -EINVAL for a
 * descriptor that is not a regular file, -EFBIG over a limit of io/limits.h (unless a->allow_large): the memory
 * the input declares, and the files its captures and reconstructions would create, the figures `scicap recon`
 * refuses the same file with — checked on what the file declares, before its data is read. */
int scicapd_import_read(scicapd_store *st, uint64_t job, scicapd_import_args *a, sci_problem ***out, int *k,
                        sci_mat_info *info, sci_error *err);
/* Store problem p (taken over) as one capture folder: id into id (32 bytes), folder into dir (1100 bytes). */
int scicapd_import_store(scicapd_store *st, const scicapd_import_args *a, const sci_mat_info *info, uid_t owner,
                         uint64_t job, int index, sci_problem *p, char *id, char *dir, sci_error *err);
/* Remove ROOT/imports (staging left by a crash). */
void scicapd_import_sweep(scicapd_store *st);

#endif
