/* daemon/loop.h — scicapd's event loop as an object: file descriptors, fd sets and timers registered by id, one
 * poll(2) per turn, a hook after each turn.
 *
 *   fds      one descriptor and the events to wait for; its callback gets the revents.
 *   pollers  a set of descriptors a module keeps itself (the control socket's listener and connections,
 *            daemon/control.h): asked to fill pollfds before each poll and handed their revents after it, with
 *            the time to its own nearest deadline. The loop's array grows to what they need: no fixed size.
 *   timers   a callback due after a delay; it returns the delay to its next run (ms), or -1 to end.
 *   after    called once after every turn, whatever woke the loop (the daemon delivers its mail and does its
 *            housekeeping there).
 * A turn waits at most max_wait_ms (scicapd_loop_new), less when a timer or a poller's deadline is nearer.
 *
 *     scicapd_loop *l;
 *     scicapd_loop_new(&l, 1000);
 *     int id = scicapd_loop_add_fd(l, sfd, POLLIN, on_signal, d);
 *     scicapd_loop_add_timer(l, 0, on_tick, d);
 *     scicapd_loop_run(l);              // until a callback calls scicapd_loop_stop
 *     scicapd_loop_free(l);
 *
 * Ids are positive and never reused within one loop. The loop does not own the descriptors. One thread only:
 * the loop's; callbacks may add and delete entries (their own too) and stop the loop. Errors: 0 or -errno.
 */
#ifndef SCICAP_DAEMON_LOOP_H
#define SCICAP_DAEMON_LOOP_H

#include <poll.h>
#include <stdint.h>

typedef struct scicapd_loop scicapd_loop;

typedef void (*scicapd_loop_fd_fn)(void *user, int fd, short revents);
/* Fill up to max pollfds; returns how many (returning max asks for a larger array: the loop grows and asks again). */
typedef int (*scicapd_loop_fill_fn)(void *user, struct pollfd *fds, int max);
/* The revents of the n pollfds filled last; called only when poll reported a ready descriptor. */
typedef void (*scicapd_loop_dispatch_fn)(void *user, const struct pollfd *fds, int n);
/* Milliseconds from now_ns (CLOCK_MONOTONIC) to the set's nearest deadline, 0 if passed, -1 when none. */
typedef int (*scicapd_loop_deadline_fn)(void *user, int64_t now_ns);
/* A timer's run; returns the delay to the next run in ms (>= 0), or -1 to delete the timer. */
typedef int (*scicapd_loop_timer_fn)(void *user);
typedef void (*scicapd_loop_after_fn)(void *user);

/* max_wait_ms: the longest a turn waits (> 0). -ENOMEM. */
int scicapd_loop_new(scicapd_loop **out, int max_wait_ms);
void scicapd_loop_free(scicapd_loop *l); /* NULL is harmless */

/* Register fd for `events` (POLLIN, POLLOUT). Returns the id (> 0) or -ENOMEM. */
int scicapd_loop_add_fd(scicapd_loop *l, int fd, short events, scicapd_loop_fd_fn fn, void *user);
/* Register a set of descriptors (deadline may be NULL). Returns the id (> 0) or -ENOMEM. */
int scicapd_loop_add_poller(scicapd_loop *l, scicapd_loop_fill_fn fill, scicapd_loop_dispatch_fn dispatch,
                            scicapd_loop_deadline_fn deadline, void *user);
/* A timer first due after delay_ms (0: at the end of the next turn). Returns the id (> 0) or -ENOMEM. */
int scicapd_loop_add_timer(scicapd_loop *l, int delay_ms, scicapd_loop_timer_fn fn, void *user);
/* Remove entry `id` (fd, poller or timer); an unknown id is ignored. */
void scicapd_loop_del(scicapd_loop *l, int id);
/* Called after every turn (NULL: none). */
void scicapd_loop_set_after(scicapd_loop *l, scicapd_loop_after_fn fn, void *user);

/* One turn: poll (at most max_wait_ms, or wait_ms when >= 0 and shorter), then the callbacks of ready fds, the
 * pollers' dispatch, due timers, the after hook. Returns 0, or -errno when poll fails (EINTR is not a failure). */
int scicapd_loop_turn(scicapd_loop *l, int wait_ms);
/* Turns until scicapd_loop_stop. 0, or -errno from poll. */
int scicapd_loop_run(scicapd_loop *l);
void scicapd_loop_stop(scicapd_loop *l);
/* Number of registered entries (fds, pollers, timers). */
int scicapd_loop_count(const scicapd_loop *l);

#endif
