/* A full disk during a capture (storage on a small tmpfs): the capture stops at the first snapshot that cannot be
 * stored — it does not go on acquiring the rest to lose them too — and capture.failed names the errno ("No space
 * left on device"). Counted, not timed: the snapshots the capture acquired before the next capture starts (the
 * acquisition thread runs one capture at a time, and one connection's events come in order). Needs root (mount). */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "tests/integration/daemon_harness.h"

#define COUNT 200

static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H); /* unmounts the store's tmpfs */
    memset(&H, 0, sizeof H);
    return 0;
}

static void test_capture_stops_at_enospc(void **state)
{
    harness_require_root("mount a small tmpfs");
    harness_init(&H, NULL);
    harness_mount_store(&H, "1m");
    harness_spawn(&H, NULL);
    hconn c;
    hconn_open(&c, &H);
    json_t *r = hconn_request(&c, "capture", json_pack("{s:i, s:b}", "count", COUNT, "reconstruct", 0));
    json_int_t job = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    int stored = 0, acquired = 0, failed = 0, second = 0;
    char why[512] = "";
    while (!second) {
        json_t *m = hconn_read(&c, 120000);
        if (!m)
            fail_msg("no event within 120 s (%d acquired, %d stored, %d failed)", acquired, stored, failed);
        const char *ev = json_string_value(json_object_get(m, "event"));
        json_int_t mj = json_integer_value(json_object_get(m, "job"));
        if (ev && mj == job && !strcmp(ev, "capture.snapshot"))
            acquired++;
        else if (ev && mj == job && !strcmp(ev, "capture.stored"))
            stored++;
        else if (ev && mj == job && !strcmp(ev, "capture.failed")) {
            if (!failed++)
                snprintf(why, sizeof why, "%s",
                         json_string_value(json_object_get(json_object_get(m, "data"), "error")));
            if (failed == 1) { /* a second capture: its start marks the end of the first's acquisition */
                json_t *req = json_pack("{s:i, s:i, s:s, s:{s:i, s:b}}", "v", 1, "id", 99, "cmd", "capture", "args",
                                        "count", 1, "reconstruct", 0);
                char *s = json_dumps(req, JSON_COMPACT);
                hconn_send_raw(&c, s, strlen(s));
                hconn_send_raw(&c, "\n", 1);
                free(s);
                json_decref(req);
            }
        } else if (ev && mj != job && !strcmp(ev, "capture.started"))
            second = 1;
        json_decref(m);
    }
    print_message("  tmpfs of 1 MiB: %d of %d snapshots acquired, %d stored, %d failed; first error: %s\n",
                  acquired, COUNT, stored, failed, why);
    assert_true(failed >= 1);
    assert_non_null(strstr(why, "No space left on device"));
    assert_true(acquired < COUNT);
    /* at most the snapshots already on their way to the writers when the first failed */
    assert_true(acquired - stored <= 16);
    hconn_close(&c);
    harness_stop(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_capture_stops_at_enospc, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
