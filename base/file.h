/* base/file.h — reading a whole file into memory.
 *
 * For the small-to-medium files the project loads whole (JSON documents, NeRF checkpoints). Errors go to *err
 * naming the path: -errno from open/read, -EFBIG past max_bytes, -ENOMEM.
 */
#ifndef SCICAP_BASE_FILE_H
#define SCICAP_BASE_FILE_H

#include <stddef.h>

#include "base/error.h"

/* Reads all of `path` into a new buffer (*out, caller frees; one extra NUL byte after the data, not counted in
 * *len, so text can be used as a C string). Returns 0 or a negative errno. */
int sci_file_read(const char *path, size_t max_bytes, void **out, size_t *len, sci_error *err);

#endif
