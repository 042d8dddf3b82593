/* What scicapd promises to keep across its own death, over the real socket and storage folder:
 *  - capture ids are never handed out twice: not after a kill -9 while a capture folder is half written, not
 *    after the newest capture is deleted and the daemon restarted (docs/capture-folder.md);
 *  - a second scicapd started on the same storage root is refused before its recovery could remove the first
 *    one's half-written folders;
 *  - reconstructions queued (or running) when the daemon dies — kill -9 or SIGTERM — are resumed at the next
 *    start, with their owner, and their results appear. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <dirent.h>

#include "tests/helpers/daemon_child.h"

/* File-static, so that a failed test's daemon is stopped and its folder removed by the teardown. */
static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

/* Number of a capture id "c000042" -> 42. */
static long id_num(const char *id) { return id && id[0] == 'c' ? strtol(id + 1, NULL, 10) : -1; }

/* Largest capture number among the entries of captures/, complete or partial (".c000042.partial"). */
static long max_on_disk(const harness *h, char *partial, size_t n)
{
    char caps[512];
    snprintf(caps, sizeof caps, "%s/captures", h->store);
    DIR *d = opendir(caps);
    long best = 0;
    if (partial)
        partial[0] = '\0';
    if (!d)
        return 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        const char *name = e->d_name[0] == '.' ? e->d_name + 1 : e->d_name;
        if (name[0] != 'c')
            continue;
        long v = strtol(name + 1, NULL, 10);
        if (v > best)
            best = v;
        if (partial && e->d_name[0] == '.' && strstr(e->d_name, ".partial"))
            snprintf(partial, n, "%s", e->d_name);
    }
    closedir(d);
    return best;
}

static long next_capture_id(hconn *c)
{
    json_decref(hconn_request(c, "capture", NULL));
    json_t *e = hconn_wait_event(c, "capture.stored", 30000);
    long v = id_num(json_string_value(json_object_get(json_object_get(e, "data"), "capture")));
    json_decref(e);
    json_decref(hconn_wait_event(c, "capture.done", 30000));
    return v;
}

static void ids_not_reused_after_kill9(void **state)
{
    (void)state;
    harness_start(&H, NULL, NULL);
    hconn c;
    hconn_open(&c, &H);
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 200)));
    long announced = 0;
    for (int i = 0; i < 2; i++) {
        json_t *e = hconn_wait_event(&c, "capture.stored", 30000);
        long v = id_num(json_string_value(json_object_get(json_object_get(e, "data"), "capture")));
        announced = v > announced ? v : announced;
        json_decref(e);
    }
    /* kill -9 the moment a capture folder is half written: its id was given out and must stay given */
    char partial[256] = "";
    int64_t t0 = h_now_ms();
    long seen = 0;
    while (!partial[0] && h_now_ms() - t0 < 20000) {
        seen = max_on_disk(&H, partial, sizeof partial);
        if (!partial[0])
            h_sleep_ms(1); /* a folder takes tens of ms to write: 1 ms polling still lands inside one */
    }
    harness_kill9(&H);
    hconn_close(&c);
    assert_true(partial[0]);
    long after = max_on_disk(&H, NULL, 0);
    long highest = announced > seen ? announced : seen;
    highest = after > highest ? after : highest;
    harness_spawn(&H, NULL);
    hconn_open(&c, &H);
    char left[256];
    max_on_disk(&H, left, sizeof left);
    long next = next_capture_id(&c);
    printf("  killed while %s was being written (highest id given out before the kill: %ld); partial removed: %s; "
           "next capture after restart: c%06ld\n", partial, highest, left[0] ? "no" : "yes", next);
    assert_false(left[0]);
    assert_true(next > highest);
    hconn_close(&c);
    daemon_child_teardown(&H);
}

static void ids_not_reused_after_delete(void **state)
{
    (void)state;
    harness_start(&H, NULL, NULL);
    hconn c;
    hconn_open(&c, &H);
    long first = next_capture_id(&c);
    long newest = next_capture_id(&c);
    hconn_close(&c);
    harness_stop(&H);
    char dir[600];
    snprintf(dir, sizeof dir, "%s/captures/c%06ld", H.store, newest);
    assert_int_equal(sci_staging_remove(dir), 0);
    harness_spawn(&H, NULL);
    hconn_open(&c, &H);
    long next = next_capture_id(&c);
    printf("  captures c%06ld, c%06ld; c%06ld deleted; after a restart the next is c%06ld\n", first, newest, newest,
           next);
    assert_true(next > newest);
    assert_int_equal(next, newest + 1); /* a clean stop leaves no gap */
    hconn_close(&c);
    daemon_child_teardown(&H);
}

/* A second scicapd on the same storage root (its own socket) while the first captures: refused before it
 * touches anything; the first one's capture goes on untouched. */
static void second_daemon_on_same_storage_refused(void **state)
{
    (void)state;
    harness_start(&H, NULL, NULL);
    hconn c;
    hconn_open(&c, &H);
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 12)));
    json_decref(hconn_wait_event(&c, "capture.stored", 30000));
    char sock2[400], log2[400];
    snprintf(sock2, sizeof sock2, "%s/second.sock", H.dir);
    snprintf(log2, sizeof log2, "%s/second.log", H.dir);
    pid_t parent = getpid(), pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        harness_child_tie(parent);
        int fd = open(log2, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0)
            dup2(fd, 2);
        execl(H.bin, H.bin, "--no-config", "--socket", sock2, "--storage", H.store, "--runtime-dir", H.run,
              "--no-fsync", geteuid() == 0 ? "--allow-root" : (char *)NULL, (char *)NULL);
        _exit(127);
    }
    int st = 0, exited = 0;
    for (int i = 0; i < 200 && !exited; i++) {
        exited = waitpid(pid, &st, WNOHANG) == pid;
        if (!exited)
            h_sleep_ms(50);
    }
    if (!exited) {
        kill(pid, SIGKILL);
        waitpid(pid, &st, 0);
    }
    char cmd[500];
    snprintf(cmd, sizeof cmd, "grep -q 'is in use by another scicapd' '%s'", log2);
    int said = system(cmd) == 0;
    /* the first daemon's capture finishes with every snapshot stored (a *.failed event fails the wait) */
    json_t *e = hconn_wait_event(&c, "capture.done", 60000);
    json_int_t done = json_integer_value(json_object_get(json_object_get(e, "data"), "done"));
    json_decref(e);
    printf("  second scicapd on the same storage: %s (exit %d, %s); first daemon's capture: %lld/12 stored\n",
           exited ? "refused" : "RAN (killed after 10 s)", exited && WIFEXITED(st) ? WEXITSTATUS(st) : -1,
           said ? "said why" : "no reason logged", (long long)done);
    assert_true(exited && WIFEXITED(st) && WEXITSTATUS(st) == 1);
    assert_true(said);
    assert_int_equal(done, 12);
    hconn_close(&c);
    daemon_child_teardown(&H);
}

/* ---- reconstruction queue ---- */

/* Queue a reconstruction; returns its job id. */
static json_int_t reconstruct(hconn *c, const char *cap, const char *method, int iters)
{
    json_t *args = json_pack("{s:s, s:s, s:s}", "capture", cap, "method", method, "preset", "fast");
    if (iters)
        json_object_set_new(args, "params", json_pack("{s:i}", "iters", iters));
    json_t *r = hconn_request(c, "reconstruct", args);
    json_int_t id = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    return id;
}

/* Cancel the unfinished reconstruction of `cap` (the long one that blocks the single worker). */
static void cancel_recon_of(hconn *c, const char *cap)
{
    json_t *r = hconn_request(c, "jobs", NULL);
    json_t *a = json_object_get(r, "jobs");
    json_int_t id = 0;
    for (size_t i = 0; i < json_array_size(a); i++) {
        json_t *j = json_array_get(a, i);
        const char *st = json_string_value(json_object_get(j, "state"));
        const char *jc = json_string_value(json_object_get(j, "capture"));
        if (jc && !strcmp(jc, cap) && (!strcmp(st, "queued") || !strcmp(st, "running")))
            id = json_integer_value(json_object_get(j, "job"));
    }
    json_decref(r);
    assert_true(id > 0);
    json_decref(hconn_request(c, "cancel", json_pack("{s:I}", "job", id)));
}

static void queued_reconstructions_resumed(void **state)
{
    (void)state;
    /* with storage.fsync on (the default the harness turns off elsewhere): the durable publish of every
     * reconstruction, and of the captures, runs here */
    harness_init(&H, "{\"reconstruction\": {\"workers\": 1}}\n");
    H.fsync = 1;
    harness_spawn(&H, NULL);
    hconn c;
    hconn_open(&c, &H);
    char cap[3][32];
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 3)));
    for (int i = 0; i < 3; i++) {
        json_t *e = hconn_wait_event(&c, "capture.stored", 30000);
        json_t *d = json_object_get(e, "data");
        snprintf(cap[json_integer_value(json_object_get(d, "index"))], 32, "%s",
                 json_string_value(json_object_get(d, "capture")));
        json_decref(e);
    }
    json_decref(hconn_wait_event(&c, "capture.done", 30000));
    /* the only worker busy for minutes; two more wait behind it; then kill -9 */
    reconstruct(&c, cap[0], "gap-tv", 100000);
    json_decref(hconn_wait_event(&c, "recon.started", 30000));
    reconstruct(&c, cap[1], "gap-tv", 0);
    reconstruct(&c, cap[2], "gap-tv", 0);
    harness_kill9(&H);
    hconn_close(&c);
    harness_spawn(&H, NULL);
    hconn_open(&c, &H);
    int n1 = daemon_child_resumed(&c);
    printf("  kill -9 with 1 running + 2 queued: %d resumed at restart\n", n1);
    assert_int_equal(n1, 3);
    cancel_recon_of(&c, cap[0]); /* the long one came back too: let the others through */
    int64_t t0 = h_now_ms();
    int ok1 = daemon_child_wait_recon(&H, cap[1], "gap-tv", 30000) && daemon_child_wait_recon(&H, cap[2], "gap-tv", 30000);
    printf("  the queued ones reconstructed after the restart: %s (%lld ms)\n", ok1 ? "yes" : "no",
           (long long)(h_now_ms() - t0));
    assert_true(ok1);
    /* SIGTERM: the same promise on an orderly stop */
    reconstruct(&c, cap[0], "gap-tv", 100000);
    json_decref(hconn_wait_event(&c, "recon.started", 30000));
    reconstruct(&c, cap[2], "admm-tv", 0);
    hconn_close(&c);
    harness_stop(&H);
    harness_spawn(&H, NULL);
    hconn_open(&c, &H);
    int n2 = daemon_child_resumed(&c);
    cancel_recon_of(&c, cap[0]);
    int ok2 = daemon_child_wait_recon(&H, cap[2], "admm-tv", 30000);
    /* finished and canceled jobs leave nothing behind to resume */
    hconn_close(&c);
    harness_stop(&H);
    harness_spawn(&H, NULL);
    hconn_open(&c, &H);
    int n3 = daemon_child_resumed(&c);
    printf("  SIGTERM with 1 running + 1 queued: %d resumed, queued one reconstructed: %s; after they ended and a "
           "clean restart: %d resumed\n", n2, ok2 ? "yes" : "no", n3);
    assert_int_equal(n2, 2);
    assert_true(ok2);
    assert_int_equal(n3, 0);
    hconn_close(&c);
    daemon_child_teardown(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(ids_not_reused_after_kill9, cleanup),
        cmocka_unit_test_teardown(ids_not_reused_after_delete, cleanup),
        cmocka_unit_test_teardown(second_daemon_on_same_storage_refused, cleanup),
        cmocka_unit_test_teardown(queued_reconstructions_resumed, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
