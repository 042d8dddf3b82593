/* tests/unit/test_daemon_store.c — the storage root's crash recovery at open, without the scicapd binary: what a
 * kill -9 leaves behind (a partial capture folder, the temporary file of an interrupted atomic write in ROOT) is
 * removed, complete captures are counted, and files of the administrator's in ROOT are left alone. */
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "daemon/store.h"

static void touch(const char *dir, const char *name)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("x", f);
    fclose(f);
}

static int present(const char *dir, const char *name)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return access(path, F_OK) == 0;
}

static void test_open_removes_what_a_crash_left(void **state)
{
    (void)state;
    char root[] = "/tmp/scicap-store-XXXXXX", path[512];
    assert_non_null(mkdtemp(root));
    snprintf(path, sizeof path, "%s/captures", root);
    assert_int_equal(mkdir(path, 0750), 0);
    snprintf(path, sizeof path, "%s/captures/c000007", root);
    assert_int_equal(mkdir(path, 0750), 0); /* complete */
    snprintf(path, sizeof path, "%s/captures/.c000008.partial", root);
    assert_int_equal(mkdir(path, 0750), 0); /* a capture being written */
    touch(root, ".capture.tmp-Ab12Cd.running"); /* an interrupted atomic write of ROOT/capture.running */
    touch(root, ".ids.tmp-Zz9Yy8.json");
    touch(root, "notes.txt");                   /* the administrator's */
    touch(root, ".keep");
    snprintf(path, sizeof path, "%s/.cache.tmp-dir", root);
    assert_int_equal(mkdir(path, 0750), 0); /* a folder of that name is not one of the writer's files */

    scicapd_store *st = NULL;
    scicapd_store_recovery rec = {0};
    sci_error err = {0};
    if (scicapd_store_open(&st, root, 0, NULL, &rec, &err) < 0)
        fail_msg("open: %s", err.msg);
    printf("store open: %d complete captures, %d partial outputs removed\n", rec.captures, rec.removed);
    assert_int_equal(rec.captures, 1);
    assert_int_equal(rec.removed, 3);
    assert_false(present(root, "captures/.c000008.partial"));
    assert_false(present(root, ".capture.tmp-Ab12Cd.running"));
    assert_false(present(root, ".ids.tmp-Zz9Yy8.json"));
    assert_true(present(root, "captures/c000007"));
    assert_true(present(root, "notes.txt"));
    assert_true(present(root, ".keep"));
    assert_true(present(root, ".cache.tmp-dir"));
    scicapd_store_close(st);

    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", root);
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_open_removes_what_a_crash_left),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
