/* The web view's defences, against the real scicapd on the simulated bench with web on 127.0.0.1 (docs/web.md):
 * off by default (no TCP socket listening at all); path traversal, raw and percent-encoded, refused; unknown
 * routes 404; control refused when off (403), and when on refused without the token (401) and with a wrong one
 * (403), accepted with it; oversized bodies, URLs and headers refused; a foreign Host refused; every response with its Content-Security-Policy and
 * nosniff; capture previews served and other files of the capture folder not; the event stream carries the
 * daemon's events; 50 connections held open half-sent while the control socket answers status and a capture is
 * stored, and the server drops them after its timeout. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <arpa/inet.h>
#include <dirent.h>
#include <netinet/in.h>

#include "recon/solver.h"
#include "tests/integration/daemon_harness.h"

#define SLOW_CONNECTIONS 50

typedef struct http_reply {
    int status;
    char head[8192];  /* status line and headers */
    char body[65536];
    size_t body_len;
} http_reply;

static int free_port(void)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    socklen_t n = sizeof a;
    assert_int_equal(getsockname(fd, (struct sockaddr *)&a, &n), 0);
    close(fd);
    return ntohs(a.sin_port);
}

static int tcp_connect(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port),
                            .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    if (fd < 0 || connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        if (fd >= 0)
            close(fd);
        return -1;
    }
    return fd;
}

static void send_all(int fd, const char *s, size_t n)
{
    while (n) {
        ssize_t w = send(fd, s, n, MSG_NOSIGNAL);
        if (w <= 0)
            return; /* the server may close on a refused request before reading all of it */
        s += w;
        n -= (size_t)w;
    }
}

/* Send `req` as is, read until the server closes (requests say Connection: close) or 10 s pass. */
static void http_raw(int port, const char *req, size_t len, http_reply *r)
{
    memset(r, 0, sizeof *r);
    int fd = tcp_connect(port);
    assert_true(fd >= 0);
    send_all(fd, req, len);
    char *buf = malloc(1 << 20);
    size_t n = 0;
    int64_t t0 = h_now_ms();
    while (n < (1 << 20) - 1 && h_now_ms() - t0 < 10000) {
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (poll(&p, 1, 200) <= 0)
            continue;
        ssize_t got = recv(fd, buf + n, (1 << 20) - 1 - n, 0);
        if (got <= 0)
            break;
        n += (size_t)got;
    }
    close(fd);
    buf[n] = '\0';
    char *end = strstr(buf, "\r\n\r\n");
    assert_non_null(end);
    size_t hl = (size_t)(end - buf);
    snprintf(r->head, sizeof r->head, "%.*s", (int)hl, buf);
    r->body_len = n - hl - 4 < sizeof r->body - 1 ? n - hl - 4 : sizeof r->body - 1;
    memcpy(r->body, end + 4, r->body_len);
    assert_int_equal(sscanf(buf, "HTTP/1.%*d %d", &r->status), 1);
    free(buf);
}

static void http_get(int port, const char *path, http_reply *r)
{
    char req[4096];
    int n = snprintf(req, sizeof req, "GET %s HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\n\r\n", path,
                     port);
    http_raw(port, req, (size_t)n, r);
}

static void http_post(int port, const char *path, const char *auth, const char *body, http_reply *r)
{
    char req[8192], a[256] = "";
    if (auth)
        snprintf(a, sizeof a, "Authorization: %s\r\n", auth);
    int n = snprintf(req, sizeof req, "POST %s HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\n%s"
                     "Content-Type: application/json\r\nContent-Length: %zu\r\n\r\n%s", path, port, a,
                     strlen(body), body);
    http_raw(port, req, (size_t)n, r);
}

static int header_has(const http_reply *r, const char *name, const char *value)
{
    char want[256];
    snprintf(want, sizeof want, "\r\n%s: ", name);
    const char *h = strcasestr(r->head, want);
    if (!h)
        return 0;
    const char *eol = strstr(h + 2, "\r\n");
    const char *v = strstr(h + strlen(want), value);
    return v && (!eol || v < eol);
}

/* Listening TCP sockets (IPv4 and IPv6) held by process pid: its socket inodes against /proc/net/tcp*. */
static int tcp_listeners(pid_t pid)
{
    char dir[64];
    snprintf(dir, sizeof dir, "/proc/%d/fd", (int)pid);
    unsigned long inodes[512];
    int ni = 0;
    DIR *d = opendir(dir);
    assert_non_null(d);
    struct dirent *e;
    while ((e = readdir(d)) && ni < 512) {
        char p[300], link[64];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        ssize_t n = readlink(p, link, sizeof link - 1);
        if (n <= 0)
            continue;
        link[n] = '\0';
        unsigned long ino;
        if (sscanf(link, "socket:[%lu]", &ino) == 1)
            inodes[ni++] = ino;
    }
    closedir(d);
    int count = 0;
    const char *tables[] = {"/proc/net/tcp", "/proc/net/tcp6"};
    for (int t = 0; t < 2; t++) {
        FILE *f = fopen(tables[t], "r");
        if (!f)
            continue;
        char line[512];
        while (fgets(line, sizeof line, f)) {
            unsigned st;
            unsigned long ino;
            if (sscanf(line, " %*d: %*s %*s %x %*s %*s %*s %*s %*s %lu", &st, &ino) != 2 || st != 0x0A)
                continue;
            for (int i = 0; i < ni; i++)
                count += inodes[i] == ino;
        }
        fclose(f);
    }
    return count;
}

/* ---- web off ---- */

static void off_by_default(void **s)
{
    (void)s;
    harness h;
    harness_start(&h, NULL, NULL);
    hconn c;
    hconn_open(&c, &h);
    json_decref(hconn_request(&c, "status", NULL));
    assert_int_equal(tcp_listeners(h.pid), 0);
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

/* ---- web on: one daemon for the rest ---- */

static harness H;
static int PORT;
static char TOKEN[128];

static int setup_web(void **s)
{
    (void)s;
    PORT = free_port();
    harness_init(&H, NULL);
    char cfg[1024];
    snprintf(cfg, sizeof cfg, "{\"version\": 1, \"web\": {\"listen\": \"127.0.0.1:%d\", \"control\": true, "
             "\"token_file\": \"%s/web.token\", \"timeout_s\": 3}}\n", PORT, H.dir);
    harness_write_config(&H, cfg);
    harness_spawn(&H, NULL);
    char path[400];
    snprintf(path, sizeof path, "%s/web.token", H.dir);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    assert_non_null(fgets(TOKEN, sizeof TOKEN, f));
    fclose(f);
    TOKEN[strcspn(TOKEN, "\n")] = '\0';
    assert_int_equal(strlen(TOKEN), 64);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    assert_int_equal(st.st_mode & 0777, 0640);
    return 0;
}

static int teardown_web(void **s)
{
    (void)s;
    harness_stop(&H);
    harness_cleanup(&H);
    return 0;
}

static void listens_and_serves_page(void **s)
{
    (void)s;
    assert_int_equal(tcp_listeners(H.pid), 1);
    http_reply r;
    http_get(PORT, "/", &r);
    assert_int_equal(r.status, 200);
    assert_true(header_has(&r, "Content-Security-Policy", "default-src 'self'"));
    assert_true(header_has(&r, "X-Content-Type-Options", "nosniff"));
    assert_non_null(strstr(r.body, "/assets/chart.min.js"));
    http_get(PORT, "/assets/chart.min.js", &r);
    assert_int_equal(r.status, 200);
    assert_true(header_has(&r, "Content-Type", "text/javascript"));
    http_get(PORT, "/api/state", &r);
    assert_int_equal(r.status, 200);
    assert_true(header_has(&r, "Content-Security-Policy", "default-src 'self'"));
    json_t *o = json_loadb(r.body, r.body_len, 0, NULL);
    assert_non_null(json_object_get(json_object_get(o, "status"), "devices"));
    assert_true(json_is_true(json_object_get(o, "control")));
    /* the control form's methods are the solver table's, in its order */
    size_t n = 0;
    const solver_ops *const *m = solver_list(&n);
    json_t *methods = json_object_get(o, "methods");
    assert_int_equal(json_array_size(methods), n);
    for (size_t i = 0; i < n; i++)
        assert_string_equal(json_string_value(json_object_get(json_array_get(methods, i), "name")), m[i]->name);
    json_decref(o);
}

static void traversal_refused(void **s)
{
    (void)s;
    static const char *const bad[] = {
        "/../etc/passwd", "/assets/../../etc/passwd", "/captures/../../../etc/passwd",
        "/%2e%2e/%2e%2e/etc/passwd", "/captures/%2e%2e/%2e%2e/etc/passwd", "/assets/..%2f..%2fetc%2fpasswd",
        "/captures/c000001%2f..%2f..%2fscicapd.json", "/captures/c000001/recon/..%2F..%2Fmeta.json",
        "/captures/c000001/..", "/captures/c000001/recon/gap-tv/../../meta.json", "/%2fetc%2fpasswd",
        "/captures//etc/passwd", "/captures/c000001/preview_meas_000.png%00.txt", "/assets/app.js%3f",
        "/captures/c000001/recon/gap-tv/frame_000.exr", "/captures/c000001/meta.json",
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        http_reply r;
        http_get(PORT, bad[i], &r);
        printf("  GET %s -> %d\n", bad[i], r.status);
        assert_true(r.status == 400 || r.status == 404);
        assert_null(strstr(r.body, "root:"));
        assert_true(header_has(&r, "Content-Security-Policy", "default-src 'self'"));
    }
}

static void unknown_routes_404(void **s)
{
    (void)s;
    static const char *const unknown[] = {"/nope", "/api/nope", "/assets/index.html", "/assets/web.c",
                                          "/index.html", "/api/state/x", "/captures/x/preview_meas_000.png"};
    for (size_t i = 0; i < sizeof unknown / sizeof unknown[0]; i++) {
        http_reply r;
        http_get(PORT, unknown[i], &r);
        assert_int_equal(r.status, 404);
    }
    http_reply r;
    http_post(PORT, "/api/shutdown", NULL, "{}", &r);
    assert_int_equal(r.status, 404);
    char req[256];
    int n = snprintf(req, sizeof req, "DELETE / HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\n\r\n", PORT);
    http_raw(PORT, req, (size_t)n, &r);
    assert_int_equal(r.status, 405);
}

static void control_needs_the_token(void **s)
{
    (void)s;
    http_reply r;
    http_post(PORT, "/api/capture", NULL, "{\"count\": 1}", &r);
    assert_int_equal(r.status, 401);
    http_post(PORT, "/api/capture", "Bearer 0000000000000000000000000000000000000000000000000000000000000000",
              "{\"count\": 1}", &r);
    assert_int_equal(r.status, 403);
    char almost[128];
    snprintf(almost, sizeof almost, "Bearer %.63s", TOKEN); /* a prefix of the right one */
    http_post(PORT, "/api/capture", almost, "{\"count\": 1}", &r);
    assert_int_equal(r.status, 403);
    snprintf(almost, sizeof almost, "Bearer %sx", TOKEN);   /* the right one and more */
    http_post(PORT, "/api/capture", almost, "{\"count\": 1}", &r);
    assert_int_equal(r.status, 403);
    http_post(PORT, "/api/cancel", "Basic abc", "{\"job\": 1}", &r);
    assert_int_equal(r.status, 401);
    /* with the token: the daemon checks the args as any client's */
    char auth[128];
    snprintf(auth, sizeof auth, "Bearer %s", TOKEN);
    http_post(PORT, "/api/capture", auth, "{\"count\": 0}", &r);
    assert_int_equal(r.status, 422);
    assert_non_null(strstr(r.body, "bad_arguments"));
    http_post(PORT, "/api/cancel", auth, "{\"job\": 999999}", &r);
    assert_int_equal(r.status, 403); /* not a job the web started */
    http_post(PORT, "/api/capture", auth, "{\"count\": 1}", &r);
    assert_int_equal(r.status, 200);
    json_t *o = json_loadb(r.body, r.body_len, 0, NULL);
    assert_true(json_integer_value(json_object_get(o, "job")) > 0);
    json_decref(o);
}

static void oversized_refused(void **s)
{
    (void)s;
    http_reply r;
    char req[1024];
    char auth[128];
    snprintf(auth, sizeof auth, "Bearer %s", TOKEN);
    /* a body announced over the limit: refused before it is read */
    int n = snprintf(req, sizeof req, "POST /api/capture HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\n"
                     "Authorization: %s\r\nContent-Length: 10000000\r\n\r\n{", PORT, auth);
    http_raw(PORT, req, (size_t)n, &r);
    assert_int_equal(r.status, 413);
    /* a chunked body that grows past it */
    size_t big = 20000;
    char *body = malloc(big + 1);
    memset(body, ' ', big);
    body[0] = '{';
    body[big - 1] = '}';
    body[big] = '\0';
    char *creq = malloc(big + 512);
    n = snprintf(creq, big + 512, "POST /api/capture HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\n"
                 "Authorization: %s\r\nTransfer-Encoding: chunked\r\n\r\n%zx\r\n%s\r\n0\r\n\r\n", PORT, auth, big,
                 body);
    http_raw(PORT, creq, (size_t)n, &r);
    assert_int_equal(r.status, 413);
    /* a URL over 1 KiB, and headers over the connection's memory: refused, never served */
    char *url = malloc(3000);
    memset(url, 'a', 2999);
    url[0] = '/';
    url[2999] = '\0';
    n = snprintf(creq, big + 512, "GET %s HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\n\r\n", url, PORT);
    http_raw(PORT, creq, (size_t)n, &r);
    printf("  3000-byte URL -> %d\n", r.status);
    assert_true(r.status == 414 || r.status == 431 || r.status == 413);
    memset(body, 'x', big);
    n = snprintf(creq, big + 512, "GET / HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nConnection: close\r\nX-Big: %s\r\n\r\n",
                 PORT, body);
    http_raw(PORT, creq, (size_t)n, &r);
    printf("  20000-byte header -> %d\n", r.status);
    assert_true(r.status == 431 || r.status == 413 || r.status == 414);
    free(url);
    free(creq);
    free(body);
}

static void foreign_host_refused(void **s)
{
    (void)s;
    http_reply r;
    char req[256];
    int n = snprintf(req, sizeof req, "GET /api/state HTTP/1.1\r\nHost: attacker.example:%d\r\nConnection: close"
                     "\r\n\r\n", PORT);
    http_raw(PORT, req, (size_t)n, &r);
    assert_int_equal(r.status, 421);
    n = snprintf(req, sizeof req, "GET /api/state HTTP/1.1\r\nHost: localhost:%d\r\nConnection: close\r\n\r\n",
                 PORT);
    http_raw(PORT, req, (size_t)n, &r);
    assert_int_equal(r.status, 200);
}

/* Read the SSE stream until `needle` appears or timeout_ms pass: 1 when seen. */
static int stream_wait(int fd, const char *needle, int timeout_ms)
{
    static char buf[1 << 16];
    size_t n = 0;
    int64_t t0 = h_now_ms();
    while (h_now_ms() - t0 < timeout_ms) {
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (poll(&p, 1, 200) <= 0)
            continue;
        if (n > sizeof buf - 4096)
            n = 0; /* keep the tail only */
        ssize_t r = recv(fd, buf + n, sizeof buf - 1 - n, 0);
        if (r <= 0)
            return 0;
        n += (size_t)r;
        buf[n] = '\0';
        if (strstr(buf, needle))
            return 1;
    }
    return 0;
}

static void events_stream_and_previews(void **s)
{
    (void)s;
    int fd = tcp_connect(PORT);
    assert_true(fd >= 0);
    char req[256];
    int n = snprintf(req, sizeof req, "GET /api/events HTTP/1.1\r\nHost: 127.0.0.1:%d\r\n\r\n", PORT);
    send_all(fd, req, (size_t)n);
    assert_true(stream_wait(fd, "text/event-stream", 5000));
    hconn c;
    hconn_open(&c, &H);
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 1)));
    json_t *e = hconn_wait_event(&c, "capture.stored", 30000);
    char cap[32];
    snprintf(cap, sizeof cap, "%s", json_string_value(json_object_get(json_object_get(e, "data"), "capture")));
    json_decref(e);
    assert_true(stream_wait(fd, "\"capture.stored\"", 10000));
    close(fd);
    hconn_close(&c);
    char path[128];
    http_reply r;
    snprintf(path, sizeof path, "/captures/%s/preview_meas_000.png", cap);
    http_get(PORT, path, &r);
    assert_int_equal(r.status, 200);
    assert_true(header_has(&r, "Content-Type", "image/png"));
    assert_memory_equal(r.body, "\x89PNG", 4);
    snprintf(path, sizeof path, "/captures/%s/meta.json", cap);
    http_get(PORT, path, &r);
    assert_int_equal(r.status, 404);
}

static void slow_connections_do_not_block(void **s)
{
    (void)s;
    int fds[SLOW_CONNECTIONS];
    char partial[128];
    int n = snprintf(partial, sizeof partial, "GET / HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nX-Slow: ", PORT);
    for (int i = 0; i < SLOW_CONNECTIONS; i++) {
        fds[i] = tcp_connect(PORT);
        assert_true(fds[i] >= 0);
        send_all(fds[i], partial, (size_t)n); /* never finished */
    }
    hconn c;
    hconn_open(&c, &H);
    int64_t t0 = h_now_ms();
    json_decref(hconn_request(&c, "status", NULL));
    int64_t status_ms = h_now_ms() - t0;
    printf("  status with %d half-sent HTTP connections: %lld ms\n", SLOW_CONNECTIONS, (long long)status_ms);
    assert_true(status_ms < 2000);
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 1)));
    json_decref(hconn_wait_event(&c, "capture.stored", 30000));
    /* the page is still served beside them */
    http_reply r;
    http_get(PORT, "/", &r);
    assert_int_equal(r.status, 200);
    /* and the server drops them after web.timeout_s (3 s) of silence */
    h_sleep_ms(5000);
    int closed = 0;
    for (int i = 0; i < SLOW_CONNECTIONS; i++) {
        struct pollfd p = {.fd = fds[i], .events = POLLIN};
        char b[256];
        if (poll(&p, 1, 2000) > 0 && recv(fds[i], b, sizeof b, MSG_DONTWAIT) <= 0)
            closed++;
        close(fds[i]);
    }
    printf("  closed by the server after its timeout: %d of %d\n", closed, SLOW_CONNECTIONS);
    assert_int_equal(closed, SLOW_CONNECTIONS);
    hconn_close(&c);
}

/* ---- web on, read-only (the default for control) ---- */

static void read_only_refuses_control(void **s)
{
    (void)s;
    harness h;
    int port = free_port();
    harness_init(&h, NULL);
    char cfg[256];
    snprintf(cfg, sizeof cfg, "{\"version\": 1, \"web\": {\"listen\": \"127.0.0.1:%d\"}}\n", port);
    harness_write_config(&h, cfg);
    harness_spawn(&h, NULL);
    http_reply r;
    http_get(port, "/api/state", &r);
    assert_int_equal(r.status, 200);
    assert_non_null(strstr(r.body, "\"control\":false"));
    http_post(port, "/api/capture", "Bearer 0000000000000000000000000000000000000000000000000000000000000000",
              "{\"count\": 1}", &r);
    assert_int_equal(r.status, 403);
    assert_non_null(strstr(r.body, "control is off"));
    http_post(port, "/api/cancel", NULL, "{\"job\": 1}", &r);
    assert_int_equal(r.status, 403);
    char token[400];
    snprintf(token, sizeof token, "%s/web.token", h.run);
    assert_int_not_equal(access(token, F_OK), 0); /* no token is written without control */
    harness_stop(&h);
    harness_cleanup(&h);
}

int main(void)
{
    const struct CMUnitTest off[] = {cmocka_unit_test(off_by_default), cmocka_unit_test(read_only_refuses_control)};
    const struct CMUnitTest on[] = {
        cmocka_unit_test(listens_and_serves_page), cmocka_unit_test(traversal_refused),
        cmocka_unit_test(unknown_routes_404),      cmocka_unit_test(control_needs_the_token),
        cmocka_unit_test(oversized_refused),       cmocka_unit_test(foreign_host_refused),
        cmocka_unit_test(events_stream_and_previews), cmocka_unit_test(slow_connections_do_not_block),
    };
    int rc = cmocka_run_group_tests_name("web off, and read-only", off, NULL, NULL);
    return rc | cmocka_run_group_tests_name("web on", on, setup_web, teardown_web);
}
