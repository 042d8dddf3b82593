/* base/json.h — JSON documents (jansson) that remember where each value came from.
 *
 * Config and scene files are validated with errors of the form
 *     scene.json:12:7: effects[2].sigma: must be > 0 (got -1)
 * jansson reports positions only for syntax errors, so a sci_json_doc also keeps an index from every value's
 * path to its line and column, built by one extra scan of the text at load time.
 *
 * Paths: "" is the root, "a.b" a member, "a[2]" an array element, "a[2].b" and so on.
 *
 *     sci_json_doc *doc;
 *     if (sci_json_doc_load_file(&doc, "scene.json", &err) < 0) return err.code;
 *     long long w;
 *     rc = sci_json_get_int(doc, sci_json_doc_root(doc), "", "width", 1, 1, 65535, &w, &err);
 *
 * Getters return 0 when the key was present and valid, 1 when it is absent and not required (the output is left
 * untouched, so preset it to the default), or SCI_ECONFIG with a positioned message.
 * Not thread-safe per document; documents are independent.
 */
#ifndef SCICAP_BASE_JSON_H
#define SCICAP_BASE_JSON_H

#include <jansson.h>
#include <stddef.h>
#include <sys/types.h>

#include "base/error.h"

typedef struct sci_json_doc sci_json_doc;

/* Parse a file. Errors: -errno with the path for I/O, SCI_ECONFIG "path:line:col: reason" for bad JSON. */
int sci_json_doc_load_file(sci_json_doc **out, const char *path, sci_error *err);
/* Parse text; `name` appears in messages in place of a file name (copied). */
int sci_json_doc_load_string(sci_json_doc **out, const char *name, const char *text, size_t len, sci_error *err);
void sci_json_doc_free(sci_json_doc *doc);

json_t *sci_json_doc_root(const sci_json_doc *doc); /* borrowed, lives as long as doc */
const char *sci_json_doc_name(const sci_json_doc *doc);
/* Line and column (1-based) of the value at `path` (for members: of its key). -ENOENT if unknown. */
int sci_json_doc_where(const sci_json_doc *doc, const char *path, int *line, int *col);

/* Fill err with "name:line:col: path: message" (position of `path`, or of its nearest known ancestor) and
 * return SCI_ECONFIG. */
int sci_json_fail(const sci_json_doc *doc, sci_error *err, const char *path, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* Typed getters on member `key` of object `obj` at `objpath`; see the return convention above. */
int sci_json_get_int(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key, int required,
                     long long min, long long max, long long *out, sci_error *err);
int sci_json_get_double(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key,
                        int required, double min, double max, double *out, sci_error *err);
int sci_json_get_bool(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key, int required,
                      int *out, sci_error *err);
/* *out is borrowed from the document. */
int sci_json_get_string(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key,
                        int required, const char **out, sci_error *err);
/* Like get_string, then the value must be one of `choices` (NULL-terminated); *index receives its position. */
int sci_json_get_enum(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key, int required,
                      const char *const *choices, int *index, sci_error *err);
/* Reject members of `obj` not listed in `allowed` (NULL-terminated): catches typos in option names. */
int sci_json_check_keys(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *const *allowed,
                        sci_error *err);
/* Replace the file `path` atomically with `j` as json_dumps encodes it (`json_flags`: JSON_COMPACT,
 * JSON_INDENT(n), ...; no newline is added), through sci_file_write_atomic (base/file.h): `mode` and
 * `file_flags` (0 or SCI_FILE_NO_SYNC) as there. The text is built in memory first. Returns 0 or a negative errno
 * with err naming the path; on failure the old file is intact. */
int sci_json_write_atomic(const char *path, const json_t *j, size_t json_flags, mode_t mode, unsigned file_flags,
                          sci_error *err);
/* Set obj[KEY] from the text "KEY=VALUE", as `scicap recon --set` reads it: VALUE parsed as JSON (3, 0.5, true,
 * [1, 2], "s") and, when it is not JSON, taken as the string itself (--set mode=fast). The key is at most 127 bytes.
 * Returns 0, -EINVAL (no '=', an empty or over-long key, a value not in UTF-8) or -ENOMEM; obj is unchanged on
 * error. */
int sci_json_set_kv(json_t *obj, const char *kv);
/* Join a path: "a" + "b" -> "a.b"; "" + "b" -> "b". Writes into buf (size n); returns buf. */
char *sci_json_path_key(char *buf, size_t n, const char *parent, const char *key);
/* "a" + 2 -> "a[2]". */
char *sci_json_path_index(char *buf, size_t n, const char *parent, size_t index);

#endif
