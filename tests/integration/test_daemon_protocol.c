/* scicapd's control protocol over the real socket: every bad request (malformed, oversized, wrong version,
 * unknown command, bad arguments) is answered with an error carrying the request id while the daemon keeps
 * serving; the bounded queue answers busy; too many clients are refused; 20 concurrent clients with mixed
 * requests all get their answers. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <pthread.h>

#include "tests/integration/daemon_harness.h"

static harness H;

static int setup(void **state)
{
    (void)state;
    harness_start(&H, "{\"control\": {\"max_clients\": 24, \"max_line_bytes\": 4096},"
                      " \"queues\": {\"capture\": 2, \"reconstruction\": 4}}\n", NULL);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    harness_stop(&H);
    harness_cleanup(&H);
    return 0;
}

/* Send a raw line; expect an error reply with `code` and the given id (json text, "null" for none). */
static void expect_raw(hconn *c, const char *line, const char *code, const char *id_json)
{
    hconn_send_raw(c, line, strlen(line));
    json_t *m = hconn_read(c, 10000);
    if (!m)
        fail_msg("no answer to %s", line);
    char *s = json_dumps(m, JSON_COMPACT);
    const char *got = json_string_value(json_object_get(json_object_get(m, "error"), "code"));
    if (json_is_true(json_object_get(m, "ok")) || !got || strcmp(got, code) != 0)
        fail_msg("%.80s: expected %s, got %s", line, code, s);
    json_t *want = json_loads(id_json, JSON_DECODE_ANY, NULL);
    if (!json_equal(json_object_get(m, "id"), want))
        fail_msg("%.80s: reply id is not %s: %s", line, id_json, s);
    printf("  %-10.60s -> %s: %s\n", line, code,
           json_string_value(json_object_get(json_object_get(m, "error"), "message")));
    json_decref(want);
    free(s);
    json_decref(m);
}

static void still_serving(hconn *c)
{
    json_t *r = hconn_request(c, "status", NULL);
    assert_int_equal(json_integer_value(json_object_get(r, "protocol")), 1);
    json_decref(r);
}

static void bad_requests_answered(void **state)
{
    (void)state;
    hconn c;
    hconn_open(&c, &H);
    expect_raw(&c, "this is not json\n", "bad_json", "null");
    still_serving(&c);
    expect_raw(&c, "[1, 2, 3]\n", "bad_json", "null");
    expect_raw(&c, "{\"v\": 1, \"id\": 5, \"cmd\": \"status\"\n", "bad_json", "null");
    expect_raw(&c, "{\"v\": 2, \"id\": 6, \"cmd\": \"status\"}\n", "bad_version", "6");
    expect_raw(&c, "{\"v\": 1, \"id\": \"abc\", \"cmd\": \"selfdestruct\"}\n", "unknown_command", "\"abc\"");
    expect_raw(&c, "{\"v\": 1, \"id\": 8}\n", "unknown_command", "8");
    expect_raw(&c, "{\"v\": 1, \"id\": 9, \"cmd\": \"capture\", \"args\": {\"count\": -3}}\n", "bad_arguments", "9");
    expect_raw(&c, "{\"v\": 1, \"id\": 10, \"cmd\": \"capture\", \"args\": {\"cuont\": 3}}\n", "bad_arguments", "10");
    expect_raw(&c, "{\"v\": 1, \"id\": 11, \"cmd\": \"capture\", \"args\": {\"mask_set\": \"nope\"}}\n", "bad_arguments",
               "11");
    expect_raw(&c, "{\"v\": 1, \"id\": 12, \"cmd\": \"reconstruct\", \"args\": {\"capture\": \"c999999\"}}\n",
               "not_found", "12");
    expect_raw(&c, "{\"v\": 1, \"id\": 13, \"cmd\": \"cancel\", \"args\": {\"job\": 424242}}\n", "not_found", "13");
    expect_raw(&c, "{\"v\": 1, \"id\": 14, \"cmd\": \"status\", \"extra\": 1}\n", "bad_json", "14");
    expect_raw(&c, "{\"v\": 1, \"id\": 15, \"cmd\": \"status\", \"args\": {\"x\": 1}}\n", "bad_arguments", "15");
    expect_raw(&c, "{\"v\": 1, \"id\": 16, \"cmd\": \"capture\", \"args\": {\"sync_mode\": \"moon-master\"}}\n",
               "bad_arguments", "16");
    /* oversized: 10 000 bytes on one line, limit 4096 */
    size_t n = 10000;
    char *big = malloc(n + 2);
    memset(big, 'x', n);
    memcpy(big, "{\"v\": 1, \"id\": 17, \"cmd\": \"status\", \"pad\": \"", 44);
    big[n] = '\n';
    big[n + 1] = '\0';
    expect_raw(&c, big, "too_long", "null");
    free(big);
    still_serving(&c);
    /* a binary mess, then a good request on the same connection */
    const char junk[] = "\x01\x02\xff\xfe{{{\n";
    expect_raw(&c, junk, "bad_json", "null");
    still_serving(&c);
    hconn_close(&c);
}

static void full_queue_answers_busy(void **state)
{
    (void)state;
    hconn c;
    hconn_open(&c, &H);
    /* slow the acquisition so that the queue of 2 fills */
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s, s:i}", "fault", "acquire-delay", "n", 300)));
    int accepted = 0, busy = 0;
    for (int i = 0; i < 8; i++) {
        json_t *m = hconn_call(&c, "capture", NULL);
        if (json_is_true(json_object_get(m, "ok")))
            accepted++;
        else if (!strcmp(json_string_value(json_object_get(json_object_get(m, "error"), "code")), "busy"))
            busy++;
        json_decref(m);
    }
    printf("  8 captures: %d accepted, %d busy\n", accepted, busy);
    assert_true(busy >= 1);
    assert_true(accepted >= 2);
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s, s:i}", "fault", "acquire-delay", "n", 0)));
    /* every accepted capture finishes: nothing accepted is dropped */
    for (int i = 0; i < accepted; i++)
        json_decref(hconn_wait_event(&c, "capture.done", 30000));
    hconn_close(&c);
}

typedef struct worker_arg {
    int index;
    int ok, errors;
    char fail[256];
} worker_arg;

static void *client_thread(void *p)
{
    worker_arg *w = p;
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", H.sock);
    int fd = h_connect_raw(H.sock);
    if (fd < 0) {
        snprintf(w->fail, sizeof w->fail, "connect failed");
        return NULL;
    }
    static const char *const cmds[] = {"status", "jobs", "devices", "capture", "bogus", "status"};
    FILE *in = fdopen(dup(fd), "r");
    for (int i = 0; i < 6; i++) {
        int which = (w->index + i) % 6;
        char line[200];
        snprintf(line, sizeof line, "{\"v\":1,\"id\":%d,\"cmd\":\"%s\"}\n", w->index * 100 + i, cmds[which]);
        if (send(fd, line, strlen(line), MSG_NOSIGNAL) < 0)
            break;
        char *buf = NULL;
        size_t cap = 0;
        for (;;) {
            if (getline(&buf, &cap, in) <= 0) {
                snprintf(w->fail, sizeof w->fail, "connection closed waiting for %s", cmds[which]);
                free(buf);
                goto out;
            }
            json_t *m = json_loads(buf, 0, NULL);
            if (m && !json_object_get(m, "event")) {
                if (json_integer_value(json_object_get(m, "id")) != w->index * 100 + i)
                    snprintf(w->fail, sizeof w->fail, "reply with the wrong id");
                if (json_is_true(json_object_get(m, "ok")))
                    w->ok++;
                else
                    w->errors++;
                json_decref(m);
                break;
            }
            json_decref(m);
        }
        free(buf);
    }
out:
    fclose(in);
    close(fd);
    return NULL;
}

static void twenty_concurrent_clients(void **state)
{
    (void)state;
    pthread_t t[20];
    worker_arg a[20];
    for (int i = 0; i < 20; i++) {
        a[i] = (worker_arg){.index = i};
        pthread_create(&t[i], NULL, client_thread, &a[i]);
    }
    int ok = 0, errors = 0;
    for (int i = 0; i < 20; i++) {
        pthread_join(t[i], NULL);
        if (a[i].fail[0])
            fail_msg("client %d: %s", i, a[i].fail);
        ok += a[i].ok;
        errors += a[i].errors;
    }
    printf("  20 clients x 6 requests: %d ok, %d errors (unknown commands and busy captures)\n", ok, errors);
    assert_int_equal(ok + errors, 120);
    assert_true(errors >= 20); /* every client sent one unknown command */
    hconn c;
    hconn_open(&c, &H);
    still_serving(&c);
    hconn_close(&c);
}

static void too_many_clients_refused(void **state)
{
    (void)state;
    hconn c[25];
    for (int i = 0; i < 24; i++)
        hconn_open(&c[i], &H);
    h_sleep_ms(200);
    hconn_open(&c[24], &H);
    json_t *m = hconn_read(&c[24], 5000);
    assert_non_null(m);
    assert_string_equal(json_string_value(json_object_get(json_object_get(m, "error"), "code")), "busy");
    json_decref(m);
    for (int i = 0; i < 25; i++)
        hconn_close(&c[i]);
    h_sleep_ms(200);
    hconn d;
    hconn_open(&d, &H);
    still_serving(&d);
    hconn_close(&d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(bad_requests_answered),
        cmocka_unit_test(full_queue_answers_busy),
        cmocka_unit_test(twenty_concurrent_clients),
        cmocka_unit_test(too_many_clients_refused),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
