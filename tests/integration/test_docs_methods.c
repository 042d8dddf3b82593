/* The method and preset tables of the documentation against the solver table (recon/solver.c), read live.
 *
 * docs/man/scicap.1, docs/man/scicapd.8 and README.md hold blocks between markers
 *     .\" methods:NAME ... .\" /methods:NAME         (man pages)
 *     <!-- methods:NAME --> ... <!-- /methods:NAME -->  (Markdown)
 * whose text this program writes from the table: every method's name and summary, and for each preset (fast,
 * balanced, best) and for the defaults the values of "iters" and of every setting that differs between them; the
 * man page also lists the settings every preset sets to one value. `docs/update-methods` rewrites the blocks with
 * `test_docs_methods --print NAME`; the tests fail when a block is not what the table gives now (a method added,
 * renamed or dropped, a preset re-chosen), with a diff and the command that brings it up to date.
 *
 * What a preset sets is found by trying: each setting is given two values (its range's ends, or false and true,
 * or two names), the preset applied, and the setting counts as the preset's when the value changed. */
#include <errno.h>
#include <glob.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include <jansson.h>

#include "recon/solver.h"

#define MAX_KEYS 64

/* The stored settings of a method (aliases and actions have no value of their own). */
typedef struct key_list {
    const solver_field *f[MAX_KEYS];
    int n;
} key_list;

static void stored_fields(const solver_ops *m, key_list *k)
{
    k->n = 0;
    for (int g = 0; g < 2; g++)
        for (int i = 0; i < m->fields[g].n && k->n < MAX_KEYS; i++) {
            const solver_field *f = &m->fields[g].f[i];
            if (!(f->flags & SOLVER_FIELD_ALIAS) && f->type != SOLVER_FIELD_ACTION)
                k->f[k->n++] = f;
        }
}

/* The settings as JSON: the defaults (p < 0) or a preset applied to them. */
static json_t *settings_json(const solver_ops *m, int p)
{
    void *s = solver_settings_new(m);
    assert_non_null(s);
    if (p >= 0)
        solver_settings_preset(m, s, (solver_preset)p);
    json_t *j = solver_settings_to_json(m, s);
    assert_non_null(j);
    solver_settings_free(s);
    return j;
}

/* Two values of field f that differ from each other (so a preset's value differs from at least one). */
static void probe_values(const solver_field *f, json_t *v[2])
{
    double lo = f->lo, hi = f->hi;
    switch (f->type) {
    case SOLVER_FIELD_INT:
        v[0] = json_integer((json_int_t)lo), v[1] = json_integer((json_int_t)(hi > 2e9 ? 2e9 : hi));
        return;
    case SOLVER_FIELD_SEED:
        v[0] = json_integer((json_int_t)lo), v[1] = json_integer((json_int_t)(hi > 4e18 ? 4e18 : hi));
        return;
    case SOLVER_FIELD_DOUBLE: v[0] = json_real(lo), v[1] = json_real(hi); return;
    case SOLVER_FIELD_BOOL: v[0] = json_false(), v[1] = json_true(); return;
    case SOLVER_FIELD_ENUM: v[0] = json_string(f->names[0]), v[1] = json_string(f->names[1] ? f->names[1] : ""); return;
    case SOLVER_FIELD_STRING: v[0] = json_string(""), v[1] = json_string("x"); return;
    case SOLVER_FIELD_LIST: v[0] = json_pack("[f]", lo), v[1] = json_pack("[f]", hi); return;
    case SOLVER_FIELD_ACTION: break;
    }
    v[0] = v[1] = NULL;
}

/* Does preset p set field f? */
static int preset_sets(const solver_ops *m, const solver_field *f, solver_preset p)
{
    json_t *v[2];
    int sets = 0;
    probe_values(f, v);
    for (int k = 0; k < 2; k++) {
        void *s = solver_settings_new(m);
        assert_non_null(s);
        assert_non_null(v[k]);
        sci_error err = {0};
        if (solver_settings_set(m, s, f->key, v[k], NULL, f->key, &err) == 0) {
            json_t *before = solver_settings_to_json(m, s);
            solver_settings_preset(m, s, p);
            json_t *after = solver_settings_to_json(m, s);
            assert_true(before && after);
            sets |= !json_equal(json_object_get(before, f->key), json_object_get(after, f->key));
            json_decref(before);
            json_decref(after);
        }
        solver_settings_free(s);
        json_decref(v[k]);
    }
    return sets;
}

/* What the documents show of method m: cols[0..2] the presets, cols[3] the defaults; `shown` the keys whose
 * values differ among those four ("iters" always, first), `constant` the other keys every preset sets. */
typedef struct method_doc {
    json_t *cols[SOLVER_PRESET_COUNT + 1];
    key_list shown, constant;
} method_doc;

static void method_doc_make(const solver_ops *m, method_doc *d)
{
    key_list all;
    stored_fields(m, &all);
    for (int p = 0; p <= SOLVER_PRESET_COUNT; p++)
        d->cols[p] = settings_json(m, p < SOLVER_PRESET_COUNT ? p : -1);
    d->shown.n = d->constant.n = 0;
    for (int i = 0; i < all.n; i++)
        if (strcmp(all.f[i]->key, "iters") == 0)
            d->shown.f[d->shown.n++] = all.f[i];
    assert_int_equal(d->shown.n, 1); /* every method has "iters" (solver_list_check) */
    for (int i = 0; i < all.n; i++) {
        const char *key = all.f[i]->key;
        if (strcmp(key, "iters") == 0)
            continue;
        int differs = 0, every = 1;
        for (int p = 1; p <= SOLVER_PRESET_COUNT; p++)
            differs |= !json_equal(json_object_get(d->cols[0], key), json_object_get(d->cols[p], key));
        for (int p = 0; p < SOLVER_PRESET_COUNT && !differs; p++)
            every &= preset_sets(m, all.f[i], (solver_preset)p);
        if (differs)
            d->shown.f[d->shown.n++] = all.f[i];
        else if (every)
            d->constant.f[d->constant.n++] = all.f[i];
    }
}

static void method_doc_free(method_doc *d)
{
    for (int p = 0; p <= SOLVER_PRESET_COUNT; p++)
        json_decref(d->cols[p]);
}

/* A JSON value as the documents write it: 80, 0.003, true, hash, 50,25,12. roff: minus signs as \-. */
static void put_value(FILE *o, const json_t *v, int roff)
{
    char b[512] = "";
    if (json_is_integer(v))
        snprintf(b, sizeof b, "%lld", (long long)json_integer_value(v));
    else if (json_is_real(v))
        snprintf(b, sizeof b, "%g", json_real_value(v));
    else if (json_is_boolean(v))
        snprintf(b, sizeof b, "%s", json_is_true(v) ? "true" : "false");
    else if (json_is_string(v))
        snprintf(b, sizeof b, "%s", json_string_length(v) ? json_string_value(v) : "\"\"");
    else if (json_is_array(v)) {
        size_t i, off = 0;
        const json_t *e;
        json_array_foreach(v, i, e) off += (size_t)snprintf(b + off, sizeof b - off, "%s%g", i ? "," : "",
                                                             json_number_value(e));
    }
    for (const char *c = b; *c; c++)
        if (roff && *c == '-')
            fputs("\\-", o);
        else if (roff && *c == '\\')
            fputs("\\e", o);
        else
            fputc(*c, o);
}

/* "iters 80, sigma 50,25,12" for column col of keys k. */
static void put_settings(FILE *o, const method_doc *d, const key_list *k, int col, int roff)
{
    for (int i = 0; i < k->n; i++) {
        fprintf(o, "%s%s ", i ? ", " : "", k->f[i]->key);
        put_value(o, json_object_get(d->cols[col], k->f[i]->key), roff);
    }
}

/* Text for roff: a backslash escaped; the summaries hold nothing else roff reads. */
static void put_roff(FILE *o, const char *s)
{
    for (; *s; s++)
        if (*s == '\\')
            fputs("\\e", o);
        else
            fputc(*s, o);
}

static const char generated_roff[] =
    ".\\\" Written from the solver table (recon/solver.c) by docs/update-methods; tests/integration/"
    "test_docs_methods.c\n.\\\" checks it. Do not edit by hand.\n";

/* scicap(1), RECONSTRUCTION METHODS: each method, its summary, its presets and defaults. */
static void block_presets(FILE *o)
{
    size_t n = 0;
    const solver_ops *const *ms = solver_list(&n);
    fputs(generated_roff, o);
    for (size_t i = 0; i < n; i++) {
        const solver_ops *m = ms[i];
        method_doc d;
        method_doc_make(m, &d);
        fprintf(o, ".TP\n.B %s\n", m->name);
        put_roff(o, m->summary);
        fputc('\n', o);
        fputs(".RS\n.PD 0\n", o);
        for (int p = 0; p <= SOLVER_PRESET_COUNT; p++) {
            if (p < SOLVER_PRESET_COUNT)
                fprintf(o, ".TP 10\n.B %s\n", solver_preset_names[p]);
            else
                fputs(".TP 10\n.I defaults\n", o);
            put_settings(o, &d, &d.shown, p, 1);
            fputc('\n', o);
        }
        fputs(".PD\n", o);
        if (d.constant.n) {
            fputs(".PP\nEvery preset also sets ", o);
            put_settings(o, &d, &d.constant, 0, 1);
            fputs(".\n", o);
        }
        fputs(".RE\n", o);
        method_doc_free(&d);
    }
}

/* scicapd(8): the methods it reconstructs with. */
static void block_list(FILE *o)
{
    size_t n = 0;
    const solver_ops *const *ms = solver_list(&n);
    fputs(generated_roff, o);
    for (size_t i = 0; i < n; i++) {
        fprintf(o, ".TP\n.B %s\n", ms[i]->name);
        put_roff(o, ms[i]->summary);
        fputc('\n', o);
    }
}

/* README.md: one row per method, the presets' and the defaults' values of the settings that differ. */
static void block_table(FILE *o)
{
    size_t n = 0;
    const solver_ops *const *ms = solver_list(&n);
    fputs("<!-- Written from the solver table (recon/solver.c) by docs/update-methods; "
          "tests/integration/test_docs_methods.c checks it. -->\n",
          o);
    fputs("| method | what it is | `--preset fast` | `balanced` | `best` | no `--preset` |\n"
          "|---|---|---|---|---|---|\n",
          o);
    for (size_t i = 0; i < n; i++) {
        method_doc d;
        method_doc_make(ms[i], &d);
        fprintf(o, "| `%s` | %s |", ms[i]->name, ms[i]->summary);
        for (int p = 0; p <= SOLVER_PRESET_COUNT; p++) {
            fputc(' ', o);
            put_settings(o, &d, &d.shown, p, 0);
            fputs(" |", o);
        }
        fputc('\n', o);
        method_doc_free(&d);
    }
}

/* The blocks: name, the file it lives in, the marker style, the writer. */
static const struct block {
    const char *name, *file;
    int roff;
    void (*write)(FILE *o);
} blocks[] = {
    {"presets", "docs/man/scicap.1", 1, block_presets},
    {"list", "docs/man/scicapd.8", 1, block_list},
    {"table", "README.md", 0, block_table},
};
#define NBLOCKS (sizeof blocks / sizeof blocks[0])

static char *block_text(const struct block *b)
{
    char *text = NULL;
    size_t len = 0;
    FILE *o = open_memstream(&text, &len);
    assert_non_null(o);
    b->write(o);
    assert_int_equal(fclose(o), 0);
    return text;
}

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        fail_msg("%s: %s (run from the source tree)", path, strerror(errno));
    char *buf = NULL;
    size_t len = 0;
    FILE *o = open_memstream(&buf, &len);
    assert_non_null(o);
    char chunk[65536];
    size_t got;
    while ((got = fread(chunk, 1, sizeof chunk, f)) > 0)
        fwrite(chunk, 1, got, o);
    fclose(f);
    assert_int_equal(fclose(o), 0);
    return buf;
}

/* The text between the block's markers in its file (malloc'd); fails when the markers are missing or repeated. */
static char *block_in_file(const struct block *b)
{
    char begin[128], end[128];
    if (b->roff) {
        snprintf(begin, sizeof begin, "\n.\\\" methods:%s\n", b->name);
        snprintf(end, sizeof end, "\n.\\\" /methods:%s\n", b->name);
    } else {
        snprintf(begin, sizeof begin, "\n<!-- methods:%s -->\n", b->name);
        snprintf(end, sizeof end, "\n<!-- /methods:%s -->\n", b->name);
    }
    char *doc = slurp(b->file);
    const char *s = strstr(doc, begin), *e = s ? strstr(s, end) : NULL;
    if (!s || !e)
        fail_msg("%s: no block between '%.*s' and '%.*s' (docs/update-methods fills it)", b->file,
                 (int)strlen(begin) - 2, begin + 1, (int)strlen(end) - 2, end + 1);
    if (strstr(s + 1, begin))
        fail_msg("%s: the block methods:%s appears twice", b->file, b->name);
    s += strlen(begin);
    char *text = strndup(s, (size_t)(e + 1 - s));
    free(doc);
    return text;
}

/* The block in its file is the one the table gives now; else a diff and the fix. */
static void check_block(const struct block *b)
{
    char *want = block_text(b), *have = block_in_file(b);
    if (strcmp(want, have) != 0) {
        char a[] = "/tmp/scicap-doc-have-XXXXXX", w[] = "/tmp/scicap-doc-want-XXXXXX";
        int fa = mkstemp(a), fw = mkstemp(w);
        assert_true(fa >= 0 && fw >= 0);
        assert_int_equal(write(fa, have, strlen(have)), (ssize_t)strlen(have));
        assert_int_equal(write(fw, want, strlen(want)), (ssize_t)strlen(want));
        close(fa);
        close(fw);
        char cmd[256];
        snprintf(cmd, sizeof cmd, "diff -u %s %s >&2", a, w);
        fprintf(stderr, "%s, block methods:%s (-: the file, +: the solver table now):\n", b->file, b->name);
        if (system(cmd) == -1)
            fprintf(stderr, "(diff did not run)\n");
        unlink(a);
        unlink(w);
        fail_msg("%s: the block methods:%s is not the solver table's; run docs/update-methods", b->file, b->name);
    }
    printf("%s: methods:%s is current (%zu bytes)\n", b->file, b->name, strlen(have));
    free(want);
    free(have);
}

static void test_man_scicap_presets(void **state) { check_block(&blocks[0]); }
static void test_man_scicapd_methods(void **state) { check_block(&blocks[1]); }
static void test_readme_methods(void **state) { check_block(&blocks[2]); }

/* Apart from its layout: the scicap(1) block names every method of the table, and under it each preset and the
 * defaults with their iterations as the table has them, computed here without the writer's code. */
static void test_presets_block_has_every_iters(void **state)
{
    char *have = block_in_file(&blocks[0]);
    size_t n = 0;
    const solver_ops *const *ms = solver_list(&n);
    assert_true(n >= 1);
    for (size_t i = 0; i < n; i++) {
        char head[96];
        snprintf(head, sizeof head, "\n.B %s\n", ms[i]->name);
        const char *at = strstr(have, head);
        if (!at)
            fail_msg("docs/man/scicap.1: the method %s is not in RECONSTRUCTION METHODS", ms[i]->name);
        const char *next = strstr(at + 1, "\n.RE\n");
        assert_non_null(next);
        for (int p = 0; p <= SOLVER_PRESET_COUNT; p++) {
            void *s = solver_settings_new(ms[i]);
            assert_non_null(s);
            if (p < SOLVER_PRESET_COUNT)
                solver_settings_preset(ms[i], s, (solver_preset)p);
            char want[128];
            snprintf(want, sizeof want, "\n.B %s\niters %d", p < SOLVER_PRESET_COUNT ? solver_preset_names[p] : "?",
                     solver_settings_iters(ms[i], s));
            if (p == SOLVER_PRESET_COUNT)
                snprintf(want, sizeof want, "\n.I defaults\niters %d", solver_settings_iters(ms[i], s));
            solver_settings_free(s);
            const char *w = strstr(at, want);
            if (!w || w > next)
                fail_msg("docs/man/scicap.1: %s: no '%s' (the table's value)", ms[i]->name, want + 1);
        }
    }
    printf("docs/man/scicap.1: %zu methods, each with %d presets and its defaults\n", n, SOLVER_PRESET_COUNT);
    free(have);
}

/* The writer on a method of known presets (not in the table): "iters" differs between the presets, "sigma" only
 * from the defaults, "passes" is set by every preset to its default, "weight" by none. Guards the probing, not
 * the numbers of the live table. */
typedef struct fake_params {
    int iters, passes;
    double weight;
    solver_values sigma;
} fake_params;

static const solver_field fake_fields[] = {
    {"iters", SOLVER_FIELD_INT, offsetof(fake_params, iters), 1, 1e6, NULL, 0, "iterations"},
    {"passes", SOLVER_FIELD_INT, offsetof(fake_params, passes), 1, 100, NULL, 0, "passes"},
    {"weight", SOLVER_FIELD_DOUBLE, offsetof(fake_params, weight), 0, 10, NULL, 0, "weight"},
    {"sigma", SOLVER_FIELD_LIST, offsetof(fake_params, sigma), 1, 255, NULL, 0, "sigmas"},
};

static void fake_defaults(void *s)
{
    *(fake_params *)s = (fake_params){.iters = 100, .passes = 5, .weight = 0.07, .sigma = {1, {50}}};
}

static void fake_preset(void *s, solver_preset p)
{
    fake_params *q = s;
    q->iters = 10 * (1 + (int)p), q->passes = 5, q->sigma = (solver_values){2, {50, 25}};
}

static void test_writer_on_known_presets(void **state)
{
    const solver_ops fake = {.name = "fake",
                             .summary = "a method for this test",
                             .settings_size = sizeof(fake_params),
                             .fields = {{fake_fields, sizeof fake_fields / sizeof fake_fields[0], 0}},
                             .defaults = fake_defaults,
                             .preset = fake_preset};
    method_doc d;
    method_doc_make(&fake, &d);
    assert_int_equal(d.shown.n, 2);
    assert_string_equal(d.shown.f[0]->key, "iters");
    assert_string_equal(d.shown.f[1]->key, "sigma");
    assert_int_equal(d.constant.n, 1);
    assert_string_equal(d.constant.f[0]->key, "passes");
    char *text = NULL;
    size_t len = 0;
    FILE *o = open_memstream(&text, &len);
    assert_non_null(o);
    for (int p = 0; p <= SOLVER_PRESET_COUNT; p++) {
        put_settings(o, &d, &d.shown, p, 0);
        fputc('|', o);
    }
    put_settings(o, &d, &d.constant, 0, 1);
    assert_int_equal(fclose(o), 0);
    assert_string_equal(text, "iters 10, sigma 50,25|iters 20, sigma 50,25|iters 30, sigma 50,25|"
                              "iters 100, sigma 50|passes 5");
    free(text);
    method_doc_free(&d);
}

/* The measurements live in docs/, not in README.md: bench/update-docs copies each bench/results/NAME.md between
 * <!-- bench:NAME --> markers of the Markdown files in docs/, so the README holds none, and every result that has markers has them
 * once, in docs/ (the accuracy-against-time report in docs/benchmarks.md). */
static void test_bench_markers_in_docs(void **state)
{
    char *readme = slurp("README.md");
    if (strstr(readme, "<!-- bench:"))
        fail_msg("README.md: holds a <!-- bench:... --> block; the measured tables belong in docs/benchmarks.md");
    free(readme);
    char *bm = slurp("docs/benchmarks.md");
    if (!strstr(bm, "\n<!-- bench:report -->\n") || !strstr(bm, "\n<!-- /bench:report -->\n"))
        fail_msg("docs/benchmarks.md: no bench:report block for make bench-report to fill");
    if (strstr(bm, "](bench/results/"))
        fail_msg("docs/benchmarks.md: an image link relative to the top folder; from docs/ it is ../bench/results/");
    free(bm);
    glob_t g;
    assert_int_equal(glob("bench/results/*.md", 0, NULL, &g), 0);
    int found = 0;
    for (size_t i = 0; i < g.gl_pathc; i++) {
        char name[256], marker[300];
        const char *base = strrchr(g.gl_pathv[i], '/') + 1;
        snprintf(name, sizeof name, "%.*s", (int)(strlen(base) - 3), base);
        snprintf(marker, sizeof marker, "\n<!-- bench:%s -->\n", name);
        glob_t d;
        int copies = 0;
        assert_int_equal(glob("docs/*.md", 0, NULL, &d), 0);
        for (size_t j = 0; j < d.gl_pathc; j++) {
            char *doc = slurp(d.gl_pathv[j]);
            for (const char *at = strstr(doc, marker); at; at = strstr(at + 1, marker))
                copies++;
            free(doc);
        }
        globfree(&d);
        if (copies > 1)
            fail_msg("docs/: the block bench:%s appears %d times", name, copies);
        found += copies;
    }
    globfree(&g);
    printf("docs/: %d bench blocks, none in README.md\n", found);
    assert_true(found >= 1);
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--print") == 0) {
        for (size_t i = 0; i < NBLOCKS; i++)
            if (strcmp(argv[2], blocks[i].name) == 0) {
                blocks[i].write(stdout);
                return fflush(stdout) == 0 ? 0 : 1;
            }
        fprintf(stderr, "test_docs_methods: no block '%s' (presets, list, table)\n", argv[2]);
        return 2;
    }
    if (argc > 1) {
        fprintf(stderr, "usage: test_docs_methods [--print presets|list|table]\n");
        return 2;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_man_scicap_presets),
        cmocka_unit_test(test_man_scicapd_methods),
        cmocka_unit_test(test_readme_methods),
        cmocka_unit_test(test_presets_block_has_every_iters),
        cmocka_unit_test(test_writer_on_known_presets),
        cmocka_unit_test(test_bench_markers_in_docs),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
