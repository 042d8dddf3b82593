/* daemon/loop.c — the event loop (see the header). */
#include "daemon/loop.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"

enum { ENTRY_FD, ENTRY_POLLER, ENTRY_TIMER };

typedef struct entry {
    int id;                  /* 0: deleted (removed after the turn) */
    int kind;
    void *user;
    /* fd */
    int fd;
    short events;
    scicapd_loop_fd_fn on_fd;
    /* poller */
    scicapd_loop_fill_fn fill;
    scicapd_loop_dispatch_fn dispatch;
    scicapd_loop_deadline_fn deadline;
    /* timer */
    scicapd_loop_timer_fn on_timer;
    int64_t due_ns;
    /* this turn: its pollfds */
    int first, n;
} entry;

struct scicapd_loop {
    entry *e;
    int len, cap;
    int next_id;
    struct pollfd *pfd;      /* grows to what the entries need */
    int pfd_cap;
    int max_wait_ms;
    int stop;
    scicapd_loop_after_fn after;
    void *after_user;
};

int scicapd_loop_new(scicapd_loop **out, int max_wait_ms)
{
    scicapd_loop *l = calloc(1, sizeof *l);
    if (!l)
        return -ENOMEM;
    l->max_wait_ms = max_wait_ms > 0 ? max_wait_ms : 1000;
    l->next_id = 1;
    *out = l;
    return 0;
}

void scicapd_loop_free(scicapd_loop *l)
{
    if (!l)
        return;
    free(l->e);
    free(l->pfd);
    free(l);
}

static entry *entry_add(scicapd_loop *l, int kind, void *user)
{
    if (l->len == l->cap) {
        int cap = l->cap ? 2 * l->cap : 8;
        entry *e = realloc(l->e, (size_t)cap * sizeof *e);
        if (!e)
            return NULL;
        l->e = e;
        l->cap = cap;
    }
    entry *e = &l->e[l->len++];
    *e = (entry){.id = l->next_id++, .kind = kind, .user = user};
    return e;
}

int scicapd_loop_add_fd(scicapd_loop *l, int fd, short events, scicapd_loop_fd_fn fn, void *user)
{
    entry *e = entry_add(l, ENTRY_FD, user);
    if (!e)
        return -ENOMEM;
    e->fd = fd;
    e->events = events;
    e->on_fd = fn;
    return e->id;
}

int scicapd_loop_add_poller(scicapd_loop *l, scicapd_loop_fill_fn fill, scicapd_loop_dispatch_fn dispatch,
                            scicapd_loop_deadline_fn deadline, void *user)
{
    entry *e = entry_add(l, ENTRY_POLLER, user);
    if (!e)
        return -ENOMEM;
    e->fill = fill;
    e->dispatch = dispatch;
    e->deadline = deadline;
    return e->id;
}

int scicapd_loop_add_timer(scicapd_loop *l, int delay_ms, scicapd_loop_timer_fn fn, void *user)
{
    entry *e = entry_add(l, ENTRY_TIMER, user);
    if (!e)
        return -ENOMEM;
    e->on_timer = fn;
    e->due_ns = sci_clock_mono_ns() + (int64_t)(delay_ms > 0 ? delay_ms : 0) * 1000000;
    return e->id;
}

void scicapd_loop_del(scicapd_loop *l, int id)
{
    for (int i = 0; i < l->len; i++)
        if (l->e[i].id == id && id > 0)
            l->e[i].id = 0;
}

void scicapd_loop_set_after(scicapd_loop *l, scicapd_loop_after_fn fn, void *user)
{
    l->after = fn;
    l->after_user = user;
}

int scicapd_loop_count(const scicapd_loop *l)
{
    int n = 0;
    for (int i = 0; i < l->len; i++)
        n += l->e[i].id != 0;
    return n;
}

void scicapd_loop_stop(scicapd_loop *l) { l->stop = 1; }

static int pfd_grow(scicapd_loop *l, int need)
{
    if (need <= l->pfd_cap)
        return 0;
    int cap = l->pfd_cap ? l->pfd_cap : 16;
    while (cap < need)
        cap *= 2;
    struct pollfd *p = realloc(l->pfd, (size_t)cap * sizeof *p);
    if (!p)
        return -ENOMEM;
    l->pfd = p;
    l->pfd_cap = cap;
    return 0;
}

/* The pollfds of every entry, in registration order; a poller that fills all it was given gets a larger array.
 * Returns how many, or -ENOMEM. */
static int fill_all(scicapd_loop *l)
{
    int k = 0;
    for (int i = 0; i < l->len; i++) {
        entry *e = &l->e[i];
        e->first = k;
        e->n = 0;
        if (!e->id || e->kind == ENTRY_TIMER)
            continue;
        if (pfd_grow(l, k + 1) < 0)
            return -ENOMEM;
        if (e->kind == ENTRY_FD) {
            l->pfd[k++] = (struct pollfd){.fd = e->fd, .events = e->events};
            e->n = 1;
            continue;
        }
        for (;;) {
            int room = l->pfd_cap - k;
            int n = e->fill(e->user, l->pfd + k, room);
            if (n < room) {
                e->n = n;
                k += n;
                break;
            }
            if (pfd_grow(l, 2 * l->pfd_cap) < 0)
                return -ENOMEM;
        }
    }
    return k;
}

/* The wait of this turn: max_wait_ms, or the nearest timer or poller deadline, or wait_ms when shorter. */
static int turn_timeout(const scicapd_loop *l, int wait_ms, int64_t now)
{
    int t = l->max_wait_ms;
    if (wait_ms >= 0 && wait_ms < t)
        t = wait_ms;
    for (int i = 0; i < l->len; i++) {
        const entry *e = &l->e[i];
        int d = -1;
        if (!e->id)
            continue;
        if (e->kind == ENTRY_TIMER)
            d = e->due_ns <= now ? 0 : (int)((e->due_ns - now + 999999) / 1000000);
        else if (e->kind == ENTRY_POLLER && e->deadline)
            d = e->deadline(e->user, now);
        if (d >= 0 && d < t)
            t = d;
    }
    return t;
}

static void run_timers(scicapd_loop *l, int len)
{
    int64_t now = sci_clock_mono_ns();
    for (int i = 0; i < len; i++) {
        if (!l->e[i].id || l->e[i].kind != ENTRY_TIMER || l->e[i].due_ns > now)
            continue;
        int next = l->e[i].on_timer(l->e[i].user); /* may add entries: l->e may move */
        if (!l->e[i].id)
            continue; /* deleted itself */
        if (next < 0)
            l->e[i].id = 0;
        else
            l->e[i].due_ns = sci_clock_mono_ns() + (int64_t)next * 1000000;
    }
}

/* Entries deleted this turn leave the table. */
static void compact(scicapd_loop *l)
{
    int k = 0;
    for (int i = 0; i < l->len; i++)
        if (l->e[i].id)
            l->e[k++] = l->e[i];
    l->len = k;
}

int scicapd_loop_turn(scicapd_loop *l, int wait_ms)
{
    int n = fill_all(l);
    if (n < 0)
        return n;
    int len = l->len; /* entries added by callbacks wait for the next turn */
    int pr = poll(l->pfd, (nfds_t)n, turn_timeout(l, wait_ms, sci_clock_mono_ns()));
    if (pr < 0 && errno != EINTR)
        return -errno;
    for (int i = 0; pr > 0 && i < len; i++) {
        entry *e = &l->e[i];
        if (!e->id || e->n == 0)
            continue;
        if (e->kind == ENTRY_FD && l->pfd[e->first].revents)
            e->on_fd(e->user, e->fd, l->pfd[e->first].revents);
        else if (e->kind == ENTRY_POLLER)
            e->dispatch(e->user, l->pfd + e->first, e->n);
    }
    run_timers(l, len);
    if (l->after)
        l->after(l->after_user);
    compact(l);
    return 0;
}

int scicapd_loop_run(scicapd_loop *l)
{
    l->stop = 0;
    while (!l->stop) {
        int rc = scicapd_loop_turn(l, -1);
        if (rc < 0)
            return rc;
    }
    return 0;
}
