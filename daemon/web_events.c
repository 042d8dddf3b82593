/* daemon/web_events.c — the ring of event lines behind /api/events (see web_events.h). */
#include "daemon/web_events.h"

#include <errno.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct web_events {
    pthread_mutex_t mu;
    pthread_cond_t cv;      /* CLOCK_MONOTONIC */
    char **line;            /* ring of capacity entries; slot of seq s is s % capacity */
    int capacity;
    uint64_t next;          /* sequence number of the next event pushed; 1 for the first */
    int closed;
};

struct web_stream {
    web_events *ev;
    int keepalive_ms;
    uint64_t seq;           /* next event to send */
    char *pending;          /* formatted text not yet handed out */
    size_t len, off;
};

int web_events_new(web_events **out, int capacity)
{
    web_events *ev = calloc(1, sizeof *ev);
    if (!ev || !(ev->line = calloc((size_t)capacity, sizeof *ev->line))) {
        free(ev);
        return -ENOMEM;
    }
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&ev->cv, &ca);
    pthread_condattr_destroy(&ca);
    pthread_mutex_init(&ev->mu, NULL);
    ev->capacity = capacity;
    ev->next = 1;
    *out = ev;
    return 0;
}

void web_events_push(web_events *ev, const char *line)
{
    size_t n = strlen(line);
    while (n > 0 && (line[n - 1] == '\n' || line[n - 1] == '\r'))
        n--;
    char *copy = strndup(line, n); /* outside the lock: the readers wait only for the swap */
    if (!copy)
        return;
    pthread_mutex_lock(&ev->mu);
    char **slot = &ev->line[ev->next % (uint64_t)ev->capacity];
    char *old = *slot;
    *slot = copy;
    ev->next++;
    pthread_cond_broadcast(&ev->cv);
    pthread_mutex_unlock(&ev->mu);
    free(old);
}

void web_events_close(web_events *ev)
{
    pthread_mutex_lock(&ev->mu);
    ev->closed = 1;
    pthread_cond_broadcast(&ev->cv);
    pthread_mutex_unlock(&ev->mu);
}

void web_events_free(web_events *ev)
{
    if (!ev)
        return;
    for (int i = 0; i < ev->capacity; i++)
        free(ev->line[i]);
    free(ev->line);
    pthread_cond_destroy(&ev->cv);
    pthread_mutex_destroy(&ev->mu);
    free(ev);
}

web_stream *web_stream_new(web_events *ev, int keepalive_ms)
{
    web_stream *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->ev = ev;
    s->keepalive_ms = keepalive_ms;
    pthread_mutex_lock(&ev->mu);
    s->seq = ev->next;
    pthread_mutex_unlock(&ev->mu);
    /* a first comment at once: the browser's EventSource reports "open" without waiting for an event */
    s->pending = strdup(": scicapd events\n\n");
    s->len = s->pending ? strlen(s->pending) : 0;
    return s;
}

/* Format what is due into s->pending (held under the lock). 0, or -1 when closed. */
static int stream_fill(web_stream *s)
{
    web_events *ev = s->ev;
    struct timespec until;
    clock_gettime(CLOCK_MONOTONIC, &until);
    until.tv_sec += s->keepalive_ms / 1000;
    until.tv_nsec += (long)(s->keepalive_ms % 1000) * 1000000L;
    if (until.tv_nsec >= 1000000000L) {
        until.tv_sec++;
        until.tv_nsec -= 1000000000L;
    }
    pthread_mutex_lock(&ev->mu);
    while (!ev->closed && s->seq == ev->next)
        if (pthread_cond_timedwait(&ev->cv, &ev->mu, &until) == ETIMEDOUT)
            break;
    if (ev->closed) {
        pthread_mutex_unlock(&ev->mu);
        return -1;
    }
    char *text = NULL;
    if (s->seq == ev->next) {
        text = strdup(": k\n\n");
    } else if (ev->next - s->seq > (uint64_t)ev->capacity) {
        s->seq = ev->next; /* overwritten before this stream read them */
        text = strdup("event: reset\ndata: {}\n\n");
    } else {
        const char *l = ev->line[s->seq % (uint64_t)ev->capacity];
        size_t n = strlen(l) + 48;
        if ((text = malloc(n)))
            snprintf(text, n, "id: %llu\ndata: %s\n\n", (unsigned long long)s->seq, l);
        s->seq++;
    }
    pthread_mutex_unlock(&ev->mu);
    free(s->pending);
    s->pending = text;
    s->len = text ? strlen(text) : 0;
    s->off = 0;
    return text ? 0 : -1;
}

ssize_t web_stream_read(web_stream *s, char *buf, size_t max)
{
    if (s->off >= s->len && stream_fill(s) < 0)
        return -1;
    size_t n = s->len - s->off < max ? s->len - s->off : max;
    memcpy(buf, s->pending + s->off, n);
    s->off += n;
    return (ssize_t)n;
}

void web_stream_free(web_stream *s)
{
    if (!s)
        return;
    free(s->pending);
    free(s);
}
