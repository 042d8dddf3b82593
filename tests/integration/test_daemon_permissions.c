/* Who is an admin of scicapd (docs/permissions.md), over its real Unix socket with real peer credentials:
 *  - by default reaching the socket does not make a user an admin: a peer in the socket's group is refused
 *    reload, shutdown and the cancel of another uid's job, and the refusal names the admin group scicap-admin,
 *    which is not the socket's group;
 *  - a peer whose group is control.admin_group may reload and cancel another uid's job;
 *  - root is always an admin, also with no admin group;
 *  - a configuration that makes the admin group the socket's group is warned about at start.
 * Other identities are taken with seteuid/setegid around connect(): SO_PEERCRED records the effective ids at
 * connect. That needs root; without it the tests say so and skip. */
#include <errno.h>
#include <grp.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "tests/integration/daemon_harness.h"

#define NOBODY 65534

static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

/* gid of an existing group (the tests need two that every Debian system has) */
static gid_t group_gid(const char *name)
{
    struct group *g = getgrnam(name);
    if (!g)
        fail_msg("group %s does not exist on this system", name);
    return g->gr_gid;
}

/* the error message of a refused call, which must carry `code` (copied into msg) */
static void expect_refusal(hconn *c, const char *cmd, json_t *args, const char *code, char *msg, size_t n)
{
    json_t *m = hconn_call(c, cmd, args);
    json_t *e = json_object_get(m, "error");
    const char *got = json_string_value(json_object_get(e, "code"));
    if (json_is_true(json_object_get(m, "ok")) || !got || strcmp(got, code) != 0)
        fail_msg("%s: expected %s, got %s", cmd, code, json_dumps(m, JSON_COMPACT));
    snprintf(msg, n, "%s", json_string_value(json_object_get(e, "message")));
    json_decref(m);
}

/* a job of root's: one capture, not reconstructed; its job id */
static json_int_t root_job(void)
{
    hconn c;
    hconn_open(&c, &H);
    json_t *r = hconn_request(&c, "capture", json_pack("{s:b}", "reconstruct", 0));
    json_int_t job = json_integer_value(json_object_get(r, "job"));
    assert_true(job > 0);
    json_decref(r);
    hconn_close(&c);
    return job;
}

/* A daemon started with config, a job of root's in it, and c connected as NOBODY with primary group `group`:
 * the job's id. Skips without root. */
static json_int_t start_with_root_job(const char *config, const char *group, hconn *c)
{
    harness_require_root("connect as other uids (seteuid)");
    gid_t gid = group_gid(group);
    harness_start_open(&H, config);
    json_int_t job = root_job();
    hconn_open_as(c, &H, NOBODY, gid);
    return job;
}

static void test_socket_group_is_not_admin_by_default(void **state)
{
    hconn c;
    json_int_t job = start_with_root_job("{\"control\": {\"mode\": \"0666\", \"group\": \"users\"}}\n", "users", &c);
    char msg[512];
    expect_refusal(&c, "reload", NULL, "permission", msg, sizeof msg);
    print_message("  reload by uid %d (group users, the socket's): %s\n", NOBODY, msg);
    if (!strstr(msg, "\"scicap-admin\""))
        fail_msg("the refusal does not name the admin group scicap-admin: %s", msg);
    expect_refusal(&c, "shutdown", NULL, "permission", msg, sizeof msg);
    expect_refusal(&c, "cancel", json_pack("{s:I}", "job", job), "permission", msg, sizeof msg);
    print_message("  cancel of root's job %lld: %s\n", (long long)job, msg);
    /* the daemon is still there and answers */
    json_decref(hconn_request(&c, "status", NULL));
    hconn_close(&c);
    harness_stop(&H);
}

static void test_admin_group_member_is_admin(void **state)
{
    hconn c;
    json_int_t job = start_with_root_job(
        "{\"control\": {\"mode\": \"0666\", \"group\": \"users\", \"admin_group\": \"adm\"}}\n", "adm", &c);
    json_decref(hconn_request(&c, "reload", NULL));
    json_t *r = hconn_request(&c, "cancel", json_pack("{s:I}", "job", job));
    print_message("  uid %d in group adm: reload ok, cancel of root's job %lld -> state %s\n", NOBODY,
                  (long long)job, json_string_value(json_object_get(r, "state")));
    json_decref(r);
    hconn_close(&c);
    /* the same uid through the socket's group only: refused */
    hconn_open_as(&c, &H, NOBODY, group_gid("users"));
    char msg[512];
    expect_refusal(&c, "reload", NULL, "permission", msg, sizeof msg);
    hconn_close(&c);
    harness_stop(&H);
}

static void test_root_is_always_admin(void **state)
{
    harness_require_root("connect as other uids (seteuid)");
    harness_start_open(&H, "{\"control\": {\"mode\": \"0666\", \"admin_group\": \"\"}}\n");
    hconn c;
    hconn_open(&c, &H);
    json_decref(hconn_request(&c, "reload", NULL));
    hconn_close(&c);
    harness_stop(&H);
}

static void test_warns_when_admin_group_is_socket_group(void **state)
{
    harness_start_open(&H, "{\"control\": {\"mode\": \"0666\", \"group\": \"users\", \"admin_group\": \"users\"}}\n");
    harness_stop(&H);
    FILE *f = fopen(H.log, "r");
    assert_non_null(f);
    char line[1024];
    int warned = 0;
    while (fgets(line, sizeof line, f))
        warned |= strstr(line, "control.admin_group is the socket's group") != NULL;
    fclose(f);
    assert_true(warned);
    /* and the default is silent */
    harness_cleanup(&H);
    harness_start_open(&H, "{\"control\": {\"mode\": \"0666\", \"group\": \"users\"}}\n");
    harness_stop(&H);
    f = fopen(H.log, "r");
    assert_non_null(f);
    warned = 0;
    while (fgets(line, sizeof line, f))
        warned |= strstr(line, "control.admin_group is the socket's group") != NULL;
    fclose(f);
    assert_false(warned);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_socket_group_is_not_admin_by_default, cleanup),
        cmocka_unit_test_teardown(test_admin_group_member_is_admin, cleanup),
        cmocka_unit_test_teardown(test_root_is_always_admin, cleanup),
        cmocka_unit_test_teardown(test_warns_when_admin_group_is_socket_group, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
