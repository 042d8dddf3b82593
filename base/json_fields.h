/* base/json_fields.h — typed, range-checked members of a JSON object, read by a table instead of a call per key.
 *
 * A table row names a key, the C type and offset it is stored at, its inclusive range, whether it is required,
 * and one line of help. sci_json_fields_read checks every row against the object and stores the values; the
 * messages are those of the typed getters of base/json.h, positioned in the document:
 *     scene.json:3:3: width: must be in [1, 16384] (got -4)
 *
 *     static const sci_json_field rows[] = {
 *         {"width", SCI_JSON_INT, offsetof(scene, w), .lo = 1, .hi = 16384, .required = 1, .help = "pixels"},
 *         {"gain", SCI_JSON_DOUBLE, offsetof(scene, gain), .lo = 0, .hi = 10, .help = "multiplier"},
 *     };
 *     rc = sci_json_fields_read(doc, obj, "", rows, SCI_JSON_FIELDS_COUNT(rows), &s, &err);
 *
 * An absent optional key leaves its member untouched: set the defaults before reading. Unknown keys are not
 * looked at here (sci_json_check_keys does that). Not thread-safe per document, as base/json.h.
 */
#ifndef SCICAP_BASE_JSON_FIELDS_H
#define SCICAP_BASE_JSON_FIELDS_H

#include <stddef.h>

#include "base/json.h"

typedef enum sci_json_type {
    SCI_JSON_INT,    /* int; JSON integer in [lo, hi] */
    SCI_JSON_U32,    /* uint32_t; JSON integer in [lo, hi] (lo >= 0) */
    SCI_JSON_SIZE,   /* size_t; JSON integer in [lo, hi] (lo >= 0) */
    SCI_JSON_LLONG,  /* long long; JSON integer in [lo, hi] (|lo|, |hi| <= 2^53: exact as doubles) */
    SCI_JSON_U64,    /* uint64_t; JSON integer in [lo, hi] (0 <= lo, hi <= 2^53) */
    SCI_JSON_DOUBLE, /* double; JSON number in [lo, hi] */
    SCI_JSON_BOOL,   /* int 0/1; JSON true/false */
    SCI_JSON_ENUM,   /* int; JSON string among names[], stored as its position */
    SCI_JSON_STRING, /* char[size], NUL-terminated copy; longer than size - 1 bytes is an error */
} sci_json_type;

typedef struct sci_json_field {
    const char *key;          /* member name */
    sci_json_type type;
    size_t offset;            /* of the member in the struct handed to sci_json_fields_read */
    double lo, hi;            /* inclusive range (number types) */
    const char *const *names; /* ENUM: NULL-terminated choices */
    size_t size;              /* STRING: bytes of the buffer, NUL included */
    int required;             /* absent is an error ("missing required key") */
    const char *help;         /* one line, for documentation and help texts */
} sci_json_field;

#define SCI_JSON_FIELDS_COUNT(rows) (sizeof(rows) / sizeof((rows)[0]))

/* Read every row of fields[0..n-1] from member keys of `obj` (at `objpath` in doc) into the struct at `out`.
 * Stops at the first bad value: SCI_ECONFIG with "name:line:col: path: reason" in err. Returns 0 otherwise. */
int sci_json_fields_read(const sci_json_doc *doc, const json_t *obj, const char *objpath,
                         const sci_json_field *fields, size_t n, void *out, sci_error *err);

/* Read one row (see sci_json_fields_read). Returns 0 when stored, 1 when absent and optional, or SCI_ECONFIG. */
int sci_json_field_read(const sci_json_doc *doc, const json_t *obj, const char *objpath, const sci_json_field *f,
                        void *out, sci_error *err);

#endif
