/* `scicap capture --from FILE.mat --allow-large`: the CLI sends allow_large with the import, and the daemon honours
 * it only for its admins. A small .mat declaring 5,000 snapshots of 8×8×8 (over the limits of io/limits.h):
 *  - root without --allow-large: --wait reports the import refused, "would create N files", nothing stored;
 *  - uid 65534 (setpriv) with --allow-large: refused at once, exit 1, the daemon's reason (permission) printed;
 *  - root with --allow-large: queued, and the import stores captures (cancelled after the first). */
#include <errno.h>
#include <matio.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <dirent.h>

#include <cmocka.h>

#include "tests/helpers/cli_child.h"
#include "tests/helpers/testfiles.h"
#include "tests/integration/daemon_harness.h"

#define SNAPSHOTS 5000

static harness H;
static char file[600], scicap[1024];

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

static void start(void)
{
    harness_start_open(&H, "{\"control\": {\"mode\": \"0666\"}}\n");
    snprintf(file, sizeof file, "%s/many.mat", H.dir);
    testfiles_write_declared_mat(file, SNAPSHOTS);
    assert_int_equal(cli_child_program(scicap, sizeof scicap, "scicap"), 0);
}

static void test_without_allow_large_refused(void **state)
{
    start();
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"capture", "--socket", H.sock, "--from", file, "--wait", NULL},
                  H.dir);
    print_message("  root, no --allow-large: exit %d; %s%s", cli_child_exit_code(&c), c.out, c.err);
    assert_int_not_equal(cli_child_exit_code(&c), 0);
    assert_true(strstr(c.err, "would create ") || strstr(c.out, "would create "));
    assert_int_equal(harness_count_captures(&H), 0);
    harness_stop(&H);
}

static void test_allow_large_refused_to_a_user(void **state)
{
    harness_require_root("run scicap as uid 65534");
    start();
    cli_child c;
    cli_child_run(&c, "/usr/bin/setpriv",
                  (const char *const[]){"--reuid", "65534", "--regid", "65534", "--clear-groups", scicap, "capture",
                                        "--socket", H.sock, "--from", file, "--allow-large", NULL},
                  H.dir);
    print_message("  uid 65534 with --allow-large: exit %d; %s", cli_child_exit_code(&c), c.err);
    assert_int_equal(cli_child_exit_code(&c), 1);
    assert_non_null(strstr(c.err, "allow_large needs root"));
    assert_int_equal(harness_count_captures(&H), 0);
    harness_stop(&H);
}

static void test_allow_large_lifts_the_limits_for_root(void **state)
{
    harness_require_root("be the daemon's admin");
    start();
    hconn w;
    hconn_open(&w, &H);
    json_decref(hconn_request(&w, "watch", NULL));
    cli_child c;
    cli_child_run(&c, scicap,
                  (const char *const[]){"capture", "--socket", H.sock, "--from", file, "--allow-large", NULL}, H.dir);
    print_message("  root with --allow-large: exit %d; %s", cli_child_exit_code(&c), c.out);
    assert_int_equal(cli_child_exit_code(&c), 0);
    json_t *e = hconn_wait_event(&w, "import.stored", 60000); /* an import.failed first fails the test */
    json_int_t job = json_integer_value(json_object_get(e, "job"));
    json_decref(e);
    json_decref(hconn_request(&w, "cancel", json_pack("{s:I}", "job", job)));
    e = hconn_wait_event_ex(&w, "import.canceled", 60000, 1);
    json_decref(e);
    int n = harness_count_captures(&H);
    print_message("  %d captures stored before the cancel\n", n);
    assert_true(n >= 1);
    hconn_close(&w);
    harness_stop(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_without_allow_large_refused, cleanup),
        cmocka_unit_test_teardown(test_allow_large_refused_to_a_user, cleanup),
        cmocka_unit_test_teardown(test_allow_large_lifts_the_limits_for_root, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
