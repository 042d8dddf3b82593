/* scicapd against careless and hostile local users, over its real Unix socket:
 *  - slowloris: 32 connections that send one byte and stall must not lock anyone out — an admin gets in at
 *    once through the reserved slots, an ordinary client as soon as the request deadline drops the stalled ones;
 *    a client that trickles a byte at a time is dropped on the same deadline; idle connections with nothing in
 *    flight are closed, watchers are not;
 *  - job ownership by peer uid: a user sees and cancels only their own jobs, watches only their own events;
 *    root sees and cancels all;
 *  - `--socket FILE` never deletes what stands at FILE unless it is a stale socket.
 * Other uids are taken with seteuid around connect(): SO_PEERCRED records the effective uid at connect, so one
 * process can hold connections of several users. That needs root; without it those tests say so and skip.
 * Everything is local: a Unix socket in a temporary folder. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "tests/integration/daemon_harness.h"

/* File-static, so that a failed test's daemon is stopped and its folder removed by the teardown. */
static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

/* request deadline 1 s, idle 2 s, 2 of 32 slots for admins; no per-uid cap, so that one uid can try to take
 * every ordinary slot (test_daemon_connections tests the cap) */
static const char *const CONFIG = "{\"control\": {\"mode\": \"0666\", \"max_clients\": 32, \"admin_slots\": 2,"
                                  " \"request_timeout_ms\": 1000, \"idle_timeout_ms\": 2000, \"max_per_uid\": 0}}\n";

/* default deadlines: a test that pauses between requests must not be cut off */
static const char *const CONFIG_SLOW = "{\"control\": {\"mode\": \"0666\"}}\n";

/* One line from fd within timeout_ms (NULL on EOF or timeout); *eof set when the peer closed. */
static json_t *read_line_fd(int fd, int timeout_ms, int *eof)
{
    char buf[4096];
    size_t len = 0;
    int64_t t0 = h_now_ms();
    *eof = 0;
    while (len < sizeof buf) {
        int left = timeout_ms - (int)(h_now_ms() - t0);
        if (len > 0 && left < 1000)
            left = 1000; /* a line has begun: its rest is on the way, never drop half a line */
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (left <= 0 || poll(&p, 1, left) <= 0)
            return NULL;
        ssize_t r = recv(fd, buf + len, 1, 0); /* byte by byte: what follows the line stays for the next read */
        if (r <= 0) {
            if (r < 0)
                print_message("  (recv: %s after %zu bytes)\n", strerror(errno), len);
            *eof = 1;
            return NULL;
        }
        if (buf[len] == '\n')
            return json_loadb(buf, len, 0, NULL);
        len++;
    }
    return NULL;
}

static const char *error_code(const json_t *m)
{
    const char *s = json_string_value(json_object_get(json_object_get(m, "error"), "code"));
    return s ? s : "";
}

/* status over a new connection as uid; returns 1 when answered, 0 when refused busy (connection closed). */
static int try_status_as(const harness *h, uid_t uid)
{
    int fd = h_connect_as(h, uid, uid);
    if (fd < 0)
        return 0;
    const char *req = "{\"v\":1,\"id\":1,\"cmd\":\"status\"}\n";
    ssize_t w = send(fd, req, strlen(req), MSG_NOSIGNAL);
    (void)w;
    int eof;
    json_t *m = read_line_fd(fd, 3000, &eof);
    close(fd);
    int ok = m && json_is_true(json_object_get(m, "ok"));
    if (m && !ok && strcmp(error_code(m), "busy") != 0) {
        char *s = json_dumps(m, JSON_COMPACT);
        fail_msg("status as uid %d: unexpected %s", (int)uid, s);
    }
    json_decref(m);
    return ok;
}

#define STALLED 32

static void slowloris_does_not_lock_out(void **state)
{
    (void)state;
    harness_require_root("connect as other uids (seteuid)");
    harness_start_open(&H, CONFIG);
    int fd[STALLED];
    int64_t t0 = h_now_ms();
    for (int i = 0; i < STALLED; i++) {
        fd[i] = h_connect_as(&H, HARNESS_UID_A, HARNESS_UID_A);
        assert_true(fd[i] >= 0);
        ssize_t w = send(fd[i], "{", 1, MSG_NOSIGNAL); /* one byte, then nothing */
        (void)w;
    }
    /* the daemon takes them in: 30 ordinary slots, the last 2 are refused */
    h_sleep_ms(150);
    int refused = 0;
    for (int i = 0; i < STALLED; i++) {
        struct pollfd p = {.fd = fd[i], .events = POLLIN};
        if (poll(&p, 1, 0) == 1) {
            int eof;
            json_t *m = read_line_fd(fd[i], 200, &eof);
            assert_non_null(m);
            assert_string_equal(error_code(m), "busy");
            json_decref(m);
            close(fd[i]);
            fd[i] = -1;
            refused++;
        }
    }
    printf("  %d stalled one-byte connections from uid %d: %d held, %d refused busy\n", STALLED, HARNESS_UID_A,
           STALLED - refused, refused);
    assert_int_equal(refused, 2);
    /* an admin (root) gets in through the reserved slots at once */
    int64_t ta = h_now_ms();
    assert_true(try_status_as(&H, 0));
    int64_t admin_ms = h_now_ms() - ta;
    assert_true(h_now_ms() - t0 < 1000); /* still inside the attackers' deadline */
    /* an ordinary well-behaved client is refused while the slots are held ... */
    assert_false(try_status_as(&H, HARNESS_UID_B));
    /* ... and served once the request deadline (1 s) has dropped the stalled connections */
    int served = 0;
    while (!served && h_now_ms() - t0 < 5000) {
        served = try_status_as(&H, HARNESS_UID_B);
        if (!served)
            h_sleep_ms(50);
    }
    int64_t user_ms = h_now_ms() - t0;
    assert_true(served);
    /* every stalled connection was told "timeout" and closed */
    int timed_out = 0;
    for (int i = 0; i < STALLED; i++) {
        if (fd[i] < 0)
            continue;
        int eof;
        json_t *m = read_line_fd(fd[i], 2000, &eof);
        if (m && strcmp(error_code(m), "timeout") == 0) {
            json_decref(read_line_fd(fd[i], 2000, &eof));
            timed_out += eof;
        }
        json_decref(m);
        close(fd[i]);
    }
    int64_t all_ms = h_now_ms() - t0;
    printf("  admin served in %lld ms; ordinary client served %lld ms after the attack began; %d/%d stalled "
           "connections answered timeout and closed by %lld ms (request deadline 1000 ms)\n",
           (long long)admin_ms, (long long)user_ms, timed_out, STALLED - refused, (long long)all_ms);
    assert_int_equal(timed_out, STALLED - refused);
    /* bounded: the deadline plus scheduling slack on a loaded 2-core machine */
    assert_true(user_ms >= 1000 && user_ms < 3000);
    assert_true(all_ms < 4000);
    harness_stop(&H);
    harness_cleanup(&H);
}

static void trickle_and_idle_deadlines(void **state)
{
    (void)state;
    harness_require_root("connect as other uids (seteuid)");
    harness_start_open(&H, CONFIG);
    /* a byte every 200 ms never completes a line: dropped 1 s after its first byte, not after its last */
    int t = h_connect_as(&H, HARNESS_UID_A, HARNESS_UID_A);
    assert_true(t >= 0);
    int64_t t0 = h_now_ms(), closed_ms = -1;
    while (h_now_ms() - t0 < 4000) {
        ssize_t w = send(t, "x", 1, MSG_NOSIGNAL); /* fails once the daemon closed: the answer is still read */
        (void)w;
        int eof;
        json_t *m = read_line_fd(t, 200, &eof);
        if (m) {
            assert_string_equal(error_code(m), "timeout");
            json_decref(m);
            closed_ms = h_now_ms() - t0;
            break;
        }
        if (eof)
            fail_msg("trickling client closed without a timeout answer after %lld ms", (long long)(h_now_ms() - t0));
    }
    close(t);
    printf("  trickling client closed after %lld ms\n", (long long)closed_ms);
    assert_true(closed_ms >= 900 && closed_ms < 2500);
    /* after a request, an ordinary idle connection is closed at 2 s; a watcher stays */
    hconn idle, watcher;
    hconn_open_as(&idle, &H, HARNESS_UID_A, HARNESS_UID_A);
    hconn_open_as(&watcher, &H, HARNESS_UID_A, HARNESS_UID_A);
    json_decref(hconn_request(&idle, "status", NULL));
    json_decref(hconn_request(&watcher, "watch", NULL));
    int64_t t1 = h_now_ms();
    json_t *m = hconn_read(&idle, 4000);
    int64_t idle_ms = h_now_ms() - t1;
    assert_non_null(m);
    assert_string_equal(error_code(m), "timeout");
    json_decref(m);
    assert_null(hconn_read(&idle, 1000)); /* closed */
    printf("  idle connection closed %lld ms after its last request (idle_timeout_ms 2000)\n", (long long)idle_ms);
    assert_true(idle_ms >= 1800 && idle_ms < 4000);
    json_t *r = hconn_request(&watcher, "status", NULL); /* idle as long, but watching */
    json_decref(r);
    hconn_close(&idle);
    hconn_close(&watcher);
    harness_stop(&H);
    harness_cleanup(&H);
}

/* The job ids listed by `jobs` on c. */
static int list_jobs(hconn *c, json_int_t *ids, int max)
{
    json_t *r = hconn_request(c, "jobs", NULL);
    json_t *a = json_object_get(r, "jobs");
    int n = 0;
    for (size_t i = 0; i < json_array_size(a) && n < max; i++)
        ids[n++] = json_integer_value(json_object_get(json_array_get(a, i), "job"));
    json_decref(r);
    return n;
}

static int has(const json_int_t *ids, int n, json_int_t id)
{
    for (int i = 0; i < n; i++)
        if (ids[i] == id)
            return 1;
    return 0;
}

static json_int_t capture_done(hconn *c)
{
    json_t *r = hconn_request(c, "capture", NULL);
    json_int_t id = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    json_t *e = hconn_wait_event(c, "capture.done", 30000);
    assert_int_equal(json_integer_value(json_object_get(e, "job")), id);
    json_decref(e);
    return id;
}

static void jobs_belong_to_their_uid(void **state)
{
    (void)state;
    harness_require_root("connect as other uids (seteuid)");
    harness_start_open(&H, CONFIG_SLOW);
    hconn a, b, bw, root, rw;
    hconn_open_as(&a, &H, HARNESS_UID_A, HARNESS_UID_A);
    hconn_open_as(&b, &H, HARNESS_UID_B, HARNESS_UID_B);
    hconn_open_as(&bw, &H, HARNESS_UID_B, HARNESS_UID_B);
    hconn_open(&root, &H);
    hconn_open(&rw, &H);
    json_decref(hconn_request(&bw, "watch", NULL));
    json_decref(hconn_request(&rw, "watch", NULL));
    json_int_t ja = capture_done(&a);
    json_int_t jb = capture_done(&b);
    /* B's watcher saw B's job end and nothing of A's before it (events keep their order) */
    int saw_a = 0, saw_b = 0;
    while (!saw_b) {
        json_t *e = hconn_read(&bw, 10000);
        if (!e)
            fail_msg("B's watcher never saw B's capture.done");
        json_int_t job = json_integer_value(json_object_get(e, "job"));
        saw_a += job == ja;
        saw_b = job == jb && !strcmp(json_string_value(json_object_get(e, "event")), "capture.done");
        json_decref(e);
    }
    /* root's watcher saw both */
    int root_a = 0, root_b = 0;
    while (!root_b) {
        json_t *e = hconn_read(&rw, 10000);
        if (!e)
            fail_msg("root's watcher never saw B's capture.done");
        json_int_t job = json_integer_value(json_object_get(e, "job"));
        root_a += job == ja;
        root_b = job == jb && !strcmp(json_string_value(json_object_get(e, "event")), "capture.done");
        json_decref(e);
    }
    json_int_t ids[64];
    int na = list_jobs(&a, ids, 64);
    int a_sees_a = has(ids, na, ja), a_sees_b = has(ids, na, jb);
    int nb = list_jobs(&b, ids, 64);
    int b_sees_a = has(ids, nb, ja), b_sees_b = has(ids, nb, jb);
    int nr = list_jobs(&root, ids, 64);
    int r_sees_both = has(ids, nr, ja) && has(ids, nr, jb);
    printf("  jobs: uid %d lists %d (own %d, other's %d); uid %d lists %d (own %d, other's %d); root lists %d "
           "(both %d)\n  watch: uid %d's watcher saw %d events of uid %d's job; root's watcher saw %d\n",
           HARNESS_UID_A, na, a_sees_a, a_sees_b, HARNESS_UID_B, nb, b_sees_b, b_sees_a, nr, r_sees_both, HARNESS_UID_B,
           saw_a, HARNESS_UID_A, root_a);
    assert_true(a_sees_a && !a_sees_b && b_sees_b && !b_sees_a && r_sees_both);
    assert_int_equal(saw_a, 0);
    assert_true(root_a > 0);
    /* cancel: not someone else's job; one's own, and root anyone's */
    hconn_expect_error(&b, "cancel", json_pack("{s:I}", "job", ja), "permission");
    json_decref(hconn_request(&a, "cancel", json_pack("{s:I}", "job", ja)));
    json_decref(hconn_request(&root, "cancel", json_pack("{s:I}", "job", jb)));
    hconn_close(&a);
    hconn_close(&b);
    hconn_close(&bw);
    hconn_close(&root);
    hconn_close(&rw);
    harness_stop(&H);
    harness_cleanup(&H);
}

/* ---- --socket FILE ---- */

/* Run scicapd on socket `sock` (everything else in h's folder); returns the pid. */
static pid_t spawn_on(const harness *h, const char *sock)
{
    pid_t parent = getpid(), pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        harness_child_tie(parent);
        int fd = open(h->log, O_WRONLY | O_CREAT | O_APPEND, 0644);
        if (fd >= 0) {
            dup2(fd, 2);
            dup2(fd, 1);
        }
        char *argv[] = {(char *)h->bin, "--no-config", "--socket", (char *)sock, "--storage", (char *)h->store,
                        "--runtime-dir", (char *)h->run, "--no-fsync", geteuid() == 0 ? "--allow-root" : NULL, NULL};
        execv(h->bin, argv);
        _exit(127);
    }
    return pid;
}

/* Exit status of pid within timeout_ms (kills it and fails otherwise). */
static int wait_exit(pid_t pid, int timeout_ms)
{
    int64_t t0 = h_now_ms();
    int st;
    while (waitpid(pid, &st, WNOHANG) != pid) {
        if (h_now_ms() - t0 > timeout_ms) {
            kill(pid, SIGKILL);
            waitpid(pid, &st, 0);
            fail_msg("scicapd still running after %d ms", timeout_ms);
        }
        h_sleep_ms(20);
    }
    return st;
}

static int log_contains(const harness *h, const char *what)
{
    FILE *f = fopen(h->log, "r");
    if (!f)
        return 0;
    char line[1024];
    int found = 0;
    while (!found && fgets(line, sizeof line, f))
        found = strstr(line, what) != NULL;
    fclose(f);
    return found;
}

static void socket_path_never_clobbers(void **state)
{
    (void)state;
    harness_init(&H, NULL);
    char path[400], target[400];
    /* a regular file */
    snprintf(path, sizeof path, "%s/notes.txt", H.dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("precious\n", f);
    fclose(f);
    int st = wait_exit(spawn_on(&H, path), 15000);
    char buf[32] = "";
    f = fopen(path, "r");
    assert_non_null(f);
    assert_non_null(fgets(buf, sizeof buf, f));
    fclose(f);
    printf("  --socket on a regular file: exit %d, file %s\n", WIFEXITED(st) ? WEXITSTATUS(st) : -1,
           strcmp(buf, "precious\n") == 0 ? "intact" : "DAMAGED");
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 1);
    assert_string_equal(buf, "precious\n");
    assert_true(log_contains(&H, "a regular file stands there; refusing to replace it"));
    /* a symbolic link (to that file) and a folder */
    snprintf(target, sizeof target, "%s/link.sock", H.dir);
    assert_int_equal(symlink(path, target), 0);
    st = wait_exit(spawn_on(&H, target), 15000);
    struct stat sb;
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 1);
    assert_int_equal(lstat(target, &sb), 0);
    assert_true(S_ISLNK(sb.st_mode));
    snprintf(target, sizeof target, "%s/folder.sock", H.dir);
    assert_int_equal(mkdir(target, 0700), 0);
    st = wait_exit(spawn_on(&H, target), 15000);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 1);
    assert_int_equal(stat(target, &sb), 0);
    assert_true(S_ISDIR(sb.st_mode));
    /* a stale socket (bound, never listened, its owner gone) is still replaced */
    snprintf(target, sizeof target, "%s/stale.sock", H.dir);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", target);
    int s = socket(AF_UNIX, SOCK_STREAM, 0);
    assert_int_equal(bind(s, (struct sockaddr *)&sa, sizeof sa), 0);
    close(s);
    pid_t pid = spawn_on(&H, target);
    int up = 0;
    for (int i = 0; i < 200 && !up; i++) {
        int fd = h_connect_raw(target);
        if (fd >= 0) {
            close(fd);
            up = 1;
        } else {
            h_sleep_ms(50);
        }
    }
    printf("  stale socket replaced: %s\n", up ? "yes" : "no");
    kill(pid, SIGTERM);
    st = wait_exit(pid, 30000);
    assert_true(up);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    harness_cleanup(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(slowloris_does_not_lock_out, cleanup),
        cmocka_unit_test_teardown(trickle_and_idle_deadlines, cleanup),
        cmocka_unit_test_teardown(jobs_belong_to_their_uid, cleanup),
        cmocka_unit_test_teardown(socket_path_never_clobbers, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
