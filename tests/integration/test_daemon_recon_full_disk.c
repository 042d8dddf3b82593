/* A reconstruction that finds no room to be written (storage on a small tmpfs, filled by a file of the test's) is
 * not dropped: "recon.waiting" names ENOSPC, its queue entry stays under recon-queue/, and once the test frees the
 * room it is written (recon.done, a result.json) and its entry removed. Then the same with a user's cancel while
 * it waits: recon.canceled and the entry gone. Counted, not timed: events in their order on one connection. Needs
 * root (mount). */
#include <dirent.h>
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "tests/integration/daemon_harness.h"

static harness H;
static char filler[400];

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H); /* unmounts the store's tmpfs */
    memset(&H, 0, sizeof H);
    return 0;
}

/* Fill the store's file system but for `keep` bytes (enough for a queue entry, not for a reconstruction). */
static void fill_but(long keep)
{
    snprintf(filler, sizeof filler, "%s/filler", H.store);
    int fd = open(filler, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(fd >= 0);
    static char block[65536];
    off_t size = 0;
    for (;;) {
        ssize_t w = write(fd, block, sizeof block);
        if (w <= 0)
            break;
        size += w;
    }
    assert_int_equal(errno, ENOSPC);
    assert_true(size > keep);
    assert_int_equal(ftruncate(fd, size - keep), 0);
    close(fd);
}

static int queue_entries(void)
{
    char dir[400];
    snprintf(dir, sizeof dir, "%s/recon-queue", H.store);
    DIR *d = opendir(dir);
    assert_non_null(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        n += strncmp(e->d_name, "r-", 2) == 0 && strstr(e->d_name, ".json") != NULL;
    closedir(d);
    return n;
}

/* Start the daemon on a fresh 16 MiB tmpfs, store one capture, fill the disk and ask its reconstruction; returns
 * the job id with the first recon.waiting's error in why. */
static json_int_t start_waiting(hconn *c, char *cap, size_t ncap, char *why, size_t nwhy)
{
    harness_init(&H, NULL);
    harness_mount_store(&H, "16m");
    harness_spawn(&H, NULL);
    hconn_open(c, &H);
    json_decref(hconn_request(c, "capture", json_pack("{s:i, s:b}", "count", 1, "reconstruct", 0)));
    json_t *e = hconn_wait_event(c, "capture.stored", 60000);
    snprintf(cap, ncap, "%s", json_string_value(json_object_get(json_object_get(e, "data"), "capture")));
    json_decref(e);
    assert_true(cap[0] != '\0');
    fill_but(64 * 1024);
    json_t *r = hconn_request(c, "reconstruct", json_pack("{s:s, s:s, s:{s:i}}", "capture", cap, "method", "gap-tv",
                                                         "params", "iters", 3));
    json_int_t job = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    e = hconn_wait_event(c, "recon.waiting", 60000); /* fails on a recon.failed first */
    assert_int_equal(json_integer_value(json_object_get(e, "job")), job);
    snprintf(why, nwhy, "%s", json_string_value(json_object_get(json_object_get(e, "data"), "error")));
    json_decref(e);
    return job;
}

static void test_written_when_room_returns(void **state)
{
    harness_require_root("mount a small tmpfs");
    hconn c;
    char cap[64], why[512];
    json_int_t job = start_waiting(&c, cap, sizeof cap, why, sizeof why);
    print_message("  waiting: %s\n", why);
    assert_non_null(strstr(why, "No space left on device"));
    assert_int_equal(queue_entries(), 1); /* kept while it waits */
    assert_int_equal(unlink(filler), 0);
    json_t *e = hconn_wait_event(&c, "recon.done", 120000); /* fails on a recon.failed first */
    assert_int_equal(json_integer_value(json_object_get(e, "job")), job);
    assert_string_equal(json_string_value(json_object_get(json_object_get(e, "data"), "folder")), "gap-tv");
    json_decref(e);
    char p[700];
    snprintf(p, sizeof p, "%s/captures/%s/recon/gap-tv/result.json", H.store, cap);
    json_t *res = json_load_file(p, 0, NULL);
    if (!res)
        fail_msg("no %s", p);
    json_decref(res);
    assert_int_equal(queue_entries(), 0);
    hconn_close(&c);
    harness_stop(&H);
}

static void test_cancel_while_waiting(void **state)
{
    harness_require_root("mount a small tmpfs");
    hconn c;
    char cap[64], why[512];
    json_int_t job = start_waiting(&c, cap, sizeof cap, why, sizeof why);
    assert_int_equal(queue_entries(), 1);
    json_decref(hconn_request(&c, "cancel", json_pack("{s:I}", "job", job)));
    json_t *e = hconn_wait_event(&c, "recon.canceled", 60000);
    assert_int_equal(json_integer_value(json_object_get(e, "job")), job);
    json_decref(e);
    assert_int_equal(queue_entries(), 0);
    char p[700];
    snprintf(p, sizeof p, "%s/captures/%s/recon/gap-tv", H.store, cap);
    struct stat sb;
    assert_int_not_equal(stat(p, &sb), 0); /* nothing published */
    hconn_close(&c);
    harness_stop(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_written_when_room_returns, cleanup),
        cmocka_unit_test_teardown(test_cancel_while_waiting, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
