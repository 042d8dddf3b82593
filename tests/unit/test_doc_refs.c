/* tests/unit/test_doc_refs.c — every document the tree cites is in the tree.
 *
 * Comments and docs point readers at Markdown files ("docs/conventions.md §10", "see docs/protocol.md"). Each such
 * name must resolve to a file of the repository: in docs/, at the root, beside the citing file, or in
 * bench/results/ (the generated tables). Material outside the repository (the paper's LaTeX source, a reference
 * folder beside the checkout) must not be cited: a reader of the repository cannot open it.
 *
 * A name counts when it starts a word (after a blank, '(', '`', '"' or '\'' or at the start of a line) and reads
 * [a-zA-Z0-9_/.-]+.md; names with a placeholder in capitals (NAME.md, nerf_compare_P.md), stems of one or two
 * letters (C's t.md is a member) and paths into the data folder (shared/data/...) are not documents. `test_doc_refs FILE...` scans the given files and prints the hits.
 */
#include <ctype.h>
#include <ftw.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#define MAX_REPORT 8192

typedef struct scan {
    char report[MAX_REPORT];
    size_t used;
    int files, refs, bad;
} scan;

static scan g_scan; /* nftw has no user pointer: the one scan of the walk in progress */

static void scan_add(scan *s, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(s->report + s->used, sizeof s->report - s->used, fmt, ap);
    va_end(ap);
    if (n > 0 && s->used + (size_t)n < sizeof s->report)
        s->used += (size_t)n;
    s->bad++;
}

static int exists(const char *path) { return access(path, F_OK) == 0; }

/* Whether the cited name `ref` (a path ending .md) resolves from the file at `from`. */
static int ref_resolves(const char *from, const char *ref)
{
    char path[4096];
    const char *base = strrchr(ref, '/') ? strrchr(ref, '/') + 1 : ref;
    if (strncmp(ref, "../", 3) == 0)
        return 0; /* outside the repository */
    if (exists(ref))
        return 1;
    snprintf(path, sizeof path, "docs/%s", base);
    if (exists(path))
        return 1;
    snprintf(path, sizeof path, "bench/results/%s", base);
    if (exists(path))
        return 1;
    const char *slash = strrchr(from, '/');
    snprintf(path, sizeof path, "%.*s/%s", slash ? (int)(slash - from) : 1, slash ? from : ".", ref);
    return exists(path);
}

/* A capital letter anywhere in the stem except a whole capitals stem that names a root file (README.md). */
static int is_placeholder(const char *ref, size_t len)
{
    const char *base = ref;
    for (size_t i = 0; i < len; i++)
        if (ref[i] == '/')
            base = ref + i + 1;
    size_t stem = (size_t)(ref + len - base) - 3;
    int upper = 0, lower = 0;
    for (size_t i = 0; i < stem; i++)
        upper += isupper((unsigned char)base[i]) != 0, lower += islower((unsigned char)base[i]) != 0;
    return upper && (lower || (stem == 4 && strncmp(base, "NAME", 4) == 0));
}

static int starts_word(const char *text, const char *p)
{
    if (p == text)
        return 1;
    char c = p[-1];
    return c == ' ' || c == '\t' || c == '\n' || c == '(' || c == '`' || c == '"' || c == '\'' || c == '*';
}

static int ref_char(char c) { return isalnum((unsigned char)c) || c == '_' || c == '/' || c == '.' || c == '-'; }

/* Scans one file's text token by token: each cited .md name must resolve; a .tex source or the reference folder
 * beside the checkout may not be cited at all. */
static void scan_text(scan *s, const char *file, const char *text)
{
    int line = 1;
    for (const char *p = text; *p; p++) {
        if (*p == '\n')
            line++;
        if (!starts_word(text, p) || !ref_char(*p))
            continue;
        const char *e = p;
        while (ref_char(*e))
            e++;
        const char *next = e;
        while (e > p && (e[-1] == '.' || e[-1] == '/'))
            e--; /* a sentence's full stop */
        size_t len = (size_t)(e - p);
        const char *base = memrchr(p, '/', len) ? (const char *)memrchr(p, '/', len) + 1 : p;
        if (memmem(p, len, "shared/reference", 16) || (len > 4 && strncmp(e - 4, ".tex", 4) == 0))
            scan_add(s, "%s:%d: cites %.*s, outside the repository\n", file, line, (int)len, p);
        else if (len > 3 && strncmp(e - 3, ".md", 3) == 0 && e - 3 - base >= 3 && !is_placeholder(p, len) &&
                 !memmem(p, len, "shared/data/", 12)) {
            char ref[512];
            snprintf(ref, sizeof ref, "%.*s", (int)len, p);
            s->refs++;
            if (!ref_resolves(file, ref))
                scan_add(s, "%s:%d: cites %s, which is not in the repository\n", file, line, ref);
        }
        p = next - 1;
    }
}

static int wanted(const char *path)
{
    static const char *const ext[] = {".c", ".h", ".cpp", ".md", ".py", ".sh", ".1", ".8", NULL};
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
    if (strcmp(base, "Makefile") == 0)
        return 1;
    /* the layering test writes a synthetic tree whose names are not documents; this file names what it forbids */
    if (strcmp(path, "tests/unit/test_layering.c") == 0 || strcmp(path, "tests/unit/test_doc_refs.c") == 0)
        return 0;
    size_t n = strlen(base);
    for (int i = 0; ext[i]; i++) {
        size_t k = strlen(ext[i]);
        if (n > k && strcmp(base + n - k, ext[i]) == 0)
            return 1;
    }
    return 0;
}

static void scan_file(scan *s, const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return;
    char *text = NULL;
    size_t cap = 0, len = 0, got;
    do {
        if (len + 65536 + 1 > cap) {
            cap = 2 * cap + 65536 + 1;
            char *t = realloc(text, cap);
            assert_non_null(t);
            text = t;
        }
        got = fread(text + len, 1, cap - len - 1, f);
        len += got;
    } while (got > 0);
    fclose(f);
    text[len] = '\0';
    s->files++;
    scan_text(s, path, text);
    free(text);
}

static int visit(const char *path, const struct stat *st, int type, struct FTW *ftw)
{
    const char *rel = path[0] == '.' && path[1] == '/' ? path + 2 : path;
    const char *base = path + ftw->base;
    if (type == FTW_D && ftw->level > 0 &&
        (base[0] == '.' || strncmp(base, "build", 5) == 0 || strcmp(base, "fixtures") == 0))
        return FTW_SKIP_SUBTREE;
    if (type == FTW_F && wanted(rel))
        scan_file(&g_scan, rel);
    return FTW_CONTINUE;
}

static void test_tree_cites_only_its_files(void **state)
{
    (void)state;
    if (!exists("docs/architecture.md"))
        fail_msg("run from the source tree's root (make check does)");
    memset(&g_scan, 0, sizeof g_scan);
    assert_int_equal(nftw(".", visit, 32, FTW_ACTIONRETVAL | FTW_PHYS), 0);
    printf("doc refs: %d files read, %d citations of .md files, %d outside the repository\n%s", g_scan.files,
           g_scan.refs, g_scan.bad, g_scan.report);
    assert_true(g_scan.files > 300);
    assert_true(g_scan.refs > 50);
    assert_int_equal(g_scan.bad, 0);
}

/* The checker itself: each kind of citation it must refuse, and the ones it must accept. */
static void test_checker_refuses_outside_citations(void **state)
{
    (void)state;
    scan s = {0};
    scan_text(&s, "recon/x.h",
              "/* see DESIGN.md, Numerics; sci-reconstruction.md §3; (rayformer.tex) and ../shared/reference/a.md */\n"
              "docs/missing-page.md\n");
    printf("%s", s.report);
    assert_int_equal(s.bad, 5); /* DESIGN.md, sci-reconstruction.md, .tex, ../shared/reference/a.md, missing */
    scan t = {0};
    scan_text(&t, "recon/x.h",
              "/* docs/conventions.md §10, (docs/protocol.md) `architecture.md`, README.md. %s.md $dir/x.md "
              "bench/results/NAME.md nerf_compare_P.md ../shared/data/real/README.md is data; t.md; obj[i].tex */\n");
    printf("%s", t.report);
    assert_int_equal(t.bad, 0);
    assert_int_equal(t.refs, 4);
}

int main(int argc, char **argv)
{
    if (argc > 1) {
        memset(&g_scan, 0, sizeof g_scan);
        for (int i = 1; i < argc; i++)
            scan_file(&g_scan, argv[i]);
        printf("%s%d files, %d citations, %d outside the repository\n", g_scan.report, g_scan.files, g_scan.refs,
               g_scan.bad);
        return g_scan.bad != 0;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tree_cites_only_its_files),
        cmocka_unit_test(test_checker_refuses_outside_citations),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
