/* One user's connections cannot lock the others out (docs/protocol.md, Connections):
 *  - an ordinary uid holds at most control.max_per_uid connections (here 4): its watches beyond that get one
 *    "busy" line naming the cap, while another uid and root still get in;
 *  - `scicap status` refused that way prints the daemon's reason, not "write failed: Broken pipe";
 *  - a watcher that stops reading is dropped once its output has waited control.stall_timeout_ms (here 1 s)
 *    unread, and its slot is free again.
 * Other uids are taken with seteuid/setegid around connect() (SO_PEERCRED records them), which needs root. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "tests/helpers/cli_child.h"
#include "tests/integration/daemon_harness.h"

static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

static void test_per_uid_cap(void **state)
{
    harness_require_root("connect as other uids (seteuid)");
    harness_start_open(&H, "{\"control\": {\"mode\": \"0666\", \"max_per_uid\": 4}}\n");
    hconn w[4];
    for (int i = 0; i < 4; i++) {
        hconn_open_as(&w[i], &H, HARNESS_UID_A, HARNESS_UID_A);
        json_decref(hconn_request(&w[i], "watch", NULL));
    }
    /* the fifth of uid A: busy, naming the cap */
    hconn x;
    hconn_open_as(&x, &H, HARNESS_UID_A, HARNESS_UID_A);
    json_t *m = hconn_read(&x, 5000);
    assert_non_null(m);
    const char *code = json_string_value(json_object_get(json_object_get(m, "error"), "code"));
    const char *msg = json_string_value(json_object_get(json_object_get(m, "error"), "message"));
    print_message("  5th connection of uid %d: %s: %s\n", HARNESS_UID_A, code, msg);
    assert_string_equal(code, "busy");
    assert_non_null(strstr(msg, "max_per_uid"));
    json_decref(m);
    hconn_close(&x);
    /* the CLI, refused the same way, says why */
    char scicap[1024];
    assert_int_equal(cli_child_program(scicap, sizeof scicap, "scicap"), 0);
    char cmd[3000], out[400];
    snprintf(out, sizeof out, "%s/cli.err", H.dir);
    snprintf(cmd, sizeof cmd, "setpriv --reuid %d --regid %d --clear-groups %s status --socket %s 2> %s", HARNESS_UID_A,
             HARNESS_UID_A, scicap, H.sock, out);
    int st = system(cmd);
    FILE *f = fopen(out, "r");
    assert_non_null(f);
    char err[2048] = "";
    size_t n = fread(err, 1, sizeof err - 1, f);
    err[n] = '\0';
    fclose(f);
    print_message("  scicap status as uid %d: exit %d, stderr: %s", HARNESS_UID_A, WEXITSTATUS(st), err);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) != 0);
    assert_null(strstr(err, "Broken pipe"));
    assert_non_null(strstr(err, "max_per_uid"));
    /* another uid and root get in */
    hconn b;
    hconn_open_as(&b, &H, HARNESS_UID_B, HARNESS_UID_B);
    json_decref(hconn_request(&b, "status", NULL));
    hconn_close(&b);
    hconn r;
    hconn_open(&r, &H);
    json_decref(hconn_request(&r, "status", NULL));
    hconn_close(&r);
    /* one of A's closes: A may connect again */
    hconn_close(&w[0]);
    h_sleep_ms(200);
    hconn_open_as(&w[0], &H, HARNESS_UID_A, HARNESS_UID_A);
    json_decref(hconn_request(&w[0], "status", NULL));
    for (int i = 0; i < 4; i++)
        hconn_close(&w[i]);
    harness_stop(&H);
}

/* Bytes the daemon has queued to fd that we have not read (SIOCINQ on our side). */
static void test_stalled_watcher_dropped(void **state)
{
    harness_start(&H, "{\"control\": {\"stall_timeout_ms\": 1000}}\n", NULL);
    hconn w, c;
    hconn_open(&w, &H);
    json_decref(hconn_request(&w, "watch", NULL));
    /* w stops reading; captures make events until its socket is full and output waits in the daemon */
    hconn_open(&c, &H);
    int dropped = 0, captures = 0;
    int64_t t0 = h_now_ms();
    while (!dropped && h_now_ms() - t0 < 120000) {
        json_decref(hconn_request(&c, "capture", json_pack("{s:b}", "reconstruct", 0)));
        captures++;
        json_decref(hconn_wait_event(&c, "capture.stored", 60000));
        /* dropped: the daemon closed w, which reads as EOF after the queued bytes */
        struct pollfd p = {.fd = w.fd, .events = POLLIN};
        if (poll(&p, 1, 0) == 1 && (p.revents & POLLHUP))
            dropped = 1;
    }
    print_message("  a watcher that stopped reading was %s after %d captures (stall timeout 1000 ms)\n",
                  dropped ? "dropped" : "NOT dropped", captures);
    assert_true(dropped);
    /* the daemon says why in its log */
    FILE *f = fopen(H.log, "r");
    assert_non_null(f);
    char line[1024];
    int said = 0;
    while (fgets(line, sizeof line, f))
        said |= strstr(line, "unread for 1000 ms") != NULL;
    fclose(f);
    assert_true(said);
    hconn_close(&w);
    hconn_close(&c);
    harness_stop(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_per_uid_cap, cleanup),
        cmocka_unit_test_teardown(test_stalled_watcher_dropped, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
