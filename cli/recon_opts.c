/* cli/recon_opts.c — `scicap recon`'s method settings as options, from the method table (see recon_opts.h). */
#include "cli/recon_opts.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/json.h"

/* Settings options spelled otherwise than their key since before the table: scripts and the man page use them.
 * "pose" was the usual abbreviation of --pose-mode before the NeRF methods' other pose_* keys became options. */
static const struct {
    const char *option, *key;
    const char *value; /* a flag's fixed value; NULL: the option takes one */
} aliases[] = {
    {"plain", "accelerate", "false"},
    {"distortion", "distortion_weight", NULL},
    {"pose", "pose_mode", NULL},
};
#define N_ALIASES (sizeof aliases / sizeof aliases[0])

/* m's field of that key, else (m NULL, or without it) the first method's in the table that has one. */
static const solver_field *field_of(const solver_ops *const *methods, const solver_ops *m, const char *key)
{
    const solver_field *f = m ? solver_field_find(m, key, NULL) : NULL;
    for (int i = 0; !f && methods[i]; i++)
        f = solver_field_find(methods[i], key, NULL);
    return f;
}

/* "patches_per_step" → "patches-per-step" (the option), into buf of n bytes. */
static void option_of_key(const char *key, char *buf, size_t n)
{
    snprintf(buf, n, "%s", key);
    for (char *p = buf; *p; p++)
        if (*p == '_')
            *p = '-';
}

static const struct option *option_find(const struct option *all, const char *name)
{
    for (int i = 0; all[i].name; i++)
        if (strcmp(all[i].name, name) == 0)
            return &all[i];
    return NULL;
}

/* The kept spellings (aliases[]) that `all` (n entries) lacks and some method of the table has the key of, appended;
 * returns the new count. all has room for N_ALIASES more. */
static size_t aliases_append(struct option *all, size_t n, const solver_ops *const *methods)
{
    for (size_t i = 0; i < N_ALIASES; i++)
        if (!option_find(all, aliases[i].option) && field_of(methods, NULL, aliases[i].key))
            all[n++] = (struct option){aliases[i].option, aliases[i].value ? no_argument : required_argument, NULL,
                                       CLI_RECON_OPT_SETTING};
    return n;
}

/* Every plain settings option a val of its own: getopt_long then refuses an abbreviation that fits several (it
 * takes the first of options that share has_arg, flag and val). The number sits above the low 16 bits. */
static void settings_vals_distinct(struct option *all)
{
    for (int i = 0; all[i].name; i++)
        if (all[i].val == CLI_RECON_OPT_SETTING)
            all[i].val = CLI_RECON_OPT_SETTING | ((i + 1) << 16);
}

struct option *cli_recon_opts_longopts(const solver_ops *const *methods, const struct option *own)
{
    enum { NAME_MAX_BYTES = 64 };
    size_t n_own = 0, n_keys = 0;
    while (own[n_own].name)
        n_own++;
    for (int i = 0; methods[i]; i++)
        n_keys += (size_t)methods[i]->fields[0].n + (size_t)methods[i]->fields[1].n;
    const size_t table_bytes = (n_own + n_keys + N_ALIASES + 1) * sizeof(struct option);
    struct option *all = calloc(1, table_bytes + n_keys * NAME_MAX_BYTES);
    if (!all)
        return NULL;
    char *names = (char *)all + table_bytes;
    memcpy(all, own, n_own * sizeof *own);
    size_t n = n_own;
    for (int i = 0; methods[i]; i++)
        for (int g = 0; g < 2; g++)
            for (int k = 0; k < methods[i]->fields[g].n; k++) {
                const solver_field *f = &methods[i]->fields[g].f[k];
                char *name = names + (n - n_own) * NAME_MAX_BYTES;
                option_of_key(f->key, name, NAME_MAX_BYTES);
                if ((f->flags & SOLVER_FIELD_ALIAS) || option_find(all, name))
                    continue; /* a JSON-only spelling, a key two methods share, or a name the command keeps */
                all[n++] = (struct option){name, required_argument, NULL, CLI_RECON_OPT_SETTING};
            }
    aliases_append(all, n, methods);
    settings_vals_distinct(all);
    return all;
}

/* A settings option's entry in the table, given what getopt_long returned; NULL when c is not one. */
static const struct option *setting_option(const struct option *all, int c, int idx)
{
    if (idx >= 0)
        return CLI_RECON_OPT_IS_SETTING(all[idx].val) ? &all[idx] : NULL;
    for (int i = 0; c > 0 && c < 256 && all[i].name; i++)
        if (all[i].val == CLI_RECON_OPT_SETTING_SHORT(c))
            return &all[i];
    return NULL;
}

static int take_set(cli_recon_given *g, const char *arg)
{
    if (!strchr(arg, '=') || arg[0] == '=') {
        fprintf(stderr, "scicap recon: --set wants KEY=VALUE, got '%s'\n", arg);
        return 2;
    }
    if (g->n_set == CLI_RECON_SETS_MAX) {
        fprintf(stderr, "scicap recon: at most %d --set options\n", g->n_set);
        return 2;
    }
    g->set[g->n_set++] = arg;
    return 0;
}

int cli_recon_opts_take(cli_recon_given *g, const struct option *all, int c, int idx, const char *arg)
{
    if (c == CLI_RECON_OPT_PRESET) {
        g->preset = arg;
        return 0;
    }
    if (c == CLI_RECON_OPT_SET)
        return take_set(g, arg);
    const struct option *o = setting_option(all, c, idx);
    if (!o)
        return 1;
    char key[64];
    const char *text = arg;
    snprintf(key, sizeof key, "%s", o->name);
    for (char *p = key; *p; p++)
        *p = *p == '-' ? '_' : *p;
    for (size_t i = 0; i < N_ALIASES; i++)
        if (strcmp(o->name, aliases[i].option) == 0) {
            snprintf(key, sizeof key, "%s", aliases[i].key);
            text = aliases[i].value ? aliases[i].value : arg;
        }
    const solver_field *f = field_of(g->methods, NULL, key);
    if (!f)
        return 1;
    if (g->n == CLI_RECON_GIVEN_MAX) {
        fprintf(stderr, "scicap recon: at most %d settings options\n", g->n);
        return 2;
    }
    cli_recon_arg *a = &g->arg[g->n++];
    a->key = f->key;
    snprintf(a->option, sizeof a->option, "--%s", o->name);
    a->text = text;
    return 0;
}

/* "a, b or c" of a NULL-terminated list: `sep` between names, `last` before the last. */
static void names_text(char *buf, size_t n, const char *const *names, const char *sep, const char *last)
{
    int count = 0;
    size_t off = 0;
    while (names[count])
        count++;
    buf[0] = 0;
    for (int i = 0; i < count && off < n; i++)
        off += (size_t)snprintf(buf + off, n - off, "%s%s", i == 0 ? "" : i == count - 1 ? last : sep, names[i]);
}

/* What a field's option wants, for messages ("an integer in [2, 16]"). */
static void field_want(const solver_field *f, char *buf, size_t n)
{
    char list[256];
    switch (f->type) {
    case SOLVER_FIELD_INT:
    case SOLVER_FIELD_SEED: snprintf(buf, n, "an integer in [%.16g, %.16g]", f->lo, f->hi); break;
    case SOLVER_FIELD_DOUBLE: snprintf(buf, n, "a number in [%.16g, %.16g]", f->lo, f->hi); break;
    case SOLVER_FIELD_BOOL: snprintf(buf, n, "0 or 1 (or false, true)"); break;
    case SOLVER_FIELD_ENUM:
    case SOLVER_FIELD_ACTION:
        names_text(list, sizeof list, f->names, ", ", " or ");
        snprintf(buf, n, "%s", list);
        break;
    case SOLVER_FIELD_STRING: snprintf(buf, n, "a string of fewer than %d bytes", SOLVER_STRING_MAX); break;
    case SOLVER_FIELD_LIST: snprintf(buf, n, "1 to %d numbers in [%g, %g]", SOLVER_LIST_MAX, f->lo, f->hi); break;
    }
}

/* The position of text in names[], or -1. An ACTION's later steps may be written +NAME, as a ladder labels them
 * (rayformer's ablation: baseline, +patch, ..., +tv). */
static int name_index(const solver_field *f, const char *text)
{
    const char *t = f->type == SOLVER_FIELD_ACTION && text[0] == '+' ? text + 1 : text;
    for (int k = 0; f->names[k]; k++)
        if (strcmp(t, f->names[k]) == 0 && (k > 0 || t == text))
            return k;
    return -1;
}

/* The option's text as the JSON value its field takes (a new reference), or NULL when the text is not one. The
 * range is checked here too, so the message names the option as given; LIST and STRING are left to the table. */
static json_t *field_value(const solver_field *f, const char *text)
{
    char *end;
    errno = 0;
    if (f->type == SOLVER_FIELD_INT || f->type == SOLVER_FIELD_SEED) {
        long long v = strtoll(text, &end, 10);
        return errno || *end || end == text || (double)v < f->lo || (double)v > f->hi ? NULL : json_integer(v);
    }
    if (f->type == SOLVER_FIELD_DOUBLE) {
        double v = strtod(text, &end);
        return errno || *end || end == text || !isfinite(v) || v < f->lo || v > f->hi ? NULL : json_real(v);
    }
    if (f->type == SOLVER_FIELD_BOOL) {
        int t = strcmp(text, "1") == 0 || strcmp(text, "true") == 0;
        return t || strcmp(text, "0") == 0 || strcmp(text, "false") == 0 ? json_boolean(t) : NULL;
    }
    if (f->type == SOLVER_FIELD_ENUM || f->type == SOLVER_FIELD_ACTION) {
        int k = name_index(f, text);
        return k < 0 ? NULL : json_string(f->names[k]);
    }
    return json_string(text);
}

/* The methods of the table that have key, "a, b" into buf. */
static void methods_with_key(const solver_ops *const *methods, const char *key, char *buf, size_t n)
{
    size_t off = 0;
    buf[0] = 0;
    for (int i = 0; methods[i] && off < n; i++)
        if (solver_field_find(methods[i], key, NULL))
            off += (size_t)snprintf(buf + off, n - off, "%s%s", off ? ", " : "", methods[i]->name);
}

static int apply_arg(const solver_ops *const *methods, const solver_ops *m, void *settings, const cli_recon_arg *a)
{
    const solver_field *f = field_of(methods, m, a->key);
    json_t *v = field_value(f, a->text);
    char buf[256];
    if (!v) {
        field_want(f, buf, sizeof buf);
        fprintf(stderr, "scicap recon: %s wants %s, got '%s'\n", a->option, buf, a->text);
        return 2;
    }
    int rc = 0;
    sci_error err = {0};
    if (!solver_field_find(m, a->key, NULL)) {
        if (f->type == SOLVER_FIELD_ACTION) {
            methods_with_key(methods, a->key, buf, sizeof buf);
            fprintf(stderr, "scicap recon: %s is for %s\n", a->option, buf);
            rc = 2;
        }
    } else if (solver_settings_set(m, settings, a->key, v, NULL, a->option, &err) < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        rc = 2;
    }
    json_decref(v);
    return rc;
}

static int apply_preset(const char *preset, const solver_ops *m, void *settings)
{
    solver_preset pr;
    int deprecated;
    sci_error err = {0};
    if (!preset)
        return 0;
    if (solver_preset_parse(preset, &pr, &deprecated, &err) < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        return 2;
    }
    if (deprecated)
        fprintf(stderr, "scicap recon: preset '%s' is deprecated: it is %s\n", preset, solver_preset_name(pr));
    solver_settings_preset(m, settings, pr);
    return 0;
}

/* --set KEY=VALUE: any setting of the method by its key (result.json's "params" names them all). VALUE is read as
 * JSON (numbers, true/false) and otherwise as a string, so "--set spacing=log" needs no quotes. Through the
 * method's table, as a params file would be (its rules between keys included): range-checked; an unknown key is
 * refused with the method's keys and what each does. */
static int apply_sets(const solver_ops *m, void *settings, const char *const *kv, int n)
{
    json_t *obj = json_object();
    int rc = obj ? 0 : -ENOMEM;
    for (int i = 0; i < n && rc == 0; i++)
        if ((rc = sci_json_set_kv(obj, kv[i])) == -EINVAL) {
            fprintf(stderr, "scicap recon: --set %s: the key must be under 128 bytes, the value UTF-8\n", kv[i]);
            rc = 2;
        }
    const char *key;
    json_t *v;
    json_object_foreach(obj, key, v) /* in the order given (jansson keeps insertion order) */
        if (rc == 0 && !solver_field_find(m, key, NULL)) {
            fprintf(stderr, "scicap recon: --set %s: %s has no such setting; its settings are:\n", key, m->name);
            for (int g = 0; g < 2; g++)
                for (int k = 0; k < m->fields[g].n; k++)
                    fprintf(stderr, "  %-20s %s\n", m->fields[g].f[k].key, m->fields[g].f[k].help);
            rc = 2;
        }
    sci_error err = {0};
    if (rc == 0 && solver_settings_from_json(m, settings, obj, NULL, NULL, &err) < 0) {
        fprintf(stderr, "scicap recon: --set: %s\n", err.msg);
        rc = 2;
    } else if (rc < 0) {
        fprintf(stderr, "scicap recon: out of memory\n");
        rc = 2;
    }
    json_decref(obj);
    return rc;
}

int cli_recon_opts_apply(const cli_recon_given *g, const solver_ops *m, void *settings)
{
    int rc = apply_preset(g->preset, m, settings);
    for (int actions = 1; actions >= 0; actions--)
        for (int i = 0; i < g->n && rc == 0; i++) {
            const solver_field *f = field_of(g->methods, m, g->arg[i].key);
            if ((f->type == SOLVER_FIELD_ACTION) == actions)
                rc = apply_arg(g->methods, m, settings, &g->arg[i]);
        }
    if (rc == 0 && g->n_set)
        rc = apply_sets(m, settings, g->set, g->n_set);
    sci_error err = {0};
    if (rc == 0 && solver_settings_check(m, settings, &err) < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        rc = 2;
    }
    return rc;
}

void cli_recon_methods_usage(FILE *f, const solver_ops *const *methods, int width)
{
    for (int i = 0; methods[i]; i++)
        fprintf(f, "  %-*s %s\n", width, methods[i]->name, methods[i]->summary);
}

/* One setting's line: its option as the table `all` spells it (short letter, aliases), value, help, range. */
static void usage_field(FILE *out, const solver_field *f, const struct option *all)
{
    char opt[64], spelled[160], value[128], range[96] = "", extra[96] = "";
    option_of_key(f->key, opt, sizeof opt);
    const struct option *o = option_find(all, opt);
    if (f->type == SOLVER_FIELD_ENUM || f->type == SOLVER_FIELD_ACTION)
        names_text(value, sizeof value, f->names, "|", "|");
    else
        snprintf(value, sizeof value, "%s", f->type == SOLVER_FIELD_DOUBLE ? "X" : f->type == SOLVER_FIELD_BOOL ? "0|1"
                                             : f->type == SOLVER_FIELD_STRING ? "TEXT"
                                             : f->type == SOLVER_FIELD_LIST   ? "X,Y,..." : "N");
    if (o && CLI_RECON_OPT_IS_SETTING(o->val) && (o->val & 0xff))
        snprintf(spelled, sizeof spelled, "-%c, --%s %s", o->val & 0xff, opt, value);
    else if (o && CLI_RECON_OPT_IS_SETTING(o->val))
        snprintf(spelled, sizeof spelled, "    --%s %s", opt, value);
    else /* the command's own option of that name wins (e.g. --threads): the setting is reached by --set */
        snprintf(spelled, sizeof spelled, "    --set %s=%s", f->key, value);
    if (f->type == SOLVER_FIELD_INT || f->type == SOLVER_FIELD_DOUBLE || f->type == SOLVER_FIELD_SEED)
        snprintf(range, sizeof range, " [%.16g, %.16g]", f->lo, f->hi);
    for (size_t i = 0; i < N_ALIASES; i++)
        if (strcmp(aliases[i].key, f->key) == 0)
            snprintf(extra, sizeof extra, "; also --%s%s%s", aliases[i].option, aliases[i].value ? ": " : "",
                     aliases[i].value ? aliases[i].value : "");
    fprintf(out, "    %-30s %s%s%s\n", spelled, f->help, range, extra);
}

void cli_recon_opts_usage(FILE *f, const solver_ops *const *methods, const struct option *all)
{
    char presets[128];
    names_text(presets, sizeof presets, solver_preset_names, ", ", " or ");
    fprintf(f, "      --preset P         %s for every method (the settings below override it); none: the\n"
               "                         method's defaults\n"
               "      --set KEY=VALUE    any setting by its key, e.g. --set KEY=false (repeatable; after the options\n"
               "                         below; VALUE read as JSON, else as a string; result.json's params list every\n"
               "                         key)\n"
               "\nSettings of each method, as --KEY VALUE (the keys of result.json's params, '_' written '-'); one a\n"
               "method does not have is ignored, except a step that sets several keys at once, which is refused:\n",
            presets);
    for (int i = 0; methods[i]; i++)
        for (int g = 0; g < 2; g++) {
            const solver_field *group = methods[i]->fields[g].f;
            int seen = 0;
            for (int j = 0; j < i; j++)
                seen |= methods[j]->fields[0].f == group || methods[j]->fields[1].f == group;
            if (!methods[i]->fields[g].n || seen)
                continue; /* a group shared with a method above: listed there */
            fprintf(f, "  %s", methods[i]->name);
            for (int j = i + 1; methods[j]; j++)
                if (methods[j]->fields[0].f == group || methods[j]->fields[1].f == group)
                    fprintf(f, ", %s", methods[j]->name);
            fprintf(f, ":\n");
            for (int k = 0; k < methods[i]->fields[g].n; k++)
                if (!(group[k].flags & SOLVER_FIELD_ALIAS))
                    usage_field(f, &group[k], all);
        }
}
