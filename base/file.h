/* base/file.h — reading a whole file, and replacing a file atomically.
 *
 * sci_file_read is for the small-to-medium files the project loads whole (JSON documents, NeRF checkpoints).
 *
 * sci_file_write_atomic* replace `path` so that a reader (or a crash, or a power cut) sees either the old
 * content or the new, never a mix: the data goes to a fresh temporary file in the same folder,
 * ".<stem>.tmp-XXXXXX<.ext>" (the rename stays inside one file system; the extension stays last for writers that
 * pick a format by it; the folder scanners that skip or sweep dot and ".tmp" names already ignore it), is
 * flushed and fsync'd, renamed over `path`, and the folder is fsync'd so the rename itself is durable. On any failure before the rename the temporary file is removed and
 * `path` is untouched (old content intact, or still absent).
 *
 *     sci_error err = {0};
 *     if (sci_file_write_atomic(path, text, strlen(text), 0644, 0, &err) < 0)
 *         fprintf(stderr, "scicap: %s\n", err.msg);
 *
 * Errors go to *err naming the path: -errno from open/read/write/fsync/rename, -EFBIG past max_bytes, -ENOMEM,
 * or whatever negative code a writer callback returned (its message kept if it set one).
 * Thread-safe: each call uses its own temporary file; two concurrent writers of one path leave one whole file.
 */
#ifndef SCICAP_BASE_FILE_H
#define SCICAP_BASE_FILE_H

#include <stddef.h>
#include <stdio.h>
#include <sys/types.h>

#include "base/error.h"

/* Reads all of `path` into a new buffer (*out, caller frees; one extra NUL byte after the data, not counted in
 * *len, so text can be used as a C string). Returns 0 or a negative errno. */
int sci_file_read(const char *path, size_t max_bytes, void **out, size_t *len, sci_error *err);

/* Flags for the atomic writers. */
enum {
    /* Skip both fsyncs (file and folder): still atomic against readers and crashes of this process, not
     * against power loss. For scratch output and for stores configured without fsync. */
    SCI_FILE_NO_SYNC = 1u << 0,
};

/* Streams the new content into `f`. Returns 0, or a negative code (optionally set in err) to abandon the
 * write; stdio errors on `f` are noticed by the caller, so a writer may ignore fprintf's return value. */
typedef int (*sci_file_writer)(FILE *f, void *user, sci_error *err);

/* Writes the new content into the file named `tmp_path` (already created, empty, with the final mode), for
 * libraries that open files by name (OpenImageIO, matio, the GIF encoder). Returns 0 or a negative code. */
typedef int (*sci_file_name_writer)(const char *tmp_path, void *user, sci_error *err);

/* Replace `path` with `len` bytes of `data`. `mode` is the new file's permission bits less the process's umask,
 * as open(2) would give them. `flags`: 0 or SCI_FILE_NO_SYNC. Returns 0 or a negative code (see above). A failing folder
 * fsync after the rename returns -errno although the new file is already in place. */
int sci_file_write_atomic(const char *path, const void *data, size_t len, mode_t mode, unsigned flags,
                          sci_error *err);

/* Like sci_file_write_atomic, the content produced by `write(f, user, err)` (for large or streamed output:
 * images, MAT files, reports). The FILE is opened "wb" by this function and closed by it. */
int sci_file_write_atomic_with(const char *path, mode_t mode, unsigned flags, sci_file_writer write, void *user,
                               sci_error *err);

/* Like sci_file_write_atomic_with, by a writer that opens the temporary file by name. */
int sci_file_write_atomic_named(const char *path, mode_t mode, unsigned flags, sci_file_name_writer write,
                                void *user, sci_error *err);

#endif
