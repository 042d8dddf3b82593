/* daemon/queue.c — bounded FIFO: a ring of pointers under one mutex, two condition variables. */
#include "daemon/queue.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/error.h"

struct scicapd_queue {
    pthread_mutex_t mu;
    pthread_cond_t nonempty, nonfull;
    void **ring;
    int cap, alloc, head, len, closed;
};

int scicapd_queue_new(scicapd_queue **out, int capacity)
{
    scicapd_queue *q = calloc(1, sizeof *q);
    if (!q || capacity < 1 || !(q->ring = calloc((size_t)capacity, sizeof *q->ring))) {
        free(q);
        return -ENOMEM;
    }
    q->cap = q->alloc = capacity;
    pthread_mutex_init(&q->mu, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&q->nonempty, &ca);
    pthread_cond_init(&q->nonfull, &ca);
    pthread_condattr_destroy(&ca);
    *out = q;
    return 0;
}

void scicapd_queue_free(scicapd_queue *q)
{
    if (!q)
        return;
    pthread_mutex_destroy(&q->mu);
    pthread_cond_destroy(&q->nonempty);
    pthread_cond_destroy(&q->nonfull);
    free(q->ring);
    free(q);
}

static void put(scicapd_queue *q, void *item)
{
    q->ring[(q->head + q->len) % q->alloc] = item;
    q->len++;
    pthread_cond_signal(&q->nonempty);
}

int scicapd_queue_push(scicapd_queue *q, void *item)
{
    int rc = 0;
    pthread_mutex_lock(&q->mu);
    if (q->closed)
        rc = -EPIPE;
    else if (q->len >= q->cap)
        rc = SCI_EBUSY;
    else
        put(q, item);
    pthread_mutex_unlock(&q->mu);
    return rc;
}

int scicapd_queue_push_wait(scicapd_queue *q, void *item)
{
    int rc = 0;
    pthread_mutex_lock(&q->mu);
    while (!q->closed && q->len >= q->cap)
        pthread_cond_wait(&q->nonfull, &q->mu);
    if (q->closed)
        rc = -EPIPE;
    else
        put(q, item);
    pthread_mutex_unlock(&q->mu);
    return rc;
}

static void *get(scicapd_queue *q)
{
    void *item = q->ring[q->head];
    q->head = (q->head + 1) % q->alloc;
    q->len--;
    pthread_cond_signal(&q->nonfull);
    return item;
}

void *scicapd_queue_pop(scicapd_queue *q, int64_t timeout_ns)
{
    struct timespec until;
    clock_gettime(CLOCK_MONOTONIC, &until);
    if (timeout_ns >= 0) {
        until.tv_sec += timeout_ns / 1000000000;
        until.tv_nsec += timeout_ns % 1000000000;
        if (until.tv_nsec >= 1000000000) {
            until.tv_sec++;
            until.tv_nsec -= 1000000000;
        }
    }
    void *item = NULL;
    pthread_mutex_lock(&q->mu);
    while (q->len == 0 && !q->closed) {
        if (timeout_ns < 0)
            pthread_cond_wait(&q->nonempty, &q->mu);
        else if (pthread_cond_timedwait(&q->nonempty, &q->mu, &until) == ETIMEDOUT)
            break;
    }
    if (q->len > 0)
        item = get(q);
    pthread_mutex_unlock(&q->mu);
    return item;
}

void *scicapd_queue_take(scicapd_queue *q)
{
    void *item = NULL;
    pthread_mutex_lock(&q->mu);
    if (q->len > 0)
        item = get(q);
    pthread_mutex_unlock(&q->mu);
    return item;
}

void scicapd_queue_close(scicapd_queue *q)
{
    pthread_mutex_lock(&q->mu);
    q->closed = 1;
    pthread_cond_broadcast(&q->nonempty);
    pthread_cond_broadcast(&q->nonfull);
    pthread_mutex_unlock(&q->mu);
}

int scicapd_queue_len(scicapd_queue *q)
{
    pthread_mutex_lock(&q->mu);
    int n = q->len;
    pthread_mutex_unlock(&q->mu);
    return n;
}

int scicapd_queue_capacity(scicapd_queue *q)
{
    pthread_mutex_lock(&q->mu);
    int n = q->cap;
    pthread_mutex_unlock(&q->mu);
    return n;
}

int scicapd_queue_resize(scicapd_queue *q, int capacity)
{
    if (capacity < 1)
        return -EINVAL;
    int rc = 0;
    pthread_mutex_lock(&q->mu);
    if (capacity > q->alloc) {
        void **r = calloc((size_t)capacity, sizeof *r);
        if (!r) {
            rc = -ENOMEM;
        } else {
            for (int i = 0; i < q->len; i++)
                r[i] = q->ring[(q->head + i) % q->alloc];
            free(q->ring);
            q->ring = r;
            q->head = 0;
            q->alloc = capacity;
        }
    }
    if (rc == 0) {
        q->cap = capacity;
        pthread_cond_broadcast(&q->nonfull);
    }
    pthread_mutex_unlock(&q->mu);
    return rc;
}
