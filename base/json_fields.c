/* base/json_fields.c — see json_fields.h. Each type goes through the matching getter of base/json.h, so a table
 * and a hand-written call say the same thing about the same mistake. */
#include "base/json_fields.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

/* An integer member stored at `at` as the row's C type. */
static int field_read_integer(const sci_json_doc *doc, const json_t *obj, const char *objpath,
                              const sci_json_field *f, char *at, sci_error *err)
{
    long long v = 0;
    int rc = sci_json_get_int(doc, obj, objpath, f->key, f->required, (long long)f->lo, (long long)f->hi, &v, err);
    if (rc != 0)
        return rc;
    switch (f->type) {
    case SCI_JSON_INT: *(int *)(void *)at = (int)v; break;
    case SCI_JSON_U32: *(uint32_t *)(void *)at = (uint32_t)v; break;
    case SCI_JSON_SIZE: *(size_t *)(void *)at = (size_t)v; break;
    case SCI_JSON_U64: *(uint64_t *)(void *)at = (uint64_t)v; break;
    default: *(long long *)(void *)at = v; break;
    }
    return 0;
}

static int field_read_string(const sci_json_doc *doc, const json_t *obj, const char *objpath,
                             const sci_json_field *f, char *at, sci_error *err)
{
    const char *s = NULL;
    int rc = sci_json_get_string(doc, obj, objpath, f->key, f->required, &s, err);
    if (rc != 0)
        return rc;
    if (strlen(s) >= f->size) {
        char path[256];
        return sci_json_fail(doc, err, sci_json_path_key(path, sizeof path, objpath, f->key),
                             "longer than %zu bytes", f->size - 1);
    }
    memcpy(at, s, strlen(s) + 1);
    return 0;
}

int sci_json_field_read(const sci_json_doc *doc, const json_t *obj, const char *objpath, const sci_json_field *f,
                        void *out, sci_error *err)
{
    char *at = (char *)out + f->offset;
    switch (f->type) {
    case SCI_JSON_INT:
    case SCI_JSON_U32:
    case SCI_JSON_SIZE:
    case SCI_JSON_LLONG:
    case SCI_JSON_U64: return field_read_integer(doc, obj, objpath, f, at, err);
    case SCI_JSON_DOUBLE:
        return sci_json_get_double(doc, obj, objpath, f->key, f->required, f->lo, f->hi, (double *)(void *)at, err);
    case SCI_JSON_BOOL: return sci_json_get_bool(doc, obj, objpath, f->key, f->required, (int *)(void *)at, err);
    case SCI_JSON_ENUM:
        return sci_json_get_enum(doc, obj, objpath, f->key, f->required, f->names, (int *)(void *)at, err);
    case SCI_JSON_STRING: return field_read_string(doc, obj, objpath, f, at, err);
    }
    return sci_error_set(err, -EINVAL, "%s: unknown field type %d", f->key, (int)f->type);
}

int sci_json_fields_read(const sci_json_doc *doc, const json_t *obj, const char *objpath,
                         const sci_json_field *fields, size_t n, void *out, sci_error *err)
{
    for (size_t i = 0; i < n; i++) {
        int rc = sci_json_field_read(doc, obj, objpath, &fields[i], out, err);
        if (rc < 0)
            return rc;
    }
    return 0;
}
