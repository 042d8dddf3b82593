/* A damaged MATLAB v7.3 (HDF5) file given to `scicap recon`: one clear line on stderr naming the file, that it is
 * a v7.3 file and HDF5's own reason — not HDF5's error stack (kilobytes of it), not a misleading "no variable"
 * or "it is empty", not "infinite loop closing library" at exit — and exit status 1. The same file whole
 * reconstructs. The files are made here with libmatio (an 8×8×4 problem), then truncated or overwritten. */
#include <fcntl.h>
#include <matio.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "tests/helpers/cli_child.h"
#include "tests/helpers/testfiles.h"

static char scicap[1024], dir[512] = "/tmp/scicap-mat73-XXXXXX";

static int setup(void **state) { return cli_child_setup(scicap, sizeof scicap, "scicap", dir); }
static int teardown(void **state) { return cli_child_remove_dir(dir); }

/* An 8×8×4 problem as v7.3: masks and measurement. */
static void write_v73(const char *path)
{
    mat_t *m = Mat_CreateVer(path, NULL, MAT_FT_MAT73);
    assert_non_null(m);
    size_t dm[3] = {8, 8, 4}, dy[2] = {8, 8};
    double mask[256], meas[64];
    for (int i = 0; i < 256; i++)
        mask[i] = i * 7 % 3 == 0;
    for (int i = 0; i < 64; i++)
        meas[i] = i % 5;
    testfiles_mat_put(m, "mask", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dm, mask, MAT_COMPRESSION_NONE);
    testfiles_mat_put(m, "meas", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dy, meas, MAT_COMPRESSION_NONE);
    Mat_Close(m);
}

/* `count` bytes at offset `at` set to `byte` */
static void overwrite(const char *path, long at, int count, int byte)
{
    int fd = open(path, O_WRONLY);
    assert_true(fd >= 0);
    char b[1024];
    memset(b, byte, sizeof b);
    assert_int_equal(pwrite(fd, b, (size_t)count, at), count);
    close(fd);
}

static void expect_one_clear_line(const char *name, const char *reason)
{
    char in[700], out[700];
    snprintf(in, sizeof in, "%s/%s.mat", dir, name);
    snprintf(out, sizeof out, "%s/out-%s", dir, name);
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", in, "-o", out, "--iters", "2", NULL}, dir);
    print_message("  %s: exit %d, %zu bytes on stderr: %s", name, cli_child_exit_code(&c), strlen(c.err), c.err);
    assert_int_equal(cli_child_exit_code(&c), 1);
    if (strstr(c.err, "HDF5-DIAG") || strstr(c.err, "infinite loop") || strstr(c.err, "no variable") ||
        strstr(c.err, "empty"))
        fail_msg("HDF5's diagnostics or a misleading message: %s", c.err);
    assert_non_null(strstr(c.err, in));
    assert_non_null(strstr(c.err, "v7.3 (HDF5)"));
    if (reason && !strstr(c.err, reason))
        fail_msg("HDF5's reason \"%s\" is not given: %s", reason, c.err);
    const char *nl = strchr(c.err, '\n');
    assert_non_null(nl);
    assert_true(nl[1] == '\0'); /* one line */
}

static void test_whole_file_reconstructs(void **state)
{
    char in[700], out[700];
    snprintf(in, sizeof in, "%s/whole.mat", dir);
    snprintf(out, sizeof out, "%s/out-whole", dir);
    write_v73(in);
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", in, "-o", out, "--iters", "2", NULL}, dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d: %s", cli_child_exit_code(&c), c.err);
    assert_null(strstr(c.err, "HDF5"));
}

static void test_truncated(void **state)
{
    char in[700];
    snprintf(in, sizeof in, "%s/truncated.mat", dir);
    write_v73(in);
    assert_int_equal(truncate(in, 3000), 0);
    expect_one_clear_line("truncated", "truncated file");
}

static void test_bad_object_header(void **state)
{
    char in[700];
    snprintf(in, sizeof in, "%s/header.mat", dir);
    write_v73(in);
    overwrite(in, 600, 600, 0xff); /* the root group's object header */
    expect_one_clear_line("header", "object header");
}

static void test_bad_superblock(void **state)
{
    char in[700];
    snprintf(in, sizeof in, "%s/superblock.mat", dir);
    write_v73(in);
    overwrite(in, 512 + 8, 1, 9); /* the superblock's version */
    expect_one_clear_line("superblock", "superblock");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_whole_file_reconstructs),
        cmocka_unit_test(test_truncated),
        cmocka_unit_test(test_bad_object_header),
        cmocka_unit_test(test_bad_superblock),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
