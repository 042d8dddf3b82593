/* tests/unit/test_layering.c — the include direction of docs/architecture.md: the tree passes, and the checker
 * (tests/helpers/layering.c) fails on a synthetic tree with a deliberately upward include, naming file and line;
 * the modules of daemon/ include each other without a cycle, and the cycle check fails on a synthetic folder
 * with two cycles, naming the files. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "tests/helpers/layering.h"
#include "tests/helpers/testfiles.h"

/* The source tree: the folder this file was compiled from (the Makefile compiles from the root, so __FILE__ is
 * "tests/unit/test_layering.c" there and the tests run from the root too). */
static const char *tree_root(char *buf, size_t n)
{
    const char *me = __FILE__, *tail = strstr(me, "tests/unit/test_layering.c");
    if (tail && tail > me)
        snprintf(buf, n, "%.*s", (int)(tail - me - 1), me);
    else
        snprintf(buf, n, ".");
    return buf;
}

static void test_tree_is_layered(void **state)
{
    (void)state;
    char root[4096], probe[4200], report[16384];
    tree_root(root, sizeof root);
    snprintf(probe, sizeof probe, "%s/base/cube.h", root);
    if (access(probe, R_OK) != 0)
        fail_msg("%s is not the source tree (run from the root, as make check does)", root);
    int files = 0;
    int bad = layering_check(root, layering_tree, layering_tree_count, report, sizeof report, &files);
    printf("layering: %d files read under %s, %d upward or unknown includes\n%s", files, root, bad, report);
    assert_true(files > 100);
    assert_int_equal(bad, 0);
}

static char tmp[] = "/tmp/scicap-layering-XXXXXX";

/* Writes `text` to root/rel, making the folders on the way. */
static void put_in(const char *root, const char *rel, const char *text)
{
    char path[4096], dir[4096];
    snprintf(path, sizeof path, "%s/%s", root, rel);
    snprintf(dir, sizeof dir, "%s", path);
    for (char *p = dir + strlen(root) + 1; (p = strchr(p, '/')); p++) {
        *p = 0;
        mkdir(dir, 0755);
        *p = '/';
    }
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

static void put(const char *rel, const char *text) { put_in(tmp, rel, text); }

static void remove_tree(const char *root)
{
    char cmd[256];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", root);
    assert_int_equal(system(cmd), 0);
}

/* One violation of each kind, and the includes that must pass, in a tree of its own. */
static void test_upward_include_fails(void **state)
{
    (void)state;
    assert_non_null(mkdtemp(tmp));
    put("base/cube.h", "#include <stdio.h>\n#include \"base/error.h\"\n");
    put("base/bad.c", "/* base may not see recon */\n#include \"recon/gaptv.h\"\n");
    put("recon/gaptv.h", "#include \"base/cube.h\"\n#include \"local.h\"\n");
    put("io/x.c", "#include \"recon/gaptv.h\"\n  #  include \"drivers/dmd.h\"\n");
    put("cli/y.c", "#include \"nowhere/z.h\"\n#include \"sim/a.h\"\n#include \"daemon/d.h\"\n");
    put("stray/s.c", "int s;\n");
    put("build-x/ignored.c", "#include \"cli/y.h\"\n");
    put("docs/notes.md", "#include \"cli/y.h\"\n");
    char report[4096];
    int files = 0;
    int bad = layering_check(tmp, layering_tree, layering_tree_count, report, sizeof report, &files);
    printf("synthetic tree: %d files, %d violations:\n%s", files, bad, report);
    assert_int_equal(files, 5);
    assert_int_equal(bad, 5);
    testfiles_expect_all(report, (const char *const[]){
        "base/bad.c:2: includes \"recon/gaptv.h\": recon/ (layer 1) is above base/ (layer 0)",
        "io/x.c:2: includes \"drivers/dmd.h\": drivers/ (layer 2) is beside io/",
        "cli/y.c:1: includes \"nowhere/z.h\": nowhere/ is not a layer",
        "cli/y.c:3: includes \"daemon/d.h\": daemon/ (layer 4) is beside cli/",
        "stray/s.c:1: stray/ is not a layer",
        NULL});
    assert_null(strstr(report, "io/x.c:1"));   /* io above recon: fine */
    assert_null(strstr(report, "ignored.c"));  /* build output */
    /* a missing root is an error, not a pass */
    assert_true(layering_check("/nonexistent-scicap-root", layering_tree, layering_tree_count, report, sizeof report,
                               NULL) < 0);
    remove_tree(tmp);
}

static void test_daemon_has_no_cycle(void **state)
{
    (void)state;
    char root[4096], report[16384];
    tree_root(root, sizeof root);
    int modules = 0;
    int cycles = layering_cycles(root, "daemon", report, sizeof report, &modules);
    printf("daemon/: %d modules, %d include cycles\n%s", modules, cycles, report);
    assert_true(modules > 20);
    assert_int_equal(cycles, 0);
}

/* The two shapes the daemon had: a job module and the thread module that calls it calling each other through
 * their headers (acq.c -> cal.h -> acq.h), and a three-module loop through .c files (pkg -> cal -> job -> pkg). */
static void test_cycle_is_named(void **state)
{
    (void)state;
    char dir[] = "/tmp/scicap-cycles-XXXXXX";
    assert_non_null(mkdtemp(dir));
    const char *files[][2] = {
        {"acq.h", "#include \"base/log.h\"\n"},
        {"acq.c", "#include \"d/acq.h\"\n#include \"d/cal.h\"\n"},
        {"cal.h", "#include <stdio.h>\n#include \"d/acq.h\"\n"},
        {"cal.c", "#include \"d/cal.h\"\n#include \"d/job.h\"\n"},
        {"job.h", "\n"},
        {"job.c", "#include \"d/job.h\"\n#include \"d/pkg.h\"\n"},
        {"pkg.h", "#include \"d/leaf.h\"\n"},
        {"pkg.c", "#include \"d/pkg.h\"\n\n\n#include \"d/cal.h\"\n"},
        {"leaf.h", "#include \"d/leaf.h\"\n"}, /* itself: not a cycle */
    };
    char rel[64];
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        snprintf(rel, sizeof rel, "d/%s", files[i][0]);
        put_in(dir, rel, files[i][1]);
    }
    char report[4096];
    int modules = 0;
    int cycles = layering_cycles(dir, "d", report, sizeof report, &modules);
    printf("synthetic folder: %d modules, %d cycles:\n%s", modules, cycles, report);
    assert_int_equal(modules, 5);
    assert_int_equal(cycles, 2);
    testfiles_expect_all(report, (const char *const[]){
        "d/acq.c includes d/cal.h (line 2)",
        "d/cal.h includes d/acq.h (line 2)",
        "d/cal.c includes d/job.h (line 2)",
        "d/job.c includes d/pkg.h (line 2)",
        "d/pkg.c includes d/cal.h (line 4)",
        NULL});
    assert_null(strstr(report, "leaf"));
    /* the same folder without the two back edges is one-way */
    put_in(dir, "d/cal.h", "");
    put_in(dir, "d/pkg.c", "#include \"d/pkg.h\"\n");
    assert_int_equal(layering_cycles(dir, "d", report, sizeof report, NULL), 0);
    assert_true(layering_cycles(dir, "missing", report, sizeof report, NULL) < 0);
    remove_tree(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tree_is_layered),
        cmocka_unit_test(test_upward_include_fails),
        cmocka_unit_test(test_daemon_has_no_cycle),
        cmocka_unit_test(test_cycle_is_named),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
