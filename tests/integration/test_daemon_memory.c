/* Memory of closed connections is returned: 29 connections of root each pipeline status requests without reading
 * a reply, so the daemon buffers megabytes of output for each (within its 16 MiB per-connection bound); then they
 * close. scicapd's resident set (VmRSS of /proc/PID/status) must come back to within AFTER_MAX_MB of what it was
 * before, while the peak (VmHWM) shows the load did build up. Ordered, not timed: the daemon has read every
 * request when our sockets' queues are empty (SIOCOUTQ), and has freed the connections when its status counts
 * one client, ours. */
#include <errno.h>
#include <linux/sockios.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/ioctl.h>

#include <cmocka.h>

#include "tests/integration/daemon_harness.h"

/* Under AddressSanitizer scicapd's memory comes from ASan's allocator (freed blocks held in its quarantine, no
 * malloc_trim), so what goes back to the system after close is the glibc build's property: check-asan runs the load
 * for memory errors and checks the peak and that the daemon still answers, and says so. */
#include "tests/helpers/sanitized.h"

#define CONNS 29
#define ROUNDS 2
#define LINES 3000        /* status requests per connection */
#define PEAK_MIN_MB 64    /* the load must have cost at least this much, or the test tests nothing */
#define AFTER_MAX_MB 48   /* resident growth allowed once every connection closed */

static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

/* kB of `key` ("VmRSS:", "VmHWM:") in /proc/PID/status */
static long proc_kb(pid_t pid, const char *key)
{
    char p[64], line[256];
    snprintf(p, sizeof p, "/proc/%d/status", (int)pid);
    FILE *f = fopen(p, "r");
    assert_non_null(f);
    long kb = -1;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, key, strlen(key)))
            kb = strtol(line + strlen(key), NULL, 10);
    fclose(f);
    assert_true(kb >= 0);
    return kb;
}

/* the integer "clients" anywhere in v (status nests it), or -1 */
static long find_clients(const json_t *v)
{
    const char *k;
    json_t *x;
    json_object_foreach((json_t *)v, k, x) {
        if (!strcmp(k, "clients") && json_is_integer(x))
            return (long)json_integer_value(x);
        long n = json_is_object(x) ? find_clients(x) : -1;
        if (n >= 0)
            return n;
    }
    return -1;
}

static int clients_now(hconn *c)
{
    json_t *r = hconn_request(c, "status", NULL);
    int n = (int)find_clients(r);
    json_decref(r);
    return n;
}

/* Ask status until it counts n connections (others' closes are seen by the event loop in turn). */
static void wait_clients(hconn *me, int n)
{
    for (int t = 0; t < 300 && clients_now(me) != n; t++)
        h_sleep_ms(100);
    assert_int_equal(clients_now(me), n);
}

/* Pipeline LINES status requests on fd; stops early when the daemon stops reading (send times out). */
static int flood(int fd)
{
    struct timeval tv = {2, 0};
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    char line[96];
    int sent = 0;
    for (int i = 0; i < LINES; i++, sent++) {
        int n = snprintf(line, sizeof line, "{\"v\":1,\"id\":%d,\"cmd\":\"status\"}\n", i + 1);
        if (send(fd, line, (size_t)n, MSG_NOSIGNAL) != n)
            break;
    }
    return sent;
}

static void test_rss_returns_after_close(void **state)
{
    harness_start(&H, "{\"control\": {\"max_clients\": 64, \"max_per_uid\": 64}}\n", NULL);
    hconn me;
    hconn_open(&me, &H);
    wait_clients(&me, 1); /* the harness's probe connection gone */
    long base = proc_kb(H.pid, "VmRSS:");
    int total = 0;
    long during = 0;
    hconn late[ROUNDS];
    /* two rounds: freeing the first round's buffers raises glibc's mmap threshold, so the second's come from the
     * heap, which glibc keeps unless told to give it back */
    for (int round = 0; round < ROUNDS; round++) {
        int fds[CONNS];
        for (int i = 0; i < CONNS; i++) {
            fds[i] = h_connect_raw(H.sock);
            assert_true(fds[i] >= 0);
            total += flood(fds[i]);
        }
        for (int i = 0; i < CONNS; i++) { /* every request read by the daemon (bounded: it may stop reading) */
            int q = 1;
            for (int t = 0; t < 600 && q > 0; t++) {
                if (ioctl(fds[i], SIOCOUTQ, &q) != 0)
                    q = 0;
                if (q > 0)
                    h_sleep_ms(50);
            }
        }
        long now = proc_kb(H.pid, "VmRSS:");
        during = now > during ? now : during;
        /* another client connects while they are open and stays: its buffers, allocated after theirs, sit above
         * them on the heap, so their memory cannot go back by trimming the heap's top alone */
        hconn_open(&late[round], &H);
        json_decref(hconn_request(&late[round], "status", NULL));
        for (int i = 0; i < CONNS; i++)
            close(fds[i]);
        wait_clients(&me, 2 + round);
    }
    long after = proc_kb(H.pid, "VmRSS:"), peak = proc_kb(H.pid, "VmHWM:");
    print_message("  %d requests on %d connections (%d rounds); VmRSS %ld MB before, %ld MB with them open (peak %ld MB), "
                  "%ld MB after they closed\n", total, CONNS, ROUNDS, base / 1024, during / 1024, peak / 1024, after / 1024);
    assert_true(peak - base >= PEAK_MIN_MB * 1024L);
    if (SANITIZED) {
        print_message("  (AddressSanitizer build: its allocator keeps freed memory; the return is checked in the "
                      "optimised build)\n");
        json_t *st = hconn_request(&me, "status", NULL);
        assert_non_null(st);
        json_decref(st);
    } else {
        assert_true(after - base <= AFTER_MAX_MB * 1024L);
    }
    for (int r = 0; r < ROUNDS; r++)
        hconn_close(&late[r]);
    hconn_close(&me);
    harness_stop(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_rss_returns_after_close, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
