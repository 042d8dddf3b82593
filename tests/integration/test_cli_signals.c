/* `scicap recon` and the signals of a shared terminal: SIGHUP (the terminal closed) and SIGQUIT (Ctrl-\) end a
 * run as SIGINT/SIGTERM do — the staging folder OUT.tmp-PID is removed, OUT never appears, and the process dies
 * of that signal — and a staging folder left by a process that no longer runs (SIGKILL, a power cut) is removed
 * by the next run into the same OUT, which says so on stderr; one of a living process is left alone.
 * Runs drop40 (all its snapshots: OUT.tmp-PID is made at the start) with GAP-TV. */
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
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "tests/helpers/cli_child.h"
#include "tests/helpers/testdata.h"

static char scicap[1024], dir[512] = "/tmp/scicap-signals-XXXXXX";

static int setup(void **state) { return cli_child_setup(scicap, sizeof scicap, "scicap", dir); }
static int teardown(void **state) { return cli_child_remove_dir(dir); }

static void sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

static int exists(const char *p)
{
    struct stat st;
    return lstat(p, &st) == 0;
}

/* Start a long recon of drop40 into out, wait for its staging folder, send sig; it must die of sig, leaving
 * neither the staging folder nor out. */
static void stop_with(int sig, const char *drop40)
{
    char out[700], stage[800];
    snprintf(out, sizeof out, "%s/out-%d", dir, sig);
    /* no core file of SIGQUIT in the test's folder */
    struct rlimit nocore = {0, 0}, old;
    getrlimit(RLIMIT_CORE, &old);
    setrlimit(RLIMIT_CORE, &nocore);
    cli_child c;
    cli_child_start(&c, scicap, (const char *const[]){"recon", "-q", drop40, "-o", out, "--iters", "100000", NULL},
                    dir);
    setrlimit(RLIMIT_CORE, &old);
    snprintf(stage, sizeof stage, "%s.tmp-%d", out, (int)c.pid);
    int seen = 0;
    for (int i = 0; i < 1200 && !(seen = exists(stage)); i++)
        sleep_ms(50);
    if (!seen) {
        kill(c.pid, SIGKILL);
        cli_child_finish(&c);
        fail_msg("no %s within 60 s; stderr: %s", stage, c.err);
    }
    sleep_ms(300); /* into the solver */
    kill(c.pid, sig);
    cli_child_finish(&c);
    if (!WIFSIGNALED(c.status) || WTERMSIG(c.status) != sig)
        fail_msg("after %s: status 0x%x, expected death by that signal; stderr: %s", strsignal(sig), c.status, c.err);
    print_message("  %s: died of it; stderr: %s", strsignal(sig), c.err);
    assert_false(exists(stage));
    assert_false(exists(out));
    assert_non_null(strstr(c.err, "interrupted"));
}

static void test_sighup_cleans_up(void **state)
{
    char drop40[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", drop40);
    stop_with(SIGHUP, drop40);
}

static void test_sigquit_cleans_up(void **state)
{
    char drop40[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", drop40);
    stop_with(SIGQUIT, drop40);
}

static void test_stale_stage_of_dead_process_removed(void **state)
{
    char drop40[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", drop40);
    char out[700], dead[800], alive[800], file[900];
    snprintf(out, sizeof out, "%s/out-stale", dir);
    /* a pid that no longer runs: a child that has exited and been reaped */
    pid_t gone = fork();
    assert_true(gone >= 0);
    if (gone == 0)
        _exit(0);
    assert_int_equal(waitpid(gone, NULL, 0), gone);
    snprintf(dead, sizeof dead, "%s.tmp-%d", out, (int)gone);
    snprintf(alive, sizeof alive, "%s.tmp-%d", out, (int)getpid()); /* ours: a living writer */
    assert_int_equal(mkdir(dead, 0755), 0);
    assert_int_equal(mkdir(alive, 0755), 0);
    snprintf(file, sizeof file, "%s/snap_001", dead);
    assert_int_equal(mkdir(file, 0755), 0);
    cli_child c;
    cli_child_run(&c, scicap,
                  (const char *const[]){"recon", "-q", drop40, "-o", out, "--snapshot", "1", "--iters", "2", NULL},
                  dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d; stderr: %s", cli_child_exit_code(&c), c.err);
    print_message("  stderr: %s", c.err);
    assert_false(exists(dead));
    assert_true(exists(alive));
    assert_true(exists(out));
    char said[900];
    snprintf(said, sizeof said, "removed %s", dead);
    if (!strstr(c.err, said) || !strstr(c.err, "no longer runs"))
        fail_msg("stderr does not say it removed %s: %s", dead, c.err);
    rmdir(alive);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sighup_cleans_up),
        cmocka_unit_test(test_sigquit_cleans_up),
        cmocka_unit_test(test_stale_stage_of_dead_process_removed),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
