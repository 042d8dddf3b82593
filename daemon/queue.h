/* daemon/queue.h — a bounded FIFO of pointers between threads (docs/architecture.md, Threads: bounded queues).
 *
 * Producers either refuse when full (scicapd_queue_push: SCI_EBUSY, the caller reports "busy" — never a silent
 * drop) or wait for room (scicapd_queue_push_wait, for hand-overs that must not lose data, e.g. snapshot → store).
 * Consumers block in scicapd_queue_pop. After scicapd_queue_close, pushes fail with -EPIPE and pop returns what
 * is left, then NULL. The queue does not own the items. Thread-safe; the lock is never held across I/O.
 */
#ifndef SCICAP_DAEMON_QUEUE_H
#define SCICAP_DAEMON_QUEUE_H

#include <stdint.h>

typedef struct scicapd_queue scicapd_queue;

/* capacity >= 1. -ENOMEM. */
int scicapd_queue_new(scicapd_queue **out, int capacity);
void scicapd_queue_free(scicapd_queue *q); /* items still queued are not freed */
/* 0, SCI_EBUSY when full, -EPIPE when closed. */
int scicapd_queue_push(scicapd_queue *q, void *item);
/* Waits for room. 0 or -EPIPE when closed. */
int scicapd_queue_push_wait(scicapd_queue *q, void *item);
/* Oldest item; waits up to timeout_ns (< 0: forever). NULL on timeout, or when closed and empty. */
void *scicapd_queue_pop(scicapd_queue *q, int64_t timeout_ns);
/* Remove and return the oldest item without waiting (NULL if empty): for draining on shutdown. */
void *scicapd_queue_take(scicapd_queue *q);
void scicapd_queue_close(scicapd_queue *q);
int scicapd_queue_len(scicapd_queue *q);
int scicapd_queue_capacity(scicapd_queue *q);
/* Change the capacity (reload); items beyond a smaller capacity stay queued. -ENOMEM. */
int scicapd_queue_resize(scicapd_queue *q, int capacity);

#endif
