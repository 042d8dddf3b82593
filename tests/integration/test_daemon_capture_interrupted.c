/* A capture job running when the daemon is killed (kill -9) is not lost silently: at the next start the daemon
 * logs it and status reports it under recovered.capture_interrupted (its job, owner and the snapshots asked), once;
 * the snapshots stored before the kill stay. A capture that ends normally leaves no such report. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "tests/integration/daemon_harness.h"

static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

static json_t *interrupted(void)
{
    hconn c;
    hconn_open(&c, &H);
    json_t *r = hconn_request(&c, "status", NULL);
    json_t *i = json_incref(json_object_get(json_object_get(r, "recovered"), "capture_interrupted"));
    json_decref(r);
    hconn_close(&c);
    return i;
}

static void test_kill9_during_capture_reported(void **state)
{
    harness_start(&H, NULL, NULL);
    hconn c;
    hconn_open(&c, &H);
    /* one that ends: nothing to report */
    json_decref(hconn_request(&c, "capture", json_pack("{s:i, s:b}", "count", 1, "reconstruct", 0)));
    json_decref(hconn_wait_event(&c, "capture.done", 60000));
    json_t *r = hconn_request(&c, "capture", json_pack("{s:i, s:b}", "count", 200, "reconstruct", 0));
    json_int_t job = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    json_decref(hconn_wait_event(&c, "capture.stored", 60000));
    hconn_close(&c);
    harness_kill9(&H);
    harness_spawn(&H, NULL);
    json_t *i = interrupted();
    char *s = json_dumps(i, JSON_COMPACT);
    print_message("  after kill -9 during job %lld: recovered.capture_interrupted = %s\n", (long long)job, s);
    free(s);
    assert_true(json_is_object(i));
    assert_int_equal(json_integer_value(json_object_get(i, "job")), job);
    assert_int_equal(json_integer_value(json_object_get(i, "owner")), (json_int_t)geteuid());
    assert_int_equal(json_integer_value(json_object_get(i, "count")), 200);
    json_decref(i);
    /* reported once: a clean restart has nothing to say */
    harness_stop(&H);
    harness_spawn(&H, NULL);
    i = interrupted();
    assert_true(json_is_null(i));
    json_decref(i);
    harness_stop(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_kill9_during_capture_reported, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
