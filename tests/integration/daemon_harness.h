/* tests/integration/daemon_harness.h — start the built scicapd in a temporary folder and talk to it over its
 * real Unix socket. Header-only (static inline) so each integration test program includes it.
 *
 *     harness h;
 *     harness_start(&h, "{\"queues\": {\"capture\": 2}}", NULL);   // config text (NULL: none), extra env
 *     hconn c; hconn_open(&c, &h);
 *     json_t *r = hconn_request(&c, "status", NULL);              // the reply's "result", or fails the test
 *     json_t *e = hconn_wait_event(&c, "capture.stored", 30000);
 *     harness_stop(&h);                                           // SIGTERM, waits, checks the exit status
 *
 * The binary is found beside the test program (BUILD/tests/integration/x -> BUILD/scicapd). The daemon is
 * killed when the test program ends, also when a failed assertion skipped harness_stop.
 */
#ifndef SCICAP_TESTS_DAEMON_HARNESS_H
#define SCICAP_TESTS_DAEMON_HARNESS_H

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <libgen.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "daemon/store.h"
#include "io/staging.h"

typedef struct harness {
    char dir[256];       /* temporary folder */
    char sock[300], store[300], run[300], config[300], log[300];
    char bin[1024];
    pid_t pid;
    int have_config;
    int fsync; /* storage.fsync as configured (set between harness_init and harness_spawn); else --no-fsync */
    int store_mounted; /* harness_mount_store's tmpfs is on store: harness_cleanup unmounts it */
} harness;

typedef struct hconn {
    int fd;
    char buf[1 << 16];
    size_t len;
    int next_id;
} hconn;

static inline int64_t h_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static inline void h_sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

static inline void harness_write_config(harness *h, const char *text)
{
    FILE *f = fopen(h->config, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    h->have_config = 1;
}

static inline int h_connect_raw(const char *path)
{
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    if (connect(fd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

/* In a forked child, first thing (and again after any change of its user or group, which clears it): the child
 * is killed when the test program dies, so a failed assertion that jumps past the stop cannot leave a scicapd
 * running. `parent` is the test's pid read before the fork; the child exits 127 when it was already orphaned. */
static inline void harness_child_tie(pid_t parent)
{
    if (prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || getppid() != parent)
        _exit(127);
}

/* Start (or restart, keeping dir) the daemon; env: NULL-terminated "K=V" list added to the environment. */
static inline void harness_spawn(harness *h, char *const *env)
{
    unlink(h->sock);
    pid_t parent = getpid();
    h->pid = fork();
    assert_true(h->pid >= 0);
    if (h->pid == 0) {
        harness_child_tie(parent);
        for (int i = 0; env && env[i]; i++)
            putenv(env[i]);
        int fd = open(h->log, O_WRONLY | O_CREAT | O_APPEND, 0644);
        if (fd >= 0) {
            dup2(fd, 2);
            dup2(fd, 1);
        }
        char *argv[16];
        int k = 0;
        argv[k++] = h->bin;
        if (h->have_config) {
            argv[k++] = "--config";
            argv[k++] = h->config;
        } else {
            argv[k++] = "--no-config";
        }
        argv[k++] = "--socket";
        argv[k++] = h->sock;
        argv[k++] = "--storage";
        argv[k++] = h->store;
        argv[k++] = "--runtime-dir";
        argv[k++] = h->run;
        if (!h->fsync)
            argv[k++] = "--no-fsync";
        if (geteuid() == 0)
            argv[k++] = "--allow-root"; /* tests run as root outside systemd: say so (daemon/main.c) */
        argv[k] = NULL;
        execv(h->bin, argv);
        _exit(127);
    }
    for (int i = 0; i < 200; i++) {
        int fd = h_connect_raw(h->sock);
        if (fd >= 0) {
            close(fd);
            return;
        }
        int st;
        if (waitpid(h->pid, &st, WNOHANG) == h->pid) {
            h->pid = 0;
            fail_msg("scicapd exited at start (status %d); log in %s", st, h->log);
        }
        h_sleep_ms(50);
    }
    fail_msg("scicapd did not listen on %s within 10 s", h->sock);
}

static inline void harness_init(harness *h, const char *config_text)
{
    memset(h, 0, sizeof *h);
    snprintf(h->dir, sizeof h->dir, "/tmp/scicapd-test-XXXXXX");
    assert_non_null(mkdtemp(h->dir));
    snprintf(h->sock, sizeof h->sock, "%s/control.sock", h->dir);
    snprintf(h->store, sizeof h->store, "%s/store", h->dir);
    snprintf(h->run, sizeof h->run, "%s/run", h->dir);
    snprintf(h->config, sizeof h->config, "%s/scicapd.json", h->dir);
    snprintf(h->log, sizeof h->log, "%s/scicapd.log", h->dir);
    char self[1024];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    assert_true(n > 0);
    self[n] = '\0';
    snprintf(h->bin, sizeof h->bin, "%s/../../scicapd", dirname(self));
    if (access(h->bin, X_OK) != 0)
        fail_msg("no scicapd binary at %s (build it first)", h->bin);
    if (config_text)
        harness_write_config(h, config_text);
}

static inline void harness_start(harness *h, const char *config_text, char *const *env)
{
    harness_init(h, config_text);
    harness_spawn(h, env);
}

/* Wait for the daemon to exit; returns its wait status. Fails after timeout_ms. */
static inline int harness_wait(harness *h, int timeout_ms)
{
    int st = 0;
    int64_t t0 = h_now_ms();
    while (h->pid > 0) {
        pid_t r = waitpid(h->pid, &st, WNOHANG);
        if (r == h->pid) {
            h->pid = 0;
            return st;
        }
        if (h_now_ms() - t0 > timeout_ms) {
            kill(h->pid, SIGKILL);
            waitpid(h->pid, &st, 0);
            h->pid = 0;
            fail_msg("scicapd did not exit within %d ms", timeout_ms);
        }
        h_sleep_ms(20);
    }
    return st;
}

/* SIGTERM and a clean exit (status 0). */
static inline void harness_stop(harness *h)
{
    if (h->pid <= 0)
        return;
    kill(h->pid, SIGTERM);
    int st = harness_wait(h, 30000);
    if (!WIFEXITED(st) || WEXITSTATUS(st) != 0)
        fail_msg("scicapd ended with status 0x%x after SIGTERM; log in %s", st, h->log);
}

static inline void harness_kill9(harness *h)
{
    kill(h->pid, SIGKILL);
    harness_wait(h, 10000);
}

static inline void harness_cleanup(harness *h)
{
    if (h->pid > 0) {
        kill(h->pid, SIGKILL);
        waitpid(h->pid, NULL, 0);
        h->pid = 0;
    }
    if (h->store_mounted)
        umount2(h->store, MNT_DETACH); /* lazily: a descriptor still open in the test must not keep it */
    h->store_mounted = 0;
    sci_staging_remove(h->dir);
}

/* Two unprivileged client uids for the ownership tests: nobody, and the one below it. */
#define HARNESS_UID_A 65534
#define HARNESS_UID_B 65533

/* Skips the test, saying so, unless it runs as root (mount, setpriv). */
static inline void harness_require_root(const char *why)
{
    if (geteuid() != 0) {
        print_message("  needs root to %s; running as uid %d\n", why, (int)geteuid());
        skip();
    }
}

/* Between harness_init and harness_spawn: the store on a fresh tmpfs of `size` (mount's size=, "1m"), for a full
 * disk on demand. Needs root; a failed mount fails the test. harness_cleanup unmounts it. */
static inline void harness_mount_store(harness *h, const char *size)
{
    char opts[64];
    snprintf(opts, sizeof opts, "size=%s", size);
    assert_int_equal(mkdir(h->store, 0755), 0);
    if (mount("tmpfs", h->store, "tmpfs", 0, opts) != 0)
        fail_msg("mount tmpfs on %s: %s", h->store, strerror(errno));
    h->store_mounted = 1;
}

/* harness_start, then the temporary folder made traversable (0755) so that other uids reach the socket (with a
 * config whose control.mode lets them: "0666"). */
static inline void harness_start_open(harness *h, const char *config_text)
{
    harness_start(h, config_text, NULL);
    assert_int_equal(chmod(h->dir, 0755), 0);
}

/* connect() to h's socket as uid with primary gid: setegid/seteuid around it (SO_PEERCRED records the effective
 * ids at connect), root's identity restored before returning. The descriptor, or -1 with connect's errno. Needs
 * root; failing to change identity fails the test. */
static inline int h_connect_as(const harness *h, uid_t uid, gid_t gid)
{
    if (setegid(gid) != 0 || seteuid(uid) != 0)
        fail_msg("seteuid(%d)/setegid(%d): %s", (int)uid, (int)gid, strerror(errno));
    int fd = h_connect_raw(h->sock);
    int e = errno;
    if (seteuid(0) != 0 || setegid(0) != 0)
        fail_msg("back to root: %s", strerror(errno));
    errno = e;
    return fd;
}

/* hconn_open as uid/gid (h_connect_as); a refused connect fails the test. */
static inline void hconn_open_as(hconn *c, const harness *h, uid_t uid, gid_t gid)
{
    memset(c, 0, sizeof *c);
    c->fd = h_connect_as(h, uid, gid);
    if (c->fd < 0)
        fail_msg("connect as uid %d: %s", (int)uid, strerror(errno));
    c->next_id = 1;
}

/* The captures stored under the store's captures/ (0 when the folder is not there yet). */
static inline int harness_count_captures(const harness *h)
{
    char p[400];
    snprintf(p, sizeof p, "%s/captures", h->store);
    DIR *d = opendir(p);
    if (!d)
        return 0;
    int n = 0;
    for (struct dirent *e; (e = readdir(d));)
        n += e->d_name[0] != '.';
    closedir(d);
    return n;
}

static inline void hconn_open(hconn *c, const harness *h)
{
    memset(c, 0, sizeof *c);
    c->fd = h_connect_raw(h->sock);
    if (c->fd < 0)
        fail_msg("connect %s: %s", h->sock, strerror(errno));
    c->next_id = 1;
}

static inline void hconn_close(hconn *c)
{
    if (c->fd >= 0)
        close(c->fd);
    c->fd = -1;
}

static inline void hconn_send_raw(hconn *c, const char *data, size_t n)
{
    size_t off = 0;
    while (off < n) {
        ssize_t w = send(c->fd, data + off, n - off, MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0)
            fail_msg("send: %s", strerror(errno));
        off += (size_t)w;
    }
}

/* Next message within timeout_ms, or NULL on timeout / closed connection. */
static inline json_t *hconn_read(hconn *c, int timeout_ms)
{
    int64_t t0 = h_now_ms();
    for (;;) {
        char *nl = memchr(c->buf, '\n', c->len);
        if (nl) {
            size_t n = (size_t)(nl - c->buf);
            json_error_t je;
            json_t *m = json_loadb(c->buf, n, 0, &je);
            memmove(c->buf, nl + 1, c->len - n - 1);
            c->len -= n + 1;
            if (!m)
                fail_msg("daemon sent invalid JSON: %s", je.text);
            return m;
        }
        int left = timeout_ms - (int)(h_now_ms() - t0);
        if (left <= 0)
            return NULL;
        struct pollfd p = {.fd = c->fd, .events = POLLIN};
        if (poll(&p, 1, left) <= 0)
            continue;
        if (c->len == sizeof c->buf)
            fail_msg("message longer than %zu bytes", sizeof c->buf);
        ssize_t r = recv(c->fd, c->buf + c->len, sizeof c->buf - c->len, 0);
        if (r <= 0)
            return NULL;
        c->len += (size_t)r;
    }
}

/* Send {"v":1,"id":N,"cmd":cmd,"args":args} (args stolen, may be NULL); return the full reply message (events
 * before it are skipped). */
static inline json_t *hconn_call(hconn *c, const char *cmd, json_t *args)
{
    int id = c->next_id++;
    json_t *req = json_pack("{s:i, s:i, s:s}", "v", 1, "id", id, "cmd", cmd);
    if (args)
        json_object_set_new(req, "args", args);
    char *s = json_dumps(req, JSON_COMPACT);
    json_decref(req);
    hconn_send_raw(c, s, strlen(s));
    hconn_send_raw(c, "\n", 1);
    free(s);
    for (;;) {
        json_t *m = hconn_read(c, 30000);
        if (!m)
            fail_msg("no reply to %s within 30 s", cmd);
        if (!json_object_get(m, "event") && json_integer_value(json_object_get(m, "id")) == id)
            return m;
        json_decref(m);
    }
}

/* The "result" of a successful call (new reference); fails the test on an error reply. */
static inline json_t *hconn_request(hconn *c, const char *cmd, json_t *args)
{
    json_t *m = hconn_call(c, cmd, args);
    if (!json_is_true(json_object_get(m, "ok"))) {
        char *s = json_dumps(m, JSON_COMPACT);
        fail_msg("%s failed: %s", cmd, s);
    }
    json_t *r = json_incref(json_object_get(m, "result"));
    json_decref(m);
    return r;
}

/* The error code of a failed call ("" if it succeeded). Static storage per call site is avoided: copies. */
static inline void hconn_expect_error(hconn *c, const char *cmd, json_t *args, const char *code)
{
    json_t *m = hconn_call(c, cmd, args);
    const char *got = json_string_value(json_object_get(json_object_get(m, "error"), "code"));
    if (json_is_true(json_object_get(m, "ok")) || !got || strcmp(got, code) != 0) {
        char *s = json_dumps(m, JSON_COMPACT);
        fail_msg("%s: expected error %s, got %s", cmd, code, s);
    }
    json_decref(m);
}

/* Wait for event `name`; returns it (new ref) or fails, also when a *.failed event comes first unless
 * `tolerate_failures`. */
static inline json_t *hconn_wait_event_ex(hconn *c, const char *name, int timeout_ms, int tolerate_failures)
{
    int64_t t0 = h_now_ms();
    for (;;) {
        int left = timeout_ms - (int)(h_now_ms() - t0);
        json_t *m = left > 0 ? hconn_read(c, left) : NULL;
        if (!m)
            fail_msg("no %s event within %d ms", name, timeout_ms);
        const char *ev = json_string_value(json_object_get(m, "event"));
        if (ev && strcmp(ev, name) == 0)
            return m;
        if (ev && !tolerate_failures && strstr(ev, ".failed") && !strstr(name, ".failed")) {
            char *s = json_dumps(m, JSON_COMPACT);
            fail_msg("waiting for %s: %s", name, s);
        }
        json_decref(m);
    }
}

static inline json_t *hconn_wait_event(hconn *c, const char *name, int timeout_ms)
{
    return hconn_wait_event_ex(c, name, timeout_ms, 0);
}

static inline int h_exists(const char *fmt, const char *a, const char *b)
{
    char p[1024];
    snprintf(p, sizeof p, fmt, a, b);
    struct stat st;
    return stat(p, &st) == 0;
}

/* An import request (args stolen) with nfds (0 to 8) descriptors attached (SCM_RIGHTS), as scicap capture --from
 * sends it; the reply message (a new reference; events that come before it are dropped). No reply within 30 s fails
 * the test. */
static inline json_t *hconn_import_fds(hconn *c, json_t *args, const int *fds, int nfds)
{
    assert_true(nfds >= 0 && nfds <= 8);
    int id = c->next_id++;
    json_t *req = json_pack("{s:i, s:i, s:s, s:o}", "v", 1, "id", id, "cmd", "import", "args", args);
    char *s = json_dumps(req, JSON_COMPACT);
    json_decref(req);
    size_t n = strlen(s);
    s[n++] = '\n';
    union {
        char b[CMSG_SPACE(sizeof(int) * 8)];
        struct cmsghdr align;
    } ctl;
    struct iovec iov = {.iov_base = s, .iov_len = n};
    struct msghdr m = {.msg_iov = &iov, .msg_iovlen = 1};
    if (nfds > 0) {
        m.msg_control = ctl.b;
        m.msg_controllen = CMSG_SPACE(sizeof(int) * (size_t)nfds);
        struct cmsghdr *h = CMSG_FIRSTHDR(&m);
        h->cmsg_level = SOL_SOCKET;
        h->cmsg_type = SCM_RIGHTS;
        h->cmsg_len = CMSG_LEN(sizeof(int) * (size_t)nfds);
        memcpy(CMSG_DATA(h), fds, sizeof(int) * (size_t)nfds);
    }
    assert_int_equal(sendmsg(c->fd, &m, MSG_NOSIGNAL), (ssize_t)n);
    free(s);
    for (;;) {
        json_t *r = hconn_read(c, 30000);
        if (!r)
            fail_msg("no reply to import within 30 s");
        if (!json_object_get(r, "event") && json_integer_value(json_object_get(r, "id")) == id)
            return r;
        json_decref(r);
    }
}

#endif
