/* The web view's parts without a daemon: the "web" configuration section (off when absent, numeric addresses
 * only, ports in range, restart needed when it changes) and the event ring behind /api/events (order, keep-alive,
 * the reset sent to a stream that fell behind, end of stream at close). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <jansson.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "daemon/config.h"
#include "daemon/web_events.h"

static scicapd_config *load(const char *text, int expect_ok, const char *expect_in_error)
{
    scicapd_config *c = NULL;
    sci_error err = {0};
    int rc = scicapd_config_load_string(&c, "scicapd.json", text, &err);
    if (expect_ok) {
        if (rc < 0)
            fail_msg("refused: %s", err.msg);
        return c;
    }
    assert_true(rc < 0);
    printf("  refused: %s\n", err.msg);
    assert_non_null(strstr(err.msg, expect_in_error));
    return NULL;
}

static void config_web_off_by_default(void **s)
{
    (void)s;
    scicapd_config *c = load("{\"version\": 1}", 1, NULL);
    assert_int_equal(c->web_enabled, 0);
    assert_string_equal(c->web_host, "127.0.0.1");
    assert_int_equal(c->web_control, 0);
    scicapd_config_free(c);
    c = load("{\"web\": {}}", 1, NULL); /* the section alone turns it on, on loopback, read-only */
    assert_int_equal(c->web_enabled, 1);
    assert_string_equal(c->web_host, "127.0.0.1");
    assert_int_equal(c->web_port, 8080);
    assert_int_equal(c->web_control, 0);
    scicapd_config_free(c);
    c = load("{\"web\": {\"enabled\": false, \"listen\": \"0.0.0.0:80\"}}", 1, NULL);
    assert_int_equal(c->web_enabled, 0);
    scicapd_config_free(c);
}

static void config_web_listen(void **s)
{
    (void)s;
    scicapd_config *c = load("{\"web\": {\"listen\": \"[::1]:9000\", \"control\": true, \"token_file\": "
                             "\"/run/x/web.token\", \"timeout_s\": 5, \"max_connections\": 8}}", 1, NULL);
    assert_string_equal(c->web_host, "::1");
    assert_int_equal(c->web_port, 9000);
    assert_int_equal(c->web_control, 1);
    assert_int_equal(c->web_timeout_s, 5);
    assert_int_equal(c->web_max_connections, 8);
    scicapd_config_free(c);
    load("{\"web\": {\"listen\": \"localhost:8080\"}}", 0, "web.listen");   /* a name, never resolved */
    load("{\"web\": {\"listen\": \"127.0.0.1\"}}", 0, "web.listen");        /* no port */
    load("{\"web\": {\"listen\": \"127.0.0.1:70000\"}}", 0, "web.listen");
    load("{\"web\": {\"listen\": \"127.0.0.1:80x\"}}", 0, "web.listen");
    load("{\"web\": {\"listen\": \"::1:8080\"}}", 0, "web.listen");         /* IPv6 without brackets */
    load("{\"web\": {\"listen\": \"[::1:8080\"}}", 0, "web.listen");
    load("{\"web\": {\"token_file\": \"web.token\"}}", 0, "web.token_file");
    load("{\"web\": {\"max_connections\": 1}}", 0, "web.max_connections");
    load("{\"web\": {\"port\": 8080}}", 0, "port");                         /* unknown key */
}

static void config_web_needs_restart(void **s)
{
    (void)s;
    scicapd_config *a = load("{}", 1, NULL), *b = load("{\"web\": {}}", 1, NULL);
    json_t *keys = scicapd_config_restart_keys(a, b);
    int found = 0;
    for (size_t i = 0; i < json_array_size(keys); i++)
        found |= strcmp(json_string_value(json_array_get(keys, i)), "web") == 0;
    assert_true(found);
    json_decref(keys);
    scicapd_config_free(a);
    scicapd_config_free(b);
}

/* Everything the stream has ready, up to one block (each read returns at most one formatted event). */
static void read_text(web_stream *st, char *out, size_t n)
{
    ssize_t r = web_stream_read(st, out, n - 1);
    assert_true(r > 0);
    out[r] = '\0';
}

/* A ring of `cap` events and one stream on it (keep-alive after keepalive_ms), its opening comment read. */
static web_stream *stream_opened(web_events **ev, int cap, int keepalive_ms)
{
    assert_int_equal(web_events_new(ev, cap), 0);
    web_stream *st = web_stream_new(*ev, keepalive_ms);
    char buf[256];
    read_text(st, buf, sizeof buf);
    assert_non_null(strstr(buf, ": scicapd events"));
    return st;
}

static void events_in_order_then_reset(void **s)
{
    (void)s;
    web_events *ev;
    web_stream *st = stream_opened(&ev, 4, 100);
    char buf[256];
    web_events_push(ev, "{\"event\": \"a\"}\n");
    web_events_push(ev, "{\"event\": \"b\"}");
    read_text(st, buf, sizeof buf);
    assert_string_equal(buf, "id: 1\ndata: {\"event\": \"a\"}\n\n");
    read_text(st, buf, sizeof buf);
    assert_string_equal(buf, "id: 2\ndata: {\"event\": \"b\"}\n\n");
    read_text(st, buf, sizeof buf); /* nothing new within 100 ms: a keep-alive comment */
    assert_string_equal(buf, ": k\n\n");
    for (int i = 0; i < 10; i++) /* more than the ring keeps, unread */
        web_events_push(ev, "{\"event\": \"x\"}");
    read_text(st, buf, sizeof buf);
    assert_non_null(strstr(buf, "event: reset"));
    web_events_push(ev, "{\"event\": \"c\"}");
    read_text(st, buf, sizeof buf);
    assert_string_equal(buf, "id: 13\ndata: {\"event\": \"c\"}\n\n");
    /* a read handed a small buffer gets the event in pieces */
    web_events_push(ev, "{\"event\": \"d\"}");
    char part[8];
    ssize_t r = web_stream_read(st, part, sizeof part);
    assert_int_equal(r, (ssize_t)sizeof part);
    assert_memory_equal(part, "id: 14\nd", 8);
    web_stream_free(st);
    web_events_free(ev);
}

static void *close_later(void *ev)
{
    usleep(100000);
    web_events_close(ev);
    return NULL;
}

static void events_close_ends_streams(void **s)
{
    (void)s;
    web_events *ev;
    web_stream *st = stream_opened(&ev, 8, 60000);
    char buf[64];
    pthread_t t;
    pthread_create(&t, NULL, close_later, ev);
    assert_int_equal(web_stream_read(st, buf, sizeof buf), -1); /* woken by the close, not by the 60 s */
    pthread_join(t, NULL);
    web_stream_free(st);
    web_events_free(ev);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(config_web_off_by_default), cmocka_unit_test(config_web_listen),
        cmocka_unit_test(config_web_needs_restart),  cmocka_unit_test(events_in_order_then_reset),
        cmocka_unit_test(events_close_ends_streams),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
