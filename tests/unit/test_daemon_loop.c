/* tests/unit/test_daemon_loop.c — scicapd's event loop (daemon/loop.h): fds by id reach their callbacks and leave
 * when deleted, a poller with more descriptors than the loop's first array gets them all, timers run in order
 * of their delays and end when they say so, the after hook runs once per turn, stop ends run. Counts and orders
 * only: no assertion on how long anything took. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "daemon/loop.h"

typedef struct counts {
    int fd_calls, last_fd, after, timer_a, timer_b, order[8], norder;
    scicapd_loop *l;
    int self_id;
} counts;

static void on_fd(void *user, int fd, short revents)
{
    counts *c = user;
    char b[16];
    assert_true(revents & POLLIN);
    assert_true(read(fd, b, sizeof b) > 0);
    c->fd_calls++;
    c->last_fd = fd;
}

static void on_after(void *user) { ((counts *)user)->after++; }

static void test_fd_by_id(void **state)
{
    (void)state;
    scicapd_loop *l;
    counts c = {0};
    int p1[2], p2[2];
    assert_int_equal(pipe(p1), 0);
    assert_int_equal(pipe(p2), 0);
    assert_int_equal(scicapd_loop_new(&l, 50), 0);
    int a = scicapd_loop_add_fd(l, p1[0], POLLIN, on_fd, &c), b = scicapd_loop_add_fd(l, p2[0], POLLIN, on_fd, &c);
    assert_true(a > 0 && b > 0 && a != b);
    scicapd_loop_set_after(l, on_after, &c);
    assert_int_equal(write(p2[1], "x", 1), 1);
    assert_int_equal(scicapd_loop_turn(l, -1), 0);
    assert_int_equal(c.fd_calls, 1);
    assert_int_equal(c.last_fd, p2[0]);
    assert_int_equal(c.after, 1);
    /* deleted: its readiness is no longer seen; the other still is */
    scicapd_loop_del(l, b);
    assert_int_equal(scicapd_loop_count(l), 1);
    assert_int_equal(write(p2[1], "y", 1), 1);
    assert_int_equal(write(p1[1], "z", 1), 1);
    assert_int_equal(scicapd_loop_turn(l, 0), 0);
    assert_int_equal(c.fd_calls, 2);
    assert_int_equal(c.last_fd, p1[0]);
    assert_int_equal(scicapd_loop_count(l), 1);
    /* nothing ready: the turn times out and the after hook still runs */
    assert_int_equal(scicapd_loop_turn(l, 0), 0);
    assert_int_equal(c.fd_calls, 2);
    assert_int_equal(c.after, 3);
    scicapd_loop_del(l, 12345); /* unknown: ignored */
    scicapd_loop_free(l);
    close(p1[0]), close(p1[1]), close(p2[0]), close(p2[1]);
}

/* A set of 300 pipes, more than the loop's first array: every one is filled and dispatched. */
typedef struct set {
    int r[300], w[300], n, fills, seen;
} set;

static int set_fill(void *user, struct pollfd *fds, int max)
{
    set *s = user;
    s->fills++;
    int k = 0;
    for (; k < s->n && k < max; k++)
        fds[k] = (struct pollfd){.fd = s->r[k], .events = POLLIN};
    return k;
}

static void set_dispatch(void *user, const struct pollfd *fds, int n)
{
    set *s = user;
    assert_int_equal(n, s->n);
    for (int i = 0; i < n; i++) {
        assert_int_equal(fds[i].fd, s->r[i]);
        s->seen += (fds[i].revents & POLLIN) != 0;
    }
}

static int set_deadline(void *user, int64_t now_ns) { return 0; }

static void test_poller_grows(void **state)
{
    (void)state;
    set *s = calloc(1, sizeof *s);
    assert_non_null(s);
    s->n = 300;
    for (int i = 0; i < s->n; i++) {
        int p[2];
        assert_int_equal(pipe(p), 0);
        s->r[i] = p[0];
        s->w[i] = p[1];
        assert_int_equal(write(p[1], "x", 1), 1);
    }
    scicapd_loop *l;
    assert_int_equal(scicapd_loop_new(&l, 1000), 0);
    assert_true(scicapd_loop_add_poller(l, set_fill, set_dispatch, set_deadline, s) > 0);
    assert_int_equal(scicapd_loop_turn(l, -1), 0);
    assert_int_equal(s->seen, 300);
    assert_true(s->fills >= 2); /* asked again with a larger array */
    int fills = s->fills;
    assert_int_equal(scicapd_loop_turn(l, -1), 0);
    assert_int_equal(s->fills, fills + 1); /* the array kept its size */
    scicapd_loop_free(l);
    for (int i = 0; i < s->n; i++)
        close(s->r[i]), close(s->w[i]);
    free(s);
}

static int timer_a(void *user)
{
    counts *c = user;
    c->order[c->norder++] = 'a';
    return ++c->timer_a < 3 ? 0 : -1; /* three runs, then ends */
}

static int timer_b(void *user)
{
    counts *c = user;
    c->order[c->norder++] = 'b';
    c->timer_b++;
    if (c->timer_a == 3) {
        scicapd_loop_del(c->l, c->self_id); /* deletes itself */
        scicapd_loop_stop(c->l);
    }
    return 0;
}

static int timer_late(void *user)
{
    fail_msg("a timer a minute away ran");
    return -1;
}

static void test_timers(void **state)
{
    (void)state;
    scicapd_loop *l;
    counts c = {0};
    assert_int_equal(scicapd_loop_new(&l, 1000), 0);
    c.l = l;
    assert_true(scicapd_loop_add_timer(l, 0, timer_a, &c) > 0);
    c.self_id = scicapd_loop_add_timer(l, 0, timer_b, &c);
    assert_true(c.self_id > 0);
    int late = scicapd_loop_add_timer(l, 60000, timer_late, &c);
    assert_true(late > 0);
    scicapd_loop_set_after(l, on_after, &c);
    assert_int_equal(scicapd_loop_run(l), 0); /* ends when b stops it, in the third turn */
    assert_int_equal(c.timer_a, 3);
    assert_int_equal(c.timer_b, 3);
    assert_int_equal(c.norder, 6);
    assert_memory_equal(c.order, ((int[]){'a', 'b', 'a', 'b', 'a', 'b'}), 6 * sizeof(int)); /* registration order */
    assert_int_equal(c.after, 3);
    assert_int_equal(scicapd_loop_count(l), 1); /* a ended, b deleted itself, the late one waits */
    scicapd_loop_del(l, late);
    assert_int_equal(scicapd_loop_turn(l, 0), 0);
    assert_int_equal(scicapd_loop_count(l), 0);
    scicapd_loop_free(l);
    scicapd_loop_free(NULL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fd_by_id),
        cmocka_unit_test(test_poller_grows),
        cmocka_unit_test(test_timers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
