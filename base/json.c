#include "base/json.h"

#include "base/file.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct json_pos {
    char *path;
    int line, col;
} json_pos;

struct sci_json_doc {
    char *name;
    json_t *root;
    json_pos *pos;
    size_t npos, cap;
};

/* --- the position index: a scan of text that jansson has already accepted, so it may assume valid JSON --- */

typedef struct scanner {
    const char *s, *end;
    int line, col;
    sci_json_doc *doc;
    int failed;
} scanner;

static void sc_advance(scanner *sc)
{
    if (*sc->s == '\n') {
        sc->line++;
        sc->col = 1;
    } else if ((*sc->s & 0xC0) != 0x80) { /* count UTF-8 characters, not bytes */
        sc->col++;
    }
    sc->s++;
}

static void sc_skip_ws(scanner *sc)
{
    while (sc->s < sc->end && (*sc->s == ' ' || *sc->s == '\t' || *sc->s == '\n' || *sc->s == '\r'))
        sc_advance(sc);
}

static void sc_record(scanner *sc, const char *path, int line, int col)
{
    sci_json_doc *d = sc->doc;
    if (d->npos == d->cap) {
        size_t cap = d->cap ? d->cap * 2 : 64;
        json_pos *p = realloc(d->pos, cap * sizeof *p);
        if (!p) {
            sc->failed = 1;
            return;
        }
        d->pos = p;
        d->cap = cap;
    }
    char *copy = strdup(path);
    if (!copy) {
        sc->failed = 1;
        return;
    }
    d->pos[d->npos++] = (json_pos){copy, line, col};
}

/* Reads a string token at sc->s (which is '"'), decoding simple escapes into buf. */
static void sc_string(scanner *sc, char *buf, size_t n)
{
    size_t k = 0;
    sc_advance(sc); /* opening quote */
    while (sc->s < sc->end && *sc->s != '"') {
        char c = *sc->s;
        if (c == '\\' && sc->s + 1 < sc->end) {
            sc_advance(sc);
            c = *sc->s;
            switch (c) {
            case 'n': c = '\n'; break;
            case 't': c = '\t'; break;
            case 'r': c = '\r'; break;
            case 'b': c = '\b'; break;
            case 'f': c = '\f'; break;
            default: break; /* \" \\ \/ as themselves; \uXXXX kept verbatim (keys with them are not expected) */
            }
        }
        if (buf && k + 1 < n)
            buf[k++] = c;
        sc_advance(sc);
    }
    if (sc->s < sc->end)
        sc_advance(sc); /* closing quote */
    if (buf)
        buf[k] = 0;
}

static void sc_value(scanner *sc, const char *path, int depth);

static void sc_value(scanner *sc, const char *path, int depth)
{
    sc_skip_ws(sc);
    if (sc->s >= sc->end || depth > 2048 || sc->failed)
        return;
    char c = *sc->s;
    if (c == '{') {
        sc_advance(sc);
        for (;;) {
            sc_skip_ws(sc);
            if (sc->s >= sc->end || *sc->s == '}')
                break;
            if (*sc->s == ',') {
                sc_advance(sc);
                continue;
            }
            int line = sc->line, col = sc->col;
            char key[256], sub[1024];
            sc_string(sc, key, sizeof key);
            sci_json_path_key(sub, sizeof sub, path, key);
            sc_record(sc, sub, line, col);
            sc_skip_ws(sc);
            if (sc->s < sc->end && *sc->s == ':')
                sc_advance(sc);
            sc_value(sc, sub, depth + 1);
        }
        if (sc->s < sc->end)
            sc_advance(sc);
    } else if (c == '[') {
        sc_advance(sc);
        size_t i = 0;
        for (;;) {
            sc_skip_ws(sc);
            if (sc->s >= sc->end || *sc->s == ']')
                break;
            if (*sc->s == ',') {
                sc_advance(sc);
                continue;
            }
            char sub[1024];
            sci_json_path_index(sub, sizeof sub, path, i++);
            sc_record(sc, sub, sc->line, sc->col);
            sc_value(sc, sub, depth + 1);
        }
        if (sc->s < sc->end)
            sc_advance(sc);
    } else if (c == '"') {
        sc_string(sc, NULL, 0);
    } else {
        while (sc->s < sc->end && !strchr(",]} \t\r\n", *sc->s))
            sc_advance(sc);
    }
}

char *sci_json_path_key(char *buf, size_t n, const char *parent, const char *key)
{
    if (parent && *parent)
        snprintf(buf, n, "%s.%s", parent, key);
    else
        snprintf(buf, n, "%s", key);
    return buf;
}

int sci_json_set_kv(json_t *obj, const char *kv)
{
    const char *eq = strchr(kv, '=');
    char key[128];
    if (!eq || eq == kv || (size_t)(eq - kv) >= sizeof key)
        return -EINVAL;
    memcpy(key, kv, (size_t)(eq - kv));
    key[eq - kv] = 0;
    json_t *v = json_loads(eq + 1, JSON_DECODE_ANY, NULL);
    if (!v && !(v = json_string(eq + 1)))
        return -EINVAL; /* not UTF-8 (jansson keeps only valid strings) */
    return json_object_set_new(obj, key, v) == 0 ? 0 : -ENOMEM;
}

char *sci_json_path_index(char *buf, size_t n, const char *parent, size_t index)
{
    snprintf(buf, n, "%s[%zu]", parent ? parent : "", index);
    return buf;
}

int sci_json_doc_load_string(sci_json_doc **out, const char *name, const char *text, size_t len, sci_error *err)
{
    *out = NULL;
    json_error_t je;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES, &je);
    if (!root)
        return sci_error_set(err, SCI_ECONFIG, "%s:%d:%d: %s", name, je.line, je.column, je.text);
    sci_json_doc *doc = calloc(1, sizeof *doc);
    if (!doc || !(doc->name = strdup(name))) {
        free(doc);
        json_decref(root);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", name);
    }
    doc->root = root;
    scanner sc = {text, text + len, 1, 1, doc, 0};
    sc_record(&sc, "", 1, 1);
    sc_value(&sc, "", 0);
    if (sc.failed) {
        sci_json_doc_free(doc);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", name);
    }
    /* The root's position is where its first character is. */
    *out = doc;
    return 0;
}

int sci_json_doc_load_file(sci_json_doc **out, const char *path, sci_error *err)
{
    *out = NULL;
    void *text;
    size_t len;
    int rc = sci_file_read(path, (size_t)1 << 30, &text, &len, err);
    if (rc < 0)
        return rc;
    rc = sci_json_doc_load_string(out, path, text, len, err);
    free(text);
    return rc;
}

void sci_json_doc_free(sci_json_doc *doc)
{
    if (!doc)
        return;
    for (size_t i = 0; i < doc->npos; i++)
        free(doc->pos[i].path);
    free(doc->pos);
    json_decref(doc->root);
    free(doc->name);
    free(doc);
}

json_t *sci_json_doc_root(const sci_json_doc *doc) { return doc->root; }
const char *sci_json_doc_name(const sci_json_doc *doc) { return doc->name; }

int sci_json_doc_where(const sci_json_doc *doc, const char *path, int *line, int *col)
{
    for (size_t i = 0; i < doc->npos; i++)
        if (strcmp(doc->pos[i].path, path) == 0) {
            *line = doc->pos[i].line;
            *col = doc->pos[i].col;
            return 0;
        }
    return -ENOENT;
}

int sci_json_fail(const sci_json_doc *doc, sci_error *err, const char *path, const char *fmt, ...)
{
    char msg[SCI_ERROR_MSG_MAX], probe[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    int line = 1, col = 1;
    /* Walk up to the nearest ancestor the index knows (a missing key points at its object). */
    snprintf(probe, sizeof probe, "%s", path ? path : "");
    while (sci_json_doc_where(doc, probe, &line, &col) < 0 && *probe) {
        char *dot = strrchr(probe, '.'), *br = strrchr(probe, '[');
        char *cut = dot > br ? dot : br;
        if (!cut)
            probe[0] = 0;
        else
            *cut = 0;
    }
    return sci_error_set(err, SCI_ECONFIG, "%s:%d:%d: %s%s%s", doc->name, line, col, path && *path ? path : "",
                         path && *path ? ": " : "", msg);
}

static const json_t *member(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key,
                            int required, char *path, size_t n, int *rc, sci_error *err)
{
    sci_json_path_key(path, n, objpath, key);
    *rc = 0;
    const json_t *v = json_is_object(obj) ? json_object_get(obj, key) : NULL;
    if (!v || json_is_null(v)) {
        *rc = required ? sci_json_fail(doc, err, path, "required key is missing") : 1;
        return NULL;
    }
    return v;
}

int sci_json_get_int(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key, int required,
                     long long min, long long max, long long *out, sci_error *err)
{
    char path[1024];
    int rc;
    const json_t *v = member(doc, obj, objpath, key, required, path, sizeof path, &rc, err);
    if (!v)
        return rc;
    long long x;
    if (json_is_integer(v))
        x = json_integer_value(v);
    else if (json_is_real(v) && json_real_value(v) == floor(json_real_value(v)) && fabs(json_real_value(v)) < 9e15)
        x = (long long)json_real_value(v);
    else
        return sci_json_fail(doc, err, path, "must be an integer");
    if (x < min || x > max)
        return sci_json_fail(doc, err, path, "must be in [%lld, %lld] (got %lld)", min, max, x);
    *out = x;
    return 0;
}

int sci_json_get_double(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key,
                        int required, double min, double max, double *out, sci_error *err)
{
    char path[1024];
    int rc;
    const json_t *v = member(doc, obj, objpath, key, required, path, sizeof path, &rc, err);
    if (!v)
        return rc;
    if (!json_is_number(v))
        return sci_json_fail(doc, err, path, "must be a number");
    double x = json_number_value(v);
    if (!isfinite(x) || x < min || x > max)
        return sci_json_fail(doc, err, path, "must be in [%g, %g] (got %g)", min, max, x);
    *out = x;
    return 0;
}

int sci_json_get_bool(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key, int required,
                      int *out, sci_error *err)
{
    char path[1024];
    int rc;
    const json_t *v = member(doc, obj, objpath, key, required, path, sizeof path, &rc, err);
    if (!v)
        return rc;
    if (!json_is_boolean(v))
        return sci_json_fail(doc, err, path, "must be true or false");
    *out = json_is_true(v);
    return 0;
}

int sci_json_get_string(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key,
                        int required, const char **out, sci_error *err)
{
    char path[1024];
    int rc;
    const json_t *v = member(doc, obj, objpath, key, required, path, sizeof path, &rc, err);
    if (!v)
        return rc;
    if (!json_is_string(v))
        return sci_json_fail(doc, err, path, "must be a string");
    *out = json_string_value(v);
    return 0;
}

int sci_json_get_enum(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key, int required,
                      const char *const *choices, int *index, sci_error *err)
{
    const char *s = NULL;
    int rc = sci_json_get_string(doc, obj, objpath, key, required, &s, err);
    if (rc != 0)
        return rc;
    char list[400] = "";
    for (int i = 0; choices[i]; i++) {
        if (strcmp(s, choices[i]) == 0) {
            *index = i;
            return 0;
        }
        size_t l = strlen(list);
        snprintf(list + l, sizeof list - l, "%s\"%s\"", i ? ", " : "", choices[i]);
    }
    char path[1024];
    return sci_json_fail(doc, err, sci_json_path_key(path, sizeof path, objpath, key),
                         "unknown value \"%s\" (expected one of %s)", s, list);
}

int sci_json_check_keys(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *const *allowed,
                        sci_error *err)
{
    if (!json_is_object(obj))
        return sci_json_fail(doc, err, objpath, "must be an object");
    const char *key;
    json_t *v;
    json_object_foreach((json_t *)obj, key, v) {
        int ok = 0;
        for (int i = 0; allowed[i] && !ok; i++)
            ok = strcmp(key, allowed[i]) == 0;
        if (!ok) {
            char path[1024];
            return sci_json_fail(doc, err, sci_json_path_key(path, sizeof path, objpath, key), "unknown key");
        }
    }
    return 0;
}

int sci_json_write_atomic(const char *path, const json_t *j, size_t json_flags, mode_t mode, unsigned file_flags,
                          sci_error *err)
{
    char *text = json_dumps(j, json_flags);
    if (!text)
        return sci_error_set(err, -ENOMEM, "%s: cannot encode the document (out of memory)", path);
    int rc = sci_file_write_atomic(path, text, strlen(text), mode, file_flags, err);
    free(text);
    return rc;
}
