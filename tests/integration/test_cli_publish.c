/* `scicap recon` publishes its output only once complete. Runs the real binary ($BUILD/scicap) in a child: SIGTERM
 * while the output is being written (one snapshot; and between snapshots of three) leaves neither OUTDIR nor
 * OUTDIR.tmp-PID and the child dies of SIGTERM. Bad inputs are refused before OUTDIR is made: an empty folder of
 * inputs (a batch) leaves no OUTDIR; an image alone says it holds no masks; a missing input is named before a
 * missing output folder. */
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

static char dir[] = "/tmp/scicap-test-cli-publish-XXXXXX";
static char scicap[1024];

static int exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* Start a reconstruction, wait until OUT.tmp-PID<suffix> (or OUT<suffix>, where the code before
 * publish-on-success wrote) appears, and SIGTERM it at once. *still_writing: the path was still there after the
 * kill, so the signal came while the output was being written. */
static void sigterm_when(const char *in, const char *out, const char *suffix, int *still_writing, cli_child *c)
{
    cli_child_start(c, scicap, (const char *const[]){"recon", "-q", "--iters", "1", in, "-o", out, NULL}, dir);
    char w1[700], w2[700];
    snprintf(w1, sizeof w1, "%s.tmp-%d%s", out, (int)c->pid, suffix);
    snprintf(w2, sizeof w2, "%s%s", out, suffix);
    struct timespec t0, t;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int seen = 0;
    for (;;) {
        if (exists(w1) || exists(w2)) {
            seen = 1;
            break;
        }
        if (waitpid(c->pid, &c->status, WNOHANG) == c->pid)
            fail_msg("scicap recon ended (status 0x%x) before %s appeared", c->status, w1);
        clock_gettime(CLOCK_MONOTONIC, &t);
        if (t.tv_sec - t0.tv_sec > 20)
            break;
        usleep(500);
    }
    kill(c->pid, SIGTERM);
    *still_writing = seen && (exists(w1) || exists(w2));
    cli_child_finish(c);
    if (!seen)
        fail_msg("%s never appeared", w1);
}

/* dir/name, a problem of k w×h×n snapshots, reconstructed into dir/out_name and sent SIGTERM once `mark` (a path
 * under the staging folder) exists: scicap dies of the signal and nothing is published. must_be_mid: the write
 * must have been under way when the signal came (else the problem is too small to tell). */
static void sigterm_publishes_nothing(const char *name, int w, int h, int n, int k, const char *mark, int must_be_mid)
{
    char in[512], out[512];
    snprintf(in, sizeof in, "%s/%s", dir, name);
    snprintf(out, sizeof out, "%s/out_%s", dir, name);
    testfiles_write_problem(in, w, h, n, k);
    int mid = 0;
    cli_child c;
    sigterm_when(in, out, mark, &mid, &c);
    if (must_be_mid && !mid)
        fail_msg("the write had finished before SIGTERM; make the problem larger");
    if (!WIFSIGNALED(c.status) || WTERMSIG(c.status) != SIGTERM)
        fail_msg("status 0x%x, not death by SIGTERM; stderr: %s", c.status, c.err);
    testfiles_assert_nothing_at(out);
}

/* the staging folder OUT.tmp-PID exists from the first file written to the rename that publishes it; the 16 1024²
 * frames take about a second to write (EXR, PNG, GIF) */
static void test_sigterm_while_writing_publishes_nothing(void **state)
{
    sigterm_publishes_nothing("large", 1024, 1024, 16, 1, "", 1);
}

/* snapshot 1 finished: OUT.tmp-PID/snap_001 now (OUT/snap_001 before publish-on-success) */
static void test_sigterm_between_snapshots_publishes_nothing(void **state)
{
    sigterm_publishes_nothing("three", 256, 256, 8, 3, "/snap_001", 0);
}

/* Run a command with stderr into dir/err.txt; its exit status. */
static int sh(const char *fmt, ...)
{
    char cmd[8192], full[8400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    snprintf(full, sizeof full, "%s >/dev/null 2>%s/err.txt", cmd, dir);
    int rc = system(full);
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

static int err_has(const char *what)
{
    char path[2048], buf[4096];
    snprintf(path, sizeof path, "%s/err.txt", dir);
    FILE *f = fopen(path, "r");
    size_t n = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
    buf[n] = 0;
    if (f)
        fclose(f);
    printf("stderr: %s", buf);
    return strstr(buf, what) != NULL;
}

static void test_bad_inputs_leave_nothing(void **state)
{
    char p[2048];
    snprintf(p, sizeof p, "%s/emptydir", dir);
    assert_int_equal(mkdir(p, 0755), 0);
    assert_int_equal(sh("%s recon %s/emptydir -o %s/o5", scicap, dir, dir), 2);
    assert_true(err_has("no .mat file or problem folder in it"));
    snprintf(p, sizeof p, "%s/o5", dir);
    assert_false(exists(p));
    assert_int_equal(sh("%s batch %s/emptydir -o %s/o6", scicap, dir, dir), 2);
    snprintf(p, sizeof p, "%s/o6", dir);
    assert_false(exists(p));
    /* an image: what it lacks, not "img.png/problem.json: Not a directory" */
    snprintf(p, sizeof p, "%s/img.png", dir);
    sci_cube *c = NULL;
    sci_error err = {0};
    assert_int_equal(sci_cube_new(&c, 8, 8, 1, &err), 0);
    assert_int_equal(sci_image_write(p, c, 0, SCI_PIXEL_U8, 255, NULL, &err), 0);
    sci_cube_free(c);
    assert_int_equal(sh("%s recon %s/img.png -o %s/o7", scicap, dir, dir), 1);
    assert_true(err_has("an image alone cannot be reconstructed (it holds no masks)"));
    /* the input is checked before the output's folder */
    assert_int_equal(sh("%s recon %s/missing.mat -o %s/nope/o8", scicap, dir, dir), 1);
    assert_true(err_has("missing.mat: No such file or directory"));
    assert_int_not_equal(sh("%s recon %s/emptydir -o %s/nope/o9", scicap, dir, dir), 0);
    assert_true(err_has("no .mat file or problem folder in it"));
}

static int setup(void **state) { return cli_child_setup(scicap, sizeof scicap, "scicap", dir); }
static int teardown(void **state) { return cli_child_remove_dir(dir); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sigterm_while_writing_publishes_nothing),
        cmocka_unit_test(test_sigterm_between_snapshots_publishes_nothing),
        cmocka_unit_test(test_bad_inputs_leave_nothing),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
