/* `scicap status` and `scicap devices` for people (issue 18), and --json for programs: against a real scicapd on
 * the simulated bench, the tables carry the values of the daemon's own JSON reply (pid, queues, job counts, each
 * device's backend, state and identity fields, the per-stage timing of issue 17), no JSON syntax; --json prints
 * the reply as it came (parsed and compared with the one read on the socket). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "tests/helpers/daemon_child.h"
#include "tests/helpers/cli_child.h"

static harness H;
static char scicap[1024];

static void run_client(cli_child *c, const char *cmd, const char *json_flag)
{
    cli_child_run(c, scicap, (const char *const[]){cmd, "--socket", H.sock, json_flag, NULL}, H.dir);
    if (cli_child_exit_code(c) != 0)
        fail_msg("scicap %s exit %d: %s", cmd, cli_child_exit_code(c), c->err);
}

/* A line of `text` that starts with `head` (after spaces) and contains `value`. */
static void assert_line(const char *text, const char *head, const char *value)
{
    for (const char *l = text; l && *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : NULL) {
        const char *p = l;
        while (*p == ' ')
            p++;
        const char *end = strchr(p, '\n');
        size_t n = end ? (size_t)(end - p) : strlen(p);
        char line[512];
        snprintf(line, sizeof line, "%.*s", (int)(n < sizeof line ? n : sizeof line - 1), p);
        if (!strncmp(line, head, strlen(head)) && strstr(line, value))
            return;
    }
    fail_msg("no line starting \"%s\" with \"%s\" in:\n%s", head, value, text);
}

static void test_status_table_and_json(void **state)
{
    hconn c;
    hconn_open(&c, &H);
    /* something in the counters: one capture, reconstructed */
    json_decref(hconn_request(&c, "capture", json_pack("{s:b, s:s}", "reconstruct", 1, "preset", "fast")));
    json_decref(hconn_wait_event(&c, "recon.done", 60000));
    json_t *st = hconn_request(&c, "status", NULL);
    cli_child out;
    run_client(&out, "status", NULL);
    print_message("%s", out.out);
    assert_null(strchr(out.out, '{'));
    char v[64];
    snprintf(v, sizeof v, "pid %lld,", (long long)json_integer_value(json_object_get(st, "pid")));
    assert_line(out.out, "scicapd ", v);
    assert_line(out.out, "state", "ready");
    assert_line(out.out, "storage", H.store);
    json_t *q = json_object_get(json_object_get(st, "queues"), "reconstruction");
    snprintf(v, sizeof v, "reconstruction %lld/%lld", (long long)json_integer_value(json_array_get(q, 0)),
             (long long)json_integer_value(json_array_get(q, 1)));
    assert_line(out.out, "queues", v);
    snprintf(v, sizeof v, "%lld finished", (long long)json_integer_value(json_object_get(json_object_get(st, "jobs"),
                                                                                        "finished")));
    assert_line(out.out, "jobs", v);
    assert_line(out.out, "dmd", "connected");
    assert_line(out.out, "recon_solve", "ms CPU"); /* the stage counters */
    assert_line(out.out, "store", "runs");
    /* --json: the reply as it came */
    run_client(&out, "status", "--json");
    json_error_t je;
    json_t *j = json_loads(out.out, 0, &je);
    if (!j)
        fail_msg("scicap status --json: %s in:\n%s", je.text, out.out);
    assert_int_equal(json_integer_value(json_object_get(j, "pid")), json_integer_value(json_object_get(st, "pid")));
    assert_true(json_equal(json_object_get(j, "devices"), json_object_get(st, "devices")));
    assert_non_null(json_object_get(json_object_get(j, "timing"), "recon_write"));
    json_decref(j);
    json_decref(st);
    hconn_close(&c);
}

static void test_devices_table_and_json(void **state)
{
    hconn c;
    hconn_open(&c, &H);
    json_t *devs = hconn_request(&c, "devices", NULL);
    hconn_close(&c);
    cli_child out;
    run_client(&out, "devices", NULL);
    print_message("%s", out.out);
    assert_null(strchr(out.out, '{'));
    const char *name;
    json_t *d;
    int n = 0;
    json_object_foreach(devs, name, d) {
        assert_line(out.out, name, json_string_value(json_object_get(d, "backend")));
        n++;
    }
    assert_int_equal(n, 3);
    /* identities, flattened: every string field of the DMD and the camera's identity shows with its value */
    assert_line(out.out, "serial", json_string_value(json_object_get(json_object_get(devs, "dmd"), "serial")));
    assert_line(out.out, "model", json_string_value(json_object_get(json_object_get(devs, "dmd"), "model")));
    assert_line(out.out, "identity.card", json_string_value(json_object_get(
                                              json_object_get(json_object_get(devs, "camera"), "identity"), "card")));
    run_client(&out, "devices", "--json");
    json_error_t je;
    json_t *j = json_loads(out.out, 0, &je);
    if (!j)
        fail_msg("scicap devices --json: %s in:\n%s", je.text, out.out);
    assert_true(json_equal(j, devs));
    json_decref(j);
    json_decref(devs);
    /* jobs --json too */
    run_client(&out, "jobs", "--json");
    j = json_loads(out.out, 0, &je);
    assert_non_null(j);
    assert_true(json_is_array(json_object_get(j, "jobs")));
    json_decref(j);
}

static int setup(void **state) { return daemon_child_setup(&H, scicap, sizeof scicap, NULL); }
static int teardown(void **state) { return daemon_child_teardown(&H); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_status_table_and_json),
        cmocka_unit_test(test_devices_table_and_json),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
