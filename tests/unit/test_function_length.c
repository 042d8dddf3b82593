/* tests/unit/test_function_length.c — no function of the tree is longer than FUNCTION_MAX_LINES.
 *
 * A reader holds one function in view; past about 120 lines it stops being one thought. The project writes a
 * function's body braces at column 0 ("{" and "}" alone on their lines, the style of every .c file here), so a
 * function is measured from the first line of its declaration (the run of non-blank lines above the "{" that are
 * neither comments, preprocessor lines nor the end of another statement) to its closing "}". Every .c and .cpp
 * file under the source folders is read, tests included; build folders and fixtures are not.
 * `test_function_length [N]` lists every function longer than N lines (default the limit), longest first.
 */
#include <ftw.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#define FUNCTION_MAX_LINES 120
#define MAX_LINES 20000

typedef struct found {
    int over, functions, files, longest;
    int limit;
    char report[8192];
    size_t used;
} found;

static found g_found; /* nftw has no user pointer: the one walk in progress */

/* Whether line `l` ends a declaration's upward run: blank, a comment, a preprocessor line, or the end of a
 * statement or block above. */
static int stops_run(const char *l)
{
    size_t n = strlen(l);
    while (n && (l[n - 1] == ' ' || l[n - 1] == '\t'))
        n--;
    return n == 0 || l[0] == '#' || l[0] == '}' || strncmp(l, "/*", 2) == 0 || strncmp(l, " *", 2) == 0 ||
           strncmp(l, "//", 2) == 0 || l[n - 1] == ';' || (n >= 2 && strncmp(l + n - 2, "*/", 2) == 0);
}

static void measure_text(found *f, const char *file, char *text)
{
    static char *lines[MAX_LINES];
    int n = 0;
    for (char *p = text; p && n < MAX_LINES; n++) {
        lines[n] = p;
        p = strchr(p, '\n');
        if (p)
            *p++ = '\0';
    }
    int start = -1;
    for (int i = 1; i < n; i++) {
        if (strcmp(lines[i], "{") == 0) {
            int j = i - 1;
            while (j > 0 && !stops_run(lines[j - 1]))
                j--;
            start = j;
        } else if (strcmp(lines[i], "}") == 0 && start >= 0) {
            int len = i - start + 1;
            f->functions++;
            if (len > f->longest)
                f->longest = len;
            if (len > f->limit) {
                f->over++;
                int k = snprintf(f->report + f->used, sizeof f->report - f->used, "  %4d lines  %s:%d  %.60s\n", len,
                                 file, start + 1, lines[start]);
                if (k > 0 && f->used + (size_t)k < sizeof f->report)
                    f->used += (size_t)k;
            }
            start = -1;
        }
    }
}

static void measure_file(found *f, const char *path)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return;
    fseek(fp, 0, SEEK_END);
    long size = ftell(fp);
    rewind(fp);
    char *text = malloc((size_t)size + 1);
    assert_non_null(text);
    size_t got = fread(text, 1, (size_t)size, fp);
    fclose(fp);
    text[got] = '\0';
    f->files++;
    measure_text(f, path, text);
    free(text);
}

static int visit(const char *path, const struct stat *st, int type, struct FTW *ftw)
{
    const char *base = path + ftw->base, *rel = strncmp(path, "./", 2) == 0 ? path + 2 : path;
    if (type == FTW_D && ftw->level > 0 &&
        (base[0] == '.' || strncmp(base, "build", 5) == 0 || strcmp(base, "fixtures") == 0))
        return FTW_SKIP_SUBTREE;
    size_t n = strlen(base);
    if (type == FTW_F && ((n > 2 && strcmp(base + n - 2, ".c") == 0) || (n > 4 && strcmp(base + n - 4, ".cpp") == 0)))
        measure_file(&g_found, rel);
    return FTW_CONTINUE;
}

static void walk(int limit)
{
    memset(&g_found, 0, sizeof g_found);
    g_found.limit = limit;
    assert_int_equal(nftw(".", visit, 32, FTW_ACTIONRETVAL | FTW_PHYS), 0);
}

static void test_no_function_too_long(void **state)
{
    (void)state;
    if (access("recon/solver.c", R_OK) != 0)
        fail_msg("run from the source tree's root (make check does)");
    walk(FUNCTION_MAX_LINES);
    printf("function length: %d functions in %d files, the longest %d lines; %d over %d:\n%s", g_found.functions,
           g_found.files, g_found.longest, g_found.over, FUNCTION_MAX_LINES, g_found.report);
    assert_true(g_found.files > 200);
    assert_true(g_found.functions > 2000);
    assert_int_equal(g_found.over, 0);
}

/* The measure itself, on a text with a long function, a short one, comments and a prototype above them. */
static void test_measure(void **state)
{
    (void)state;
    char text[4096] = "#include <x.h>\n/* a comment */\nstatic int f(int a,\n             int b)\n{\n";
    for (int i = 0; i < 6; i++)
        strcat(text, "    a++;\n");
    strcat(text, "}\n\nint g(void);\n/* g */\nint g(void)\n{\n    return 0;\n}\n");
    found f = {.limit = 8};
    measure_text(&f, "x.c", text);
    printf("%s", f.report);
    assert_int_equal(f.functions, 2);
    assert_int_equal(f.longest, 10); /* the two declaration lines, the braces and six statements */
    assert_int_equal(f.over, 1);
    assert_non_null(strstr(f.report, "x.c:3"));
}

int main(int argc, char **argv)
{
    if (argc > 1) {
        walk(atoi(argv[1]));
        printf("%s%d functions, %d over %d lines, the longest %d\n", g_found.report, g_found.functions, g_found.over,
               g_found.limit, g_found.longest);
        return 0;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_measure),
        cmocka_unit_test(test_no_function_too_long),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
