/* recon/solver.c — the method table and what every method's settings share: presets, JSON, ranges, the run
 * wrapper (see solver.h). */
#include "recon/solver.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "recon/admmtv.h"
#include "recon/desci.h"
#include "recon/gaptv.h"
#include "recon/pnp_ffdnet.h"
#include "recon/nerf/rayformer_solve.h"
#include "recon/nerf/scinerf_solve.h"
#include "recon/nerf/trainer.h"

/* A test build compiles this file with -DSCICAP_EXTRA_SOLVER=<its solver_ops> and links that method in: the row
 * below is then all that tells every interface about it (tests/extra_method). */
#ifdef SCICAP_EXTRA_SOLVER
extern const solver_ops SCICAP_EXTRA_SOLVER;
#endif

/* The table: one row per method, in the order help texts and reports list them. */
static const solver_ops *const solvers[] = {
    &sci_gaptv_solver,
    &sci_admmtv_solver,
    &sci_pnp_ffdnet_solver,
    &sci_desci_solver,
    &sci_rayformer_solver,
    &sci_scinerf_solver,
#ifdef SCICAP_EXTRA_SOLVER
    &SCICAP_EXTRA_SOLVER,
#endif
    NULL,
};

const char *const solver_preset_names[SOLVER_PRESET_COUNT + 1] = {"fast", "balanced", "best", NULL};

int solver_preset_parse(const char *name, solver_preset *out, int *deprecated, sci_error *err)
{
    /* scicapd's protocol 1 said default and quality; they stay accepted so old clients and configs work */
    static const struct { const char *name; solver_preset p; } alias[] = {
        {"default", SOLVER_PRESET_BALANCED},
        {"quality", SOLVER_PRESET_BEST},
    };
    if (deprecated)
        *deprecated = 0;
    for (int i = 0; i < SOLVER_PRESET_COUNT; i++)
        if (name && strcmp(name, solver_preset_names[i]) == 0) {
            *out = (solver_preset)i;
            return 0;
        }
    for (size_t i = 0; i < sizeof alias / sizeof alias[0]; i++)
        if (name && strcmp(name, alias[i].name) == 0) {
            *out = alias[i].p;
            if (deprecated)
                *deprecated = 1;
            return 0;
        }
    return sci_error_set(err, -EINVAL, "unknown preset '%.32s' (fast, balanced, best)", name ? name : "");
}

int solver_preset_get(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key,
                      solver_preset *out, sci_error *err)
{
    const char *name = NULL;
    int rc = sci_json_get_string(doc, obj, objpath, key, 0, &name, err);
    if (rc != 0)
        return rc;
    if (solver_preset_parse(name, out, NULL, NULL) < 0) {
        char kp[256];
        return sci_json_fail(doc, err, sci_json_path_key(kp, sizeof kp, objpath, key),
                             "must be fast, balanced or best (got \"%.32s\")", name);
    }
    return 0;
}

const char *solver_preset_name(solver_preset p)
{
    return (unsigned)p < SOLVER_PRESET_COUNT ? solver_preset_names[p] : "?";
}

const solver_ops *const *solver_list(size_t *count)
{
    if (count)
        *count = sizeof solvers / sizeof solvers[0] - 1;
    return solvers;
}

/* Names are copied into fixed buffers (sci_result.method, scicapd's config, the curves, a NeRF checkpoint's
 * header): one that does not fit would be cut silently there, so the table refuses it. */
static int name_check(const solver_ops *m, sci_error *err)
{
    size_t len = m->name ? strlen(m->name) : 0;
    if (len == 0)
        return sci_error_set(err, -EINVAL, "a row without a name");
    if (len >= SOLVER_NAME_MAX)
        return sci_error_set(err, -EINVAL, "%.*s...: a name of %zu bytes, SOLVER_NAME_MAX (%d) allows %d",
                             SOLVER_NAME_MAX - 1, m->name, len, SOLVER_NAME_MAX, SOLVER_NAME_MAX - 1);
    if ((m->caps & SOLVER_CHECKPOINTS) && len >= NERF_CKPT_METHOD_MAX)
        return sci_error_set(err, -EINVAL, "%s: a name of %zu bytes, a checkpoint header (NERF_CKPT_METHOD_MAX %d) "
                             "holds %d", m->name, len, NERF_CKPT_METHOD_MAX, NERF_CKPT_METHOD_MAX - 1);
    return 0;
}

int solver_list_check(sci_error *err)
{
    return solver_table_check(solvers, err);
}

int solver_table_check(const solver_ops *const *list, sci_error *err)
{
    for (size_t i = 0; list[i]; i++) {
        const solver_ops *m = list[i];
        int rc = name_check(m, err);
        if (rc < 0)
            return rc;
        const solver_field *it = solver_field_find(m, "iters", NULL);
        if (m->settings_size > SOLVER_SETTINGS_MAX)
            return sci_error_set(err, -EINVAL, "%s: settings of %zu bytes exceed SOLVER_SETTINGS_MAX (%d)", m->name,
                                 m->settings_size, SOLVER_SETTINGS_MAX);
        if (!it || it->type != SOLVER_FIELD_INT)
            return sci_error_set(err, -EINVAL, "%s: no integer \"iters\" setting", m->name);
        if (!m->defaults || !m->preset || !m->run || !m->summary || !m->bench_quick || !m->bench_full)
            return sci_error_set(err, -EINVAL, "%s: the row lacks defaults, preset, run, summary or bench grids",
                                 m->name);
        for (size_t j = 0; j < i; j++)
            if (strcmp(list[j]->name, m->name) == 0)
                return sci_error_set(err, -EINVAL, "%s: two rows of that name", m->name);
    }
    return 0;
}

const solver_ops *solver_list_find(const solver_ops *const *list, const char *name, sci_error *err)
{
    for (size_t i = 0; name && list[i]; i++)
        if (strcmp(list[i]->name, name) == 0)
            return list[i];
    char names[256] = "";
    size_t off = 0;
    for (size_t i = 0; err && list[i] && off < sizeof names; i++)
        off += (size_t)snprintf(names + off, sizeof names - off, "%s%s", i ? ", " : "", list[i]->name);
    sci_error_set(err, -EINVAL, "unknown method '%.64s' (%s)", name ? name : "", names);
    return NULL;
}

const solver_ops *solver_find(const char *name)
{
    return solver_list_find(solvers, name, NULL);
}

char *solver_names_text(char *buf, size_t n, const char *sep)
{
    size_t off = 0;
    if (n)
        buf[0] = 0;
    for (size_t i = 0; solvers[i] && off < n; i++)
        off += (size_t)snprintf(buf + off, n - off, "%s%s", i ? sep : "", solvers[i]->name);
    return buf;
}

const solver_ops *solver_find_err(const char *name, sci_error *err)
{
    return solver_list_find(solvers, name, err);
}

void *solver_settings_new(const solver_ops *m)
{
    void *s = calloc(1, m->settings_size);
    if (s)
        m->defaults(s);
    return s;
}

void solver_settings_free(void *settings)
{
    free(settings);
}

void solver_settings_preset(const solver_ops *m, void *settings, solver_preset p)
{
    m->preset(settings, p);
}

const solver_field *solver_field_find(const solver_ops *m, const char *key, size_t *base)
{
    for (int g = 0; g < 2; g++)
        for (int i = 0; i < m->fields[g].n; i++)
            if (strcmp(m->fields[g].f[i].key, key) == 0) {
                if (base)
                    *base = m->fields[g].base;
                return &m->fields[g].f[i];
            }
    return NULL;
}

/* A message at `path`: positioned when the value came from a document. */
static int fail(const sci_json_doc *doc, sci_error *err, const char *method, const char *path, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static int fail(const sci_json_doc *doc, sci_error *err, const char *method, const char *path, const char *fmt, ...)
{
    char msg[SCI_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (doc)
        return sci_json_fail(doc, err, path, "%s: %s", method, msg);
    return sci_error_set(err, -EINVAL, "%s: %s: %s", method, path, msg);
}

/* The value's position in names[] (a string, or an index in range), or -1. */
static int name_index(const char *const *names, const json_t *v)
{
    int n = 0;
    while (names[n])
        n++;
    if (json_is_integer(v))
        return json_integer_value(v) >= 0 && json_integer_value(v) < n ? (int)json_integer_value(v) : -1;
    for (int i = 0; json_is_string(v) && i < n; i++)
        if (strcmp(json_string_value(v), names[i]) == 0)
            return i;
    return -1;
}

static void names_list(char *buf, size_t n, const char *const *names)
{
    size_t off = 0;
    buf[0] = 0;
    for (int i = 0; names[i] && off < n; i++)
        off += (size_t)snprintf(buf + off, n - off, "%s%s", i ? ", " : "", names[i]);
}

/* A LIST value: a JSON array of numbers, one number (a list of one: --set sigma=12, as bench/results.csv writes
 * [12]), or a string of numbers separated by commas, spaces or slashes (--set sigma=50,25,12; the CSV writes
 * 50/25/12). */
static int list_set(const solver_ops *m, const solver_field *f, solver_values *out, const json_t *v,
                    const sci_json_doc *doc, const char *path, const char *got, sci_error *err)
{
    solver_values l = {0};
    int ok = 1;
    if (json_is_array(v)) {
        size_t i;
        const json_t *e;
        ok = json_array_size(v) >= 1 && json_array_size(v) <= SOLVER_LIST_MAX;
        json_array_foreach(v, i, e) {
            if (!ok || !json_is_number(e))
                ok = 0;
            else
                l.v[l.n++] = json_number_value(e);
        }
    } else if (json_is_number(v)) {
        l.v[l.n++] = json_number_value(v);
    } else if (json_is_string(v)) {
        const char *p = json_string_value(v);
        while (ok && *p) {
            char *end;
            double d = strtod(p, &end);
            ok = end != p && l.n < SOLVER_LIST_MAX;
            if (ok)
                l.v[l.n++] = d;
            p = end;
            while (ok && (*p == ',' || *p == ' ' || *p == '/'))
                p++;
        }
        ok = ok && l.n >= 1;
    } else {
        ok = 0;
    }
    for (int i = 0; ok && i < l.n; i++)
        ok = isfinite(l.v[i]) && l.v[i] >= f->lo && l.v[i] <= f->hi;
    if (!ok)
        return fail(doc, err, m->name, path, "must be a list of 1 to %d numbers in [%g, %g] (got %s)",
                    SOLVER_LIST_MAX, f->lo, f->hi, got);
    *out = l;
    return 0;
}

int solver_settings_set(const solver_ops *m, void *settings, const char *key, const json_t *v,
                        const sci_json_doc *doc, const char *path, sci_error *err)
{
    size_t base = 0;
    const solver_field *f = solver_field_find(m, key, &base);
    if (!f)
        return 1;
    char *at = (char *)settings + base + f->offset;
    char got[64];
    if (json_is_string(v))
        snprintf(got, sizeof got, "'%.48s'", json_string_value(v));
    else if (json_is_number(v))
        snprintf(got, sizeof got, "%.17g", json_number_value(v));
    else
        snprintf(got, sizeof got, "a JSON %s", json_is_object(v) ? "object" : json_is_array(v) ? "array"
                                               : json_is_boolean(v) ? "boolean" : "null");
    switch (f->type) {
    case SOLVER_FIELD_INT:
    case SOLVER_FIELD_SEED: {
        if (!json_is_integer(v) || (double)json_integer_value(v) < f->lo || (double)json_integer_value(v) > f->hi)
            return fail(doc, err, m->name, path, "must be an integer in [%.15g, %.15g] (got %s)", f->lo, f->hi, got);
        if (f->type == SOLVER_FIELD_INT)
            *(int *)at = (int)json_integer_value(v);
        else
            *(unsigned long long *)at = (unsigned long long)json_integer_value(v);
        return 0;
    }
    case SOLVER_FIELD_DOUBLE: {
        const double d = json_number_value(v);
        if (!json_is_number(v) || !isfinite(d) || d < f->lo || d > f->hi)
            return fail(doc, err, m->name, path, "must be a number in [%g, %g] (got %s)", f->lo, f->hi, got);
        *(double *)at = d;
        return 0;
    }
    case SOLVER_FIELD_BOOL:
        if (json_is_boolean(v))
            *(int *)at = json_is_true(v);
        else if (json_is_integer(v) && (json_integer_value(v) == 0 || json_integer_value(v) == 1))
            *(int *)at = (int)json_integer_value(v);
        else
            return fail(doc, err, m->name, path, "must be true or false (got %s)", got);
        return 0;
    case SOLVER_FIELD_ENUM:
    case SOLVER_FIELD_ACTION: {
        int i = name_index(f->names, v);
        if (i < 0) {
            char list[256];
            names_list(list, sizeof list, f->names);
            return fail(doc, err, m->name, path, "must be one of %s (got %s)", list, got);
        }
        if (f->type == SOLVER_FIELD_ENUM) {
            *(int *)at = i;
            return 0;
        }
        int rc = m->action ? m->action(settings, key, i, err) : -EINVAL;
        return rc < 0 ? fail(doc, err, m->name, path, "%s", err && err->msg[0] ? err->msg : "cannot be applied") : 0;
    }
    case SOLVER_FIELD_STRING:
        if (!json_is_string(v) || json_string_length(v) >= SOLVER_STRING_MAX)
            return fail(doc, err, m->name, path, "must be a string of fewer than %d bytes (got %s)",
                        SOLVER_STRING_MAX, got);
        snprintf(at, SOLVER_STRING_MAX, "%s", json_string_value(v));
        return 0;
    case SOLVER_FIELD_LIST:
        return list_set(m, f, (solver_values *)(void *)at, v, doc, path, got, err);
    }
    return -EINVAL;
}

static void keys_list(const solver_ops *m, char *buf, size_t n)
{
    size_t off = 0;
    buf[0] = 0;
    for (int g = 0; g < 2; g++)
        for (int i = 0; i < m->fields[g].n && off < n; i++)
            off += (size_t)snprintf(buf + off, n - off, "%s%s", off ? ", " : "", m->fields[g].f[i].key);
}

int solver_settings_from_json(const solver_ops *m, void *settings, const json_t *obj, const sci_json_doc *doc,
                              const char *path, sci_error *err)
{
    char kp[256];
    const char *p0 = path ? path : "settings";
    if (!json_is_object(obj))
        return fail(doc, err, m->name, p0, "must be a JSON object");
    const json_t *pv = json_object_get(obj, "preset");
    if (pv) {
        solver_preset pr;
        sci_error e2 = {0};
        if (!json_is_string(pv) || solver_preset_parse(json_string_value(pv), &pr, NULL, &e2) < 0)
            return fail(doc, err, m->name, sci_json_path_key(kp, sizeof kp, path ? path : "", "preset"),
                        "must be fast, balanced or best");
        m->preset(settings, pr);
    }
    void *before = malloc(m->settings_size);
    if (!before)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", m->name);
    memcpy(before, settings, m->settings_size);
    const char *key;
    json_t *v;
    int rc = 0;
    json_object_foreach((json_t *)obj, key, v) {
        if (strcmp(key, "preset") == 0)
            continue;
        sci_json_path_key(kp, sizeof kp, path ? path : "", key);
        if (strcmp(key, "method") == 0) {
            if (!json_is_string(v) || strcmp(json_string_value(v), m->name) != 0) {
                rc = fail(doc, err, m->name, kp, "names another method");
                break;
            }
            continue;
        }
        rc = solver_settings_set(m, settings, key, v, doc, kp, err);
        if (rc == 1) {
            char keys[1024];
            keys_list(m, keys, sizeof keys);
            rc = fail(doc, err, m->name, kp, "no such setting (the settings are: preset, %s)", keys);
        }
        if (rc < 0)
            break;
    }
    if (rc == 0 && m->from_json_rules)
        m->from_json_rules(settings, before, obj);
    free(before);
    if (rc < 0)
        return rc;
    if ((rc = solver_settings_check(m, settings, err)) < 0 && doc)
        return sci_json_fail(doc, err, p0, "%s", err->msg);
    return rc;
}

json_t *solver_settings_to_json(const solver_ops *m, const void *settings)
{
    json_t *j = json_pack("{s:s}", "method", m->name);
    for (int g = 0; j && g < 2; g++)
        for (int i = 0; i < m->fields[g].n; i++) {
            const solver_field *f = &m->fields[g].f[i];
            const char *at = (const char *)settings + m->fields[g].base + f->offset;
            json_t *v = NULL;
            if (f->flags & SOLVER_FIELD_ALIAS)
                continue;
            switch (f->type) {
            case SOLVER_FIELD_INT: v = json_integer(*(const int *)at); break;
            case SOLVER_FIELD_SEED: v = json_integer((json_int_t) * (const unsigned long long *)at); break;
            case SOLVER_FIELD_DOUBLE: v = json_real(*(const double *)at); break;
            case SOLVER_FIELD_BOOL: v = json_boolean(*(const int *)at); break;
            case SOLVER_FIELD_ENUM: {
                int k = *(const int *)at, n = 0;
                while (f->names[n])
                    n++;
                v = k >= 0 && k < n ? json_string(f->names[k]) : json_integer(k);
                break;
            }
            case SOLVER_FIELD_ACTION: continue;
            case SOLVER_FIELD_STRING: v = json_string(at); break;
            case SOLVER_FIELD_LIST: {
                const solver_values *l = (const void *)at;
                v = json_array();
                for (int k = 0; v && k < l->n && k < SOLVER_LIST_MAX; k++)
                    json_array_append_new(v, json_real(l->v[k]));
                break;
            }
            }
            if (!v || json_object_set_new(j, f->key, v) < 0) {
                json_decref(j);
                return NULL;
            }
        }
    return j;
}

int solver_settings_check(const solver_ops *m, const void *settings, sci_error *err)
{
    for (int g = 0; g < 2; g++)
        for (int i = 0; i < m->fields[g].n; i++) {
            const solver_field *f = &m->fields[g].f[i];
            const char *at = (const char *)settings + m->fields[g].base + f->offset;
            double v;
            if (f->type == SOLVER_FIELD_LIST) {
                const solver_values *l = (const void *)at;
                if (l->n < 1 || l->n > SOLVER_LIST_MAX)
                    return sci_error_set(err, -EINVAL, "%s: %s must hold 1 to %d values (has %d)", m->name, f->key,
                                         SOLVER_LIST_MAX, l->n);
                for (int k = 0; k < l->n; k++)
                    if (!(l->v[k] >= f->lo && l->v[k] <= f->hi))
                        return sci_error_set(err, -EINVAL, "%s: %s[%d] must be in [%.15g, %.15g] (got %.17g)",
                                             m->name, f->key, k, f->lo, f->hi, l->v[k]);
                continue;
            }
            if (f->type == SOLVER_FIELD_STRING) {
                if (!memchr(at, 0, SOLVER_STRING_MAX))
                    return sci_error_set(err, -EINVAL, "%s: %s is not terminated", m->name, f->key);
                continue;
            }
            if (f->type == SOLVER_FIELD_INT)
                v = *(const int *)at;
            else if (f->type == SOLVER_FIELD_DOUBLE)
                v = *(const double *)at;
            else if (f->type == SOLVER_FIELD_SEED)
                v = (double)*(const unsigned long long *)at;
            else
                continue;
            if (!(v >= f->lo && v <= f->hi))
                return sci_error_set(err, -EINVAL, "%s: %s must be in [%.15g, %.15g] (got %.17g)", m->name, f->key,
                                     f->lo, f->hi, v);
        }
    return m->check ? m->check(settings, err) : 0;
}

int solver_settings_iters(const solver_ops *m, const void *settings)
{
    size_t base = 0;
    const solver_field *f = solver_field_find(m, "iters", &base);
    return f && f->type == SOLVER_FIELD_INT ? *(const int *)((const char *)settings + base + f->offset) : 0;
}

/* The caller's progress callback, then the cancel flag. */
typedef struct cancel_ctx {
    const solver_io *io;
} cancel_ctx;

static int progress_with_cancel(const sci_trace_entry *e, void *user)
{
    const cancel_ctx *c = user;
    int stop = c->io->progress ? c->io->progress(e, c->io->user) : 0;
    return stop || (c->io->cancel && atomic_load(c->io->cancel));
}

int solver_run(const solver_ops *m, const sci_problem *p, const void *settings, const solver_io *io,
               sci_result *result)
{
    static const solver_io none;
    if (!io)
        io = &none;
    snprintf(result->method, sizeof result->method, "%s", m->name);
    int rc = solver_settings_check(m, settings, &result->error);
    if (rc < 0)
        return rc;
    if (!io->cancel)
        return m->run(p, settings, io, result);
    cancel_ctx c = {.io = io};
    solver_io wrapped = *io;
    wrapped.progress = progress_with_cancel;
    wrapped.user = &c;
    return m->run(p, settings, &wrapped, result);
}
