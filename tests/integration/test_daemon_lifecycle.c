/* scicapd's life as a service, over the real socket: configuration reload (good, bad, by command and SIGHUP);
 * SIGTERM during a reconstruction; kill -9 during a capture followed by a restart; a DMD that disconnects
 * mid-run and comes back; the sd_notify messages (READY, WATCHDOG keep-alives, STOPPING) seen by a listener on
 * NOTIFY_SOCKET. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <dirent.h>

#include "io/problem_dir.h"
#include "tests/integration/daemon_harness.h"

static const char *const CONFIG_A = "{\n  \"version\": 1,\n  \"queues\": {\"capture\": 4}\n}\n";
static const char *const CONFIG_B =
    "{\n  \"version\": 1,\n  \"queues\": {\"capture\": 6},\n"
    "  \"mask_sets\": {\"random8\": {\"type\": \"random\", \"frames\": 8},\n"
    "                \"shift8\": {\"type\": \"shifting\", \"frames\": 8, \"step\": 2}}\n}\n";
static const char *const CONFIG_BAD = "{\n  \"version\": 1,\n  \"queues\": {\"capture\": 0}\n}\n";
static const char *const CONFIG_SYNTAX = "{\n  \"version\": 1,\n  \"queues\": {\"capture\": 3,}\n}\n";

static void expect_capacity(hconn *c, int cap)
{
    json_t *r = hconn_request(c, "status", NULL);
    assert_int_equal(json_integer_value(json_array_get(json_object_get(json_object_get(r, "queues"), "capture"), 1)),
                     cap);
    json_decref(r);
}

static void reload_good_and_bad(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, CONFIG_A, NULL);
    hconn c;
    hconn_open(&c, &h);
    expect_capacity(&c, 4);
    hconn_expect_error(&c, "capture", json_pack("{s:s}", "mask_set", "shift8"), "bad_arguments");
    /* good: a new mask set and a new queue size, live */
    harness_write_config(&h, CONFIG_B);
    json_t *r = hconn_request(&c, "reload", NULL);
    assert_int_equal(json_array_size(json_object_get(r, "restart_needed")), 0);
    json_decref(r);
    expect_capacity(&c, 6);
    json_decref(hconn_request(&c, "capture", json_pack("{s:s}", "mask_set", "shift8")));
    json_decref(hconn_wait_event(&c, "capture.done", 20000));
    /* bad value: refused with file:line:column and the key; the old configuration stays */
    harness_write_config(&h, CONFIG_BAD);
    json_t *m = hconn_call(&c, "reload", NULL);
    assert_true(json_is_false(json_object_get(m, "ok")));
    const char *msg = json_string_value(json_object_get(json_object_get(m, "error"), "message"));
    printf("  bad config refused: %s\n", msg);
    assert_non_null(strstr(msg, "scicapd.json:3:"));
    assert_non_null(strstr(msg, "queues.capture"));
    json_decref(m);
    expect_capacity(&c, 6);
    json_decref(hconn_request(&c, "capture", json_pack("{s:s}", "mask_set", "shift8")));
    json_decref(hconn_wait_event(&c, "capture.done", 20000));
    /* bad syntax by SIGHUP: the daemon keeps running on the old configuration */
    harness_write_config(&h, CONFIG_SYNTAX);
    kill(h.pid, SIGHUP);
    h_sleep_ms(300);
    expect_capacity(&c, 6);
    /* good by SIGHUP */
    harness_write_config(&h, CONFIG_A);
    kill(h.pid, SIGHUP);
    h_sleep_ms(300);
    expect_capacity(&c, 4);
    hconn_expect_error(&c, "capture", json_pack("{s:s}", "mask_set", "shift8"), "bad_arguments");
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

/* No entry anywhere under dir whose name marks a partial write. */
static int count_partial(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        if (e->d_name[0] == '.' || strstr(e->d_name, ".tmp-") || strstr(e->d_name, ".partial"))
            n++;
        char p[1024];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        if (e->d_type == DT_DIR)
            n += count_partial(p);
    }
    closedir(d);
    return n;
}

static void sigterm_during_reconstruction(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, NULL, NULL);
    hconn c;
    hconn_open(&c, &h);
    json_decref(hconn_request(&c, "capture", NULL));
    json_t *st = hconn_wait_event(&c, "capture.stored", 20000);
    char id[64], dir[512];
    snprintf(id, sizeof id, "%s", json_string_value(json_object_get(json_object_get(st, "data"), "capture")));
    snprintf(dir, sizeof dir, "%s", json_string_value(json_object_get(json_object_get(st, "data"), "dir")));
    json_decref(st);
    json_decref(hconn_request(&c, "reconstruct", json_pack("{s:s, s:{s:i}}", "capture", id, "params", "iters",
                                                           100000)));
    json_decref(hconn_wait_event(&c, "recon.progress", 20000));
    int64_t t0 = h_now_ms();
    harness_stop(&h); /* SIGTERM; fails unless the exit status is 0 */
    printf("  stopped %lld ms after SIGTERM in mid-reconstruction\n", (long long)(h_now_ms() - t0));
    json_t *ev = hconn_wait_event(&c, "recon.canceled", 5000); /* the client was told */
    json_decref(ev);
    assert_false(h_exists("%s/%s", dir, "recon/gap-tv"));
    assert_true(h_exists("%s/%s", dir, "problem.json"));
    assert_int_equal(count_partial(h.store), 0);
    hconn_close(&c);
    harness_cleanup(&h);
}

static void kill9_during_capture_then_restart(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, NULL, NULL);
    hconn c;
    hconn_open(&c, &h);
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 40)));
    char announced[16][32];
    int n = 0;
    while (n < 4) {
        json_t *e = hconn_wait_event(&c, "capture.stored", 20000);
        snprintf(announced[n++], 32, "%s", json_string_value(json_object_get(json_object_get(e, "data"), "capture")));
        json_decref(e);
    }
    h_sleep_ms(37); /* somewhere inside the next snapshot or its write */
    harness_kill9(&h);
    char caps[512];
    snprintf(caps, sizeof caps, "%s/captures", h.store);
    printf("  killed after %d announced captures; %d partial entries left on disk\n", n, count_partial(caps));
    hconn_close(&c);
    harness_spawn(&h, NULL);
    hconn_open(&c, &h);
    json_t *r = hconn_request(&c, "status", NULL);
    int found = (int)json_integer_value(json_object_get(json_object_get(r, "recovered"), "captures"));
    printf("  restart: %d complete captures, %lld partial folders removed\n", found,
           (long long)json_integer_value(json_object_get(json_object_get(r, "recovered"), "removed_partial")));
    json_decref(r);
    assert_true(found >= n);
    assert_int_equal(count_partial(caps), 0);
    for (int i = 0; i < n; i++) {
        char dir[700];
        snprintf(dir, sizeof dir, "%s/%s", caps, announced[i]);
        sci_problem **p;
        int k;
        sci_error err = {0};
        if (sci_problem_dir_read(dir, &p, &k, &err) < 0)
            fail_msg("announced capture %s lost or damaged: %s", announced[i], err.msg);
        sci_problem_array_free(p, k);
        assert_true(h_exists("%s/%s/meta.json", caps, announced[i]));
        assert_true(h_exists("%s/%s/raw.tif", caps, announced[i]));
    }
    /* numbering continues after the survivors */
    json_decref(hconn_request(&c, "capture", NULL));
    json_t *e = hconn_wait_event(&c, "capture.stored", 20000);
    const char *next = json_string_value(json_object_get(json_object_get(e, "data"), "capture"));
    assert_true(strcmp(next, announced[n - 1]) > 0);
    json_decref(e);
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

static void dmd_disconnects_and_returns(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, NULL, NULL);
    hconn c, w;
    hconn_open(&c, &h);
    hconn_open(&w, &h);
    json_decref(hconn_request(&w, "watch", NULL));
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s, s:i}", "fault", "acquire-delay", "n", 150)));
    /* 40 snapshots of >= 150 ms: still running when the first is announced, even when a loaded machine delays
     * the writer by seconds (with 6, the job could end before the unplug: no capture.failed, a 20 s timeout) */
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 40)));
    json_decref(hconn_wait_event(&c, "capture.stored", 20000));
    /* unplug while the capture job runs */
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s}", "fault", "dmd-unplug")));
    json_t *e = hconn_wait_event(&c, "capture.failed", 20000);
    printf("  mid-run unplug: %s\n", json_string_value(json_object_get(json_object_get(e, "data"), "error")));
    json_decref(e);
    json_decref(hconn_wait_event_ex(&w, "device.disconnected", 5000, 1));
    json_t *r = hconn_request(&c, "status", NULL);
    assert_true(json_is_false(json_object_get(r, "dmd_connected")));
    json_decref(r);
    /* a capture while it is away fails with a reason, and the daemon keeps serving */
    json_decref(hconn_request(&c, "capture", NULL));
    json_decref(hconn_wait_event(&c, "capture.failed", 20000));
    /* plugged back: reconnected, masks uploaded again, captures work */
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s}", "fault", "dmd-replug")));
    json_decref(hconn_wait_event_ex(&w, "device.connected", 5000, 1));
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s, s:i}", "fault", "acquire-delay", "n", 0)));
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 2)));
    e = hconn_wait_event(&c, "capture.done", 20000);
    assert_int_equal(json_integer_value(json_object_get(json_object_get(e, "data"), "done")), 2);
    json_decref(e);
    r = hconn_request(&c, "status", NULL);
    assert_true(json_is_true(json_object_get(r, "dmd_connected")));
    json_decref(r);
    hconn_close(&w);
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

static void watchdog_keepalives(void **state)
{
    (void)state;
    harness h;
    harness_init(&h, NULL);
    char npath[400];
    snprintf(npath, sizeof npath, "%s/notify.sock", h.dir);
    int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", npath);
    assert_int_equal(bind(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    char env1[512], env2[64];
    snprintf(env1, sizeof env1, "NOTIFY_SOCKET=%s", npath);
    snprintf(env2, sizeof env2, "WATCHDOG_USEC=%d", 200000);
    char *env[] = {env1, env2, NULL};
    harness_spawn(&h, env);
    int ready = 0, pings = 0, stopping = 0, status = 0;
    int64_t t0 = h_now_ms(), stop_at = 0;
    while (h_now_ms() - t0 < 8000) {
        if (!stop_at && h_now_ms() - t0 > 1500) {
            kill(h.pid, SIGTERM);
            stop_at = h_now_ms();
        }
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (poll(&p, 1, 100) <= 0)
            continue;
        char buf[512];
        ssize_t r = recv(fd, buf, sizeof buf - 1, 0);
        if (r <= 0)
            continue;
        buf[r] = '\0';
        ready += strstr(buf, "READY=1") != NULL;
        pings += !stop_at && strstr(buf, "WATCHDOG=1") != NULL;
        status += strstr(buf, "STATUS=") != NULL;
        if (strstr(buf, "STOPPING=1")) {
            stopping = 1;
            break;
        }
    }
    printf("  READY %d, WATCHDOG=1 x %d in 1.5 s (WatchdogSec 0.2 s), STATUS x %d, STOPPING %d\n", ready, pings,
           status, stopping);
    assert_int_equal(ready, 1);
    assert_true(pings >= 5);
    assert_true(stopping);
    int st = harness_wait(&h, 20000);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    close(fd);
    harness_cleanup(&h);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(reload_good_and_bad),
        cmocka_unit_test(sigterm_during_reconstruction),
        cmocka_unit_test(kill9_during_capture_then_restart),
        cmocka_unit_test(dmd_disconnects_and_returns),
        cmocka_unit_test(watchdog_keepalives),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
