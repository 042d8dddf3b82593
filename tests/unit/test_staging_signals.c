/* io/staging.h: sci_staging_publish's check of the stop flag and its rename run with SIGINT, SIGTERM, SIGHUP and
 * SIGQUIT blocked, so a stop signal comes either before (nothing published) or after (the output complete),
 * never in between. This program defines rename() itself — the executable's definition takes the place of
 * libc's for libscicap.a's calls — and raises each signal from inside it: the signal must stay pending there and
 * reach its handler only after the publish has returned. */
#include <fcntl.h>
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cmocka.h>

#include "io/staging.h"

static int raise_in_rename;          /* the signal to raise from inside rename, 0: none */
static volatile sig_atomic_t stop;   /* the handler's flag, as the CLI's */
static volatile sig_atomic_t during; /* the handler ran while rename was running */
static volatile sig_atomic_t in_rename;
static int pending_in_rename;        /* sigpending() held the signal inside rename */

int rename(const char *from, const char *to)
{
    if (raise_in_rename) {
        in_rename = 1;
        raise(raise_in_rename);
        sigset_t p;
        sigpending(&p);
        pending_in_rename = sigismember(&p, raise_in_rename);
        in_rename = 0;
    }
    return (int)syscall(SYS_renameat, AT_FDCWD, from, AT_FDCWD, to);
}

static void on_stop(int sig)
{
    stop = sig;
    if (in_rename)
        during = 1;
}

/* Publish a staged folder with `sig` raised in the middle; the signal must be held until publish returns. */
static void publish_with(int sig)
{
    char base[] = "/tmp/scicap-staging-XXXXXX", tmp[256], out[256], file[300];
    assert_non_null(mkdtemp(base));
    snprintf(out, sizeof out, "%s/out", base);
    assert_int_equal(sci_staging_name(tmp, sizeof tmp, out), 0);
    assert_int_equal(mkdir(tmp, 0755), 0);
    struct sigaction sa = {.sa_handler = on_stop}, old;
    sigemptyset(&sa.sa_mask);
    assert_int_equal(sigaction(sig, &sa, &old), 0);
    stop = during = in_rename = 0;
    pending_in_rename = 0;
    raise_in_rename = sig;
    sci_error err = {0};
    int rc = sci_staging_publish(tmp, out, 0, &stop, &err);
    raise_in_rename = 0;
    sigaction(sig, &old, NULL);
    print_message("  %s: publish %d, pending inside the rename %d, handled during it %d, handled after %d\n",
                  strsignal(sig), rc, pending_in_rename, (int)during, stop == sig);
    assert_int_equal(rc, 0);
    assert_int_equal(during, 0);
    assert_true(pending_in_rename);
    assert_int_equal(stop, sig); /* delivered once unblocked */
    struct stat sb;
    assert_int_equal(stat(out, &sb), 0);
    assert_int_not_equal(stat(tmp, &sb), 0);
    snprintf(file, sizeof file, "%s", base);
    assert_int_equal(sci_staging_remove(file), 0);
}

static void test_sigint_held(void **state) { publish_with(SIGINT); }
static void test_sigterm_held(void **state) { publish_with(SIGTERM); }
static void test_sighup_held(void **state) { publish_with(SIGHUP); }
static void test_sigquit_held(void **state) { publish_with(SIGQUIT); }

/* A stop flag already set: nothing published, the staging folder removed. */
static void test_stop_before(void **state)
{
    char base[] = "/tmp/scicap-staging-XXXXXX", tmp[256], out[256];
    assert_non_null(mkdtemp(base));
    snprintf(out, sizeof out, "%s/out", base);
    assert_int_equal(sci_staging_name(tmp, sizeof tmp, out), 0);
    assert_int_equal(mkdir(tmp, 0755), 0);
    volatile sig_atomic_t set = SIGHUP;
    sci_error err = {0};
    assert_int_equal(sci_staging_publish(tmp, out, 0, &set, &err), SCI_ECANCELED);
    struct stat sb;
    assert_int_not_equal(stat(out, &sb), 0);
    assert_int_not_equal(stat(tmp, &sb), 0);
    assert_int_equal(sci_staging_remove(base), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sigint_held),  cmocka_unit_test(test_sigterm_held),
        cmocka_unit_test(test_sighup_held),  cmocka_unit_test(test_sigquit_held),
        cmocka_unit_test(test_stop_before),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
