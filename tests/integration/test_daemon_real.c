/* A real capture of another lab through the daemon: `scicap capture --from 6fan14_cacti.mat --recon --wait` with no
 * scale option infers what `scicap recon` infers (masks 0–113 divided by 113, white 130), says so in the import's
 * line, and the reconstruction's frames are neither black nor saturated (result.json's levels). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>
#include <jansson.h>

#include "tests/helpers/cli_child.h"
#include "tests/helpers/daemon_child.h"
#include "tests/helpers/testdata.h"

static harness H;
static char scicap[1024];

static void test_real_capture_imports_with_inferred_scales(void **state)
{
    char real[4096];
    TESTDATA_REQUIRE("real/6fan14_cacti.mat", real);
    cli_child c;
    cli_child_run(&c, scicap,
                  (const char *const[]){"capture", "--socket", H.sock, "--from", real, "--recon", "--wait", NULL}, H.dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d\nstdout: %s\nstderr: %s", cli_child_exit_code(&c), c.out, c.err);
    print_message("%s", c.out);
    if (!strstr(c.out, "values divided by 130: masks 'mask' peak at 113, divided by it"))
        fail_msg("the inferred scales are not said: %s", c.out);
    if (!strstr(c.out, "relative residual"))
        fail_msg("no residual reported: %s", c.out);
    json_t *j = daemon_child_result(&H, "c000001", "gap-tv");
    testdata_expect_real_levels(j, "  capture c000001");
    json_decref(j);
}

static int setup(void **state) { return daemon_child_setup(&H, scicap, sizeof scicap, NULL); }
static int teardown(void **state) { return daemon_child_teardown(&H); }

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_real_capture_imports_with_inferred_scales)};
    return cmocka_run_group_tests(tests, setup, teardown);
}
