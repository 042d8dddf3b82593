/* `scicap recon` against inputs that claim too much. Runs the real binary ($BUILD/scicap) in a
 * child and watches it:
 *   - a 2 KB .mat declaring a 1×1×2,000,000 mask, and one declaring 2,000,000 snapshots, are refused before any
 *     work, naming the limit and --allow-large, with nothing written (before: 4,000,005 files, 17 GB; 140,716
 *     folders when it was stopped);
 *   - --allow-large lifts the limits (the run gets to the next check);
 *   - a stack sidecar claiming 24576² is refused before the cube is allocated (child's peak RSS < 300 MB; before:
 *     2.4 GB allocated and zeroed, then a shape error), by the limit, and with --allow-large by the first frame. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <glob.h>
#include <jansson.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>
#include <matio.h>

#include "io/image.h"
#include "io/problem_dir.h"
#include "tests/helpers/cli_child.h"
#include "tests/helpers/testfiles.h"

static char dir[] = "/tmp/scicap-test-cli-limits-XXXXXX";
static char scicap[1024];

/* A 2 KB .mat: uint8 mask 1×1×nmask and meas 1×1×nmeas, zlib-compressed zeros. */
static void write_tiny_mat(const char *path, size_t nmask, size_t nmeas)
{
    mat_t *m = Mat_CreateVer(path, NULL, MAT_FT_MAT5);
    assert_non_null(m);
    unsigned char *d = calloc(nmask > nmeas ? nmask : nmeas, 1);
    assert_non_null(d);
    d[0] = 1;
    size_t dm[3] = {1, 1, nmask}, dy[3] = {1, 1, nmeas};
    testfiles_mat_put(m, "mask", MAT_C_UINT8, MAT_T_UINT8, 3, dm, d, MAT_COMPRESSION_ZLIB);
    testfiles_mat_put(m, "meas", MAT_C_UINT8, MAT_T_UINT8, 3, dy, d, MAT_COMPRESSION_ZLIB);
    Mat_Close(m);
    free(d);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    assert_true(st.st_size < 4096);
}

static void assert_limit_refusal(const cli_child *c, const char *out)
{
    if (cli_child_exit_code(c) != 1 || !strstr(c->err, "limit of") || !strstr(c->err, "--allow-large"))
        fail_msg("exit %d, stderr: %s", cli_child_exit_code(c), c->err);
    testfiles_assert_nothing_at(out);
}

static void test_mat_declaring_2m_frames_refused(void **state)
{
    char in[512], out[512];
    snprintf(in, sizeof in, "%s/frames.mat", dir);
    snprintf(out, sizeof out, "%s/out_frames", dir);
    write_tiny_mat(in, 2000000, 1);
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", "--iters", "1", in, "-o", out, NULL}, dir);
    assert_limit_refusal(&c, out);
    assert_non_null(strstr(c.err, "2000000 frames each"));
}

static void test_mat_declaring_2m_snapshots_refused(void **state)
{
    char in[512], out[512];
    snprintf(in, sizeof in, "%s/snaps.mat", dir);
    snprintf(out, sizeof out, "%s/out_snaps", dir);
    write_tiny_mat(in, 8, 2000000);
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", "--iters", "1", in, "-o", out, NULL}, dir);
    assert_limit_refusal(&c, out);
    assert_non_null(strstr(c.err, "2000000 snapshot(s)"));
    assert_true(c.maxrss_kb < 300 * 1024); /* refused from the headers: 2,000,000 problems never built */
}

/* With --allow-large the limits are gone: the same 2,000,000-frame file gets past them to the next check, the
 * output folder's missing parent (cheap to provoke; checked before the solver starts). */
static void test_allow_large_lifts_the_limits(void **state)
{
    char in[512], out[512];
    snprintf(in, sizeof in, "%s/frames.mat", dir);
    snprintf(out, sizeof out, "%s/no/such/parent/out", dir);
    write_tiny_mat(in, 2000000, 1);
    cli_child c;
    cli_child_run(&c, scicap,
                  (const char *const[]){"recon", "-q", "--iters", "1", "--allow-large", in, "-o", out, NULL}, dir);
    if (cli_child_exit_code(&c) != 1 || strstr(c.err, "limit of") || !strstr(c.err, "no/such/parent"))
        fail_msg("exit %d, stderr: %s", cli_child_exit_code(&c), c.err);
}

static void test_sidecar_claim_refused_before_allocating(void **state)
{
    char in[512], side[600], out[512];
    snprintf(in, sizeof in, "%s/claim", dir);
    snprintf(side, sizeof side, "%s/mask.json", in);
    snprintf(out, sizeof out, "%s/out_claim", dir);
    testfiles_write_problem(in, 16, 16, 1, 1);
    json_error_t je;
    json_t *j = json_load_file(side, 0, &je);
    assert_non_null(j);
    json_object_set_new(j, "w", json_integer(24576));
    json_object_set_new(j, "h", json_integer(24576));
    assert_int_equal(json_dump_file(j, side, 0), 0);
    json_decref(j);
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", "--iters", "1", in, "-o", out, NULL}, dir);
    assert_limit_refusal(&c, out);
    assert_true(c.maxrss_kb < 300 * 1024);
    cli_child_run(&c, scicap,
                  (const char *const[]){"recon", "-q", "--iters", "1", "--allow-large", in, "-o", out, NULL}, dir);
    if (cli_child_exit_code(&c) != 1 || !strstr(c.err, "24576x24576") || !strstr(c.err, "is 16x16"))
        fail_msg("exit %d, stderr: %s", cli_child_exit_code(&c), c.err);
    if (c.maxrss_kb >= 300 * 1024)
        fail_msg("peak RSS %ld MB: the claimed cube was allocated", c.maxrss_kb / 1024);
    testfiles_assert_nothing_at(out);
}

static int setup(void **state) { return cli_child_setup(scicap, sizeof scicap, "scicap", dir); }
static int teardown(void **state) { return cli_child_remove_dir(dir); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mat_declaring_2m_frames_refused),
        cmocka_unit_test(test_mat_declaring_2m_snapshots_refused),
        cmocka_unit_test(test_allow_large_lifts_the_limits),
        cmocka_unit_test(test_sidecar_claim_refused_before_allocating),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
