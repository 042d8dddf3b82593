/* 4200×4200 through `scicap recon`: OpenImageIO 2.4's GIF writer dies of SIGSEGV on frames over
 * 2^24 pixels, and the crash left OUTDIR.tmp-PID behind. Now the preview is shrunk (to 1400², io/image.h) and the
 * run succeeds with no temporary left. Runs the real binary in a child. `scicap sim` wrote its preview_truth.gif
 * through the same sci_image_write_gif (checked at 4200² in test_io): a 4200² simulation takes 30 s on a loaded
 * 2-core machine, too long for this suite. */
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

static char dir[] = "/tmp/scicap-test-cli-large-XXXXXX";
static char scicap[1024];

static void test_4200_square_reconstructs_with_small_gif(void **state)
{
    char in[512], out[512], gif[600];
    snprintf(in, sizeof in, "%s/huge", dir);
    snprintf(out, sizeof out, "%s/out_huge", dir);
    snprintf(gif, sizeof gif, "%s/preview.gif", out);
    testfiles_write_problem(in, 4200, 4200, 2, 1);
    cli_child c;
    cli_child_run(&c, scicap,
                  (const char *const[]){"recon", "-q", "--iters", "1", "--tv-iters", "1", in, "-o", out, NULL}, dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("status 0x%x (signal %d), stderr: %s", c.status, WIFSIGNALED(c.status) ? WTERMSIG(c.status) : 0,
                 c.err);
    sci_cube *g = NULL;
    sci_error err = {0};
    if (sci_image_read(gif, &g, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(g->w, 1400); /* 4200 / 3: the smallest factor under 2048² pixels */
    assert_int_equal(g->h, 1400);
    sci_cube_free(g);
    char pat[600];
    glob_t gl;
    snprintf(pat, sizeof pat, "%s.tmp-*", out);
    assert_int_not_equal(glob(pat, 0, NULL, &gl), 0);
    globfree(&gl);
}

static int setup(void **state) { return cli_child_setup(scicap, sizeof scicap, "scicap", dir); }
static int teardown(void **state) { return cli_child_remove_dir(dir); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_4200_square_reconstructs_with_small_gif),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
