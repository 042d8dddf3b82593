/* The daemon's import holds a file to the limits `scicap recon` holds it to (io/limits.h): a small compressed
 * .mat declaring 5,000 snapshots of 8×8 pixels, 8 frames each (a few KB), is refused by `scicap recon` ("would
 * create N files") and by the daemon's import with the same figure, before one capture is stored; lifting the
 * limits (allow_large) is for admins only — another uid asking for it gets `permission`. */
#include <errno.h>
#include <matio.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <dirent.h>
#include <sys/socket.h>

#include <cmocka.h>

#include "tests/helpers/cli_child.h"
#include "tests/helpers/testfiles.h"
#include "tests/integration/daemon_harness.h"

#define NOBODY 65534
#define SNAPSHOTS 5000

static harness H;
static char file[600];

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

static void test_refused_as_the_cli_refuses_it(void **state)
{
    harness_start(&H, "{\"control\": {\"mode\": \"0666\"}}\n", NULL);
    snprintf(file, sizeof file, "%s/many.mat", H.dir);
    testfiles_write_declared_mat(file, SNAPSHOTS);
    struct stat st;
    assert_int_equal(stat(file, &st), 0);
    /* the offline CLI */
    char scicap[1024], out[700];
    assert_int_equal(cli_child_program(scicap, sizeof scicap, "scicap"), 0);
    snprintf(out, sizeof out, "%s/out", H.dir);
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", file, "-o", out, NULL}, H.dir);
    print_message("  %lld-byte file; scicap recon: exit %d, %s", (long long)st.st_size, cli_child_exit_code(&c), c.err);
    assert_int_equal(cli_child_exit_code(&c), 1);
    const char *cli_fig = strstr(c.err, "would create ");
    assert_non_null(cli_fig);
    long cli_files = strtol(cli_fig + 13, NULL, 10);
    /* the daemon */
    hconn hc;
    hconn_open(&hc, &H);
    int fd = open(file, O_RDONLY | O_CLOEXEC);
    assert_true(fd >= 0);
    json_t *r = hconn_import_fds(&hc, json_pack("{s:[s], s:b}", "files", "many.mat", "reconstruct", 1), &fd, 1);
    close(fd);
    assert_true(json_is_true(json_object_get(r, "ok")));
    json_decref(r);
    json_t *e = hconn_wait_event_ex(&hc, "import.failed", 60000, 1);
    const char *msg = json_string_value(json_object_get(json_object_get(e, "data"), "error"));
    print_message("  daemon: %s\n", msg);
    const char *fig = strstr(msg, "would create ");
    assert_non_null(fig);
    assert_int_equal(strtol(fig + 13, NULL, 10), cli_files);
    assert_non_null(strstr(msg, "many.mat"));
    json_decref(e);
    assert_int_equal(harness_count_captures(&H), 0);
    hconn_close(&hc);
    harness_stop(&H);
}

static void test_allow_large_is_for_admins(void **state)
{
    harness_require_root("connect as uid 65534 (seteuid)");
    harness_start_open(&H, "{\"control\": {\"mode\": \"0666\"}}\n");
    snprintf(file, sizeof file, "%s/many.mat", H.dir);
    testfiles_write_declared_mat(file, SNAPSHOTS);
    hconn hc;
    hconn_open_as(&hc, &H, NOBODY, NOBODY);
    int fd = open(file, O_RDONLY | O_CLOEXEC);
    assert_true(fd >= 0);
    json_t *r = hconn_import_fds(&hc, json_pack("{s:[s], s:b}", "files", "many.mat", "allow_large", 1), &fd, 1);
    close(fd);
    const char *code = json_string_value(json_object_get(json_object_get(r, "error"), "code"));
    print_message("  uid %d with allow_large: %s\n", NOBODY, json_dumps(r, JSON_COMPACT));
    assert_false(json_is_true(json_object_get(r, "ok")));
    assert_string_equal(code, "permission");
    json_decref(r);
    hconn_close(&hc);
    assert_int_equal(harness_count_captures(&H), 0);
    harness_stop(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_refused_as_the_cli_refuses_it, cleanup),
        cmocka_unit_test_teardown(test_allow_large_is_for_admins, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
