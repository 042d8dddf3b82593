/* base/file: sci_file_write_atomic* replace a file whole or not at all, and leave no temporary file behind. */
#include <dirent.h>
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "base/file.h"
#include "base/json.h"

typedef struct fixture {
    char dir[64];
    char path[128];
} fixture;

static int setup(void **state)
{
    fixture *fx = calloc(1, sizeof *fx);
    strcpy(fx->dir, "/tmp/scicap-file-XXXXXX");
    if (!mkdtemp(fx->dir))
        return -1;
    snprintf(fx->path, sizeof fx->path, "%s/out.json", fx->dir);
    *state = fx;
    return 0;
}

static int teardown(void **state)
{
    fixture *fx = *state;
    DIR *d = opendir(fx->dir);
    for (struct dirent *e; d && (e = readdir(d));) {
        char p[400];
        snprintf(p, sizeof p, "%s/%s", fx->dir, e->d_name);
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
            unlink(p);
    }
    if (d)
        closedir(d);
    rmdir(fx->dir);
    free(fx);
    return 0;
}

/* Names in the folder other than . and .. */
static int count_entries(const char *dir)
{
    int n = 0;
    DIR *d = opendir(dir);
    for (struct dirent *e; d && (e = readdir(d));)
        n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
    closedir(d);
    return n;
}

static void assert_content(const char *path, const char *want)
{
    void *buf;
    size_t len;
    sci_error err = {0};
    assert_int_equal(sci_file_read(path, 1 << 20, &buf, &len, &err), 0);
    assert_int_equal(len, strlen(want));
    assert_memory_equal(buf, want, len);
    free(buf);
}

static void test_write_creates_and_replaces(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    assert_int_equal(sci_file_write_atomic(fx->path, "first\n", 6, 0640, 0, &err), 0);
    assert_content(fx->path, "first\n");
    struct stat st;
    assert_int_equal(stat(fx->path, &st), 0);
    assert_int_equal(st.st_mode & 0777, 0640);
    assert_int_equal(sci_file_write_atomic(fx->path, "second", 6, 0644, SCI_FILE_NO_SYNC, &err), 0);
    assert_content(fx->path, "second");
    assert_int_equal(sci_file_write_atomic(fx->path, "", 0, 0644, 0, &err), 0);
    assert_content(fx->path, "");
    assert_int_equal(count_entries(fx->dir), 1); /* no temporary file left */
}

/* The mode is what open(2) would give: a private umask keeps the file private. */
static void test_umask_applies(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    mode_t old = umask(077);
    int rc = sci_file_write_atomic(fx->path, "x", 1, 0644, 0, &err);
    umask(old);
    assert_int_equal(rc, 0);
    struct stat st;
    assert_int_equal(stat(fx->path, &st), 0);
    assert_int_equal(st.st_mode & 0777, 0600);
}

static int write_lines(FILE *f, void *user, sci_error *err)
{
    (void)err;
    for (int i = 0; i < *(int *)user; i++)
        fprintf(f, "line %d\n", i);
    return 0;
}

static int write_then_fail(FILE *f, void *user, sci_error *err)
{
    (void)user;
    fputs("half a docu", f);
    fflush(f);
    return sci_error_set(err, -EINVAL, "x.json: the writer gave up");
}

static void test_writer_failure_keeps_old(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    int lines = 3;
    assert_int_equal(sci_file_write_atomic_with(fx->path, 0644, 0, write_lines, &lines, &err), 0);
    assert_content(fx->path, "line 0\nline 1\nline 2\n");
    assert_int_equal(sci_file_write_atomic_with(fx->path, 0644, 0, write_then_fail, NULL, &err), -EINVAL);
    assert_string_equal(err.msg, "x.json: the writer gave up"); /* the writer's message is kept */
    assert_content(fx->path, "line 0\nline 1\nline 2\n");
    assert_int_equal(count_entries(fx->dir), 1);
}

/* A full disk, as the file-size limit makes it: the write fails with EFBIG at the flush. */
static void test_full_disk_keeps_old(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    assert_int_equal(sci_file_write_atomic(fx->path, "old", 3, 0644, 0, &err), 0);
    struct rlimit old_lim, lim = {.rlim_cur = 4096, .rlim_max = RLIM_INFINITY};
    getrlimit(RLIMIT_FSIZE, &old_lim);
    lim.rlim_max = old_lim.rlim_max;
    void (*old_sig)(int) = signal(SIGXFSZ, SIG_IGN);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
    static char big[65536];
    memset(big, 'x', sizeof big);
    int rc = sci_file_write_atomic(fx->path, big, sizeof big, 0644, 0, &err);
    setrlimit(RLIMIT_FSIZE, &old_lim);
    signal(SIGXFSZ, old_sig);
    assert_int_equal(rc, -EFBIG);
    assert_non_null(strstr(err.msg, fx->path));
    assert_content(fx->path, "old");
    assert_int_equal(count_entries(fx->dir), 1);
}

static void test_missing_folder(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    char p[200];
    snprintf(p, sizeof p, "%s/no/such/out.json", fx->dir);
    assert_int_equal(sci_file_write_atomic(p, "x", 1, 0644, 0, &err), -ENOENT);
    assert_non_null(strstr(err.msg, p));
    assert_int_equal(count_entries(fx->dir), 0);
}

/* Renaming over a folder fails: the temporary file must go, the folder stay. */
static void test_rename_failure_cleans_up(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    assert_int_equal(mkdir(fx->path, 0755), 0);
    assert_true(sci_file_write_atomic(fx->path, "x", 1, 0644, 0, &err) < 0);
    assert_int_equal(count_entries(fx->dir), 1);
    struct stat st;
    assert_int_equal(stat(fx->path, &st), 0);
    assert_true(S_ISDIR(st.st_mode));
    rmdir(fx->path);
}

/* A bare file name lands in the current folder. */
static void test_relative_name(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    char cwd[4096];
    assert_non_null(getcwd(cwd, sizeof cwd));
    assert_int_equal(chdir(fx->dir), 0);
    int rc = sci_file_write_atomic("plain.txt", "abc", 3, 0600, 0, &err);
    assert_int_equal(chdir(cwd), 0);
    assert_int_equal(rc, 0);
    char p[200];
    snprintf(p, sizeof p, "%s/plain.txt", fx->dir);
    assert_content(p, "abc");
    assert_int_equal(count_entries(fx->dir), 1);
}

/* A writer by name gets an empty file in the same folder whose name keeps the extension last. */
static int write_by_name(const char *tmp, void *user, sci_error *err)
{
    const fixture *fx = user;
    size_t n = strlen(tmp), dn = strlen(fx->dir);
    if (strncmp(tmp, fx->dir, dn) != 0 || tmp[dn] != '/' || tmp[dn + 1] != '.' || n < 5 ||
        strcmp(tmp + n - 5, ".json") != 0)
        return sci_error_set(err, -EINVAL, "%s: not a sibling ending in .json", tmp);
    FILE *f = fopen(tmp, "w");
    if (!f)
        return -errno;
    fputs("by name", f);
    return fclose(f) == 0 ? 0 : -EIO;
}

static int fail_by_name(const char *tmp, void *user, sci_error *err)
{
    (void)user, (void)err;
    FILE *f = fopen(tmp, "w");
    fputs("partial", f);
    fclose(f);
    return -ENOSPC;
}

static void test_named_writer(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    assert_int_equal(sci_file_write_atomic_named(fx->path, 0644, 0, write_by_name, fx, &err), 0);
    assert_content(fx->path, "by name");
    assert_int_equal(sci_file_write_atomic_named(fx->path, 0644, 0, fail_by_name, fx, &err), -ENOSPC);
    assert_non_null(strstr(err.msg, fx->path)); /* no message from the writer: the path and the code's text */
    assert_content(fx->path, "by name");
    assert_int_equal(count_entries(fx->dir), 1);
}

/* The JSON form writes exactly what json_dumpf would. */
static void test_json_document(void **state)
{
    fixture *fx = *state;
    sci_error err = {0};
    json_t *j = json_pack("{s:i}", "a", 1);
    assert_int_equal(sci_json_write_atomic(fx->path, j, JSON_COMPACT, 0644, 0, &err), 0);
    json_decref(j);
    assert_content(fx->path, "{\"a\":1}");
    assert_int_equal(count_entries(fx->dir), 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_write_creates_and_replaces, setup, teardown),
        cmocka_unit_test_setup_teardown(test_umask_applies, setup, teardown),
        cmocka_unit_test_setup_teardown(test_writer_failure_keeps_old, setup, teardown),
        cmocka_unit_test_setup_teardown(test_full_disk_keeps_old, setup, teardown),
        cmocka_unit_test_setup_teardown(test_missing_folder, setup, teardown),
        cmocka_unit_test_setup_teardown(test_rename_failure_cleans_up, setup, teardown),
        cmocka_unit_test_setup_teardown(test_relative_name, setup, teardown),
        cmocka_unit_test_setup_teardown(test_json_document, setup, teardown),
        cmocka_unit_test_setup_teardown(test_named_writer, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
