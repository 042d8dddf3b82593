/* daemon/web_events.h — the web view's event ring: the daemon's event lines kept for the open SSE streams.
 *
 *     web_events *ev;  web_events_new(&ev, 256);
 *     web_events_push(ev, line);                     // event loop: copies the line, wakes the streams
 *     web_stream *s = web_stream_new(ev, 5000);      // per /api/events response
 *     ssize_t n = web_stream_read(s, buf, max);      // blocks up to keepalive_ms; 0 never returned
 *     web_stream_free(s);
 *     web_events_close(ev);                          // every reader returns -1 (end of stream)
 *     web_events_free(ev);
 *
 * Each event is sent as "id: SEQ\ndata: JSON\n\n"; a keep-alive comment (": k\n\n") after keepalive_ms of
 * silence keeps idle streams under the server's connection timeout. A stream that fell more than the ring's
 * capacity behind is sent "event: reset" (the page then reloads /api/state) and goes on from the newest.
 * Thread-safe: one mutex and one condition variable; push never waits for a reader.
 */
#ifndef SCICAP_DAEMON_WEB_EVENTS_H
#define SCICAP_DAEMON_WEB_EVENTS_H

#include <stddef.h>
#include <sys/types.h>

typedef struct web_events web_events;
typedef struct web_stream web_stream;

/* capacity: events kept (>= 1). 0 or -ENOMEM. */
int web_events_new(web_events **out, int capacity);
/* Copy `line` (JSON, a trailing newline is dropped) into the ring. Allocation failure drops the event. */
void web_events_push(web_events *ev, const char *line);
/* Wake every reader and make them end their streams. */
void web_events_close(web_events *ev);
/* NULL is harmless; the streams must be freed before. */
void web_events_free(web_events *ev);

/* A reader starting after the newest event. NULL on allocation failure. */
web_stream *web_stream_new(web_events *ev, int keepalive_ms);
/* Up to max bytes of the stream into buf: > 0 bytes, or -1 when the ring was closed. Blocks until an event or
 * the keep-alive is due. */
ssize_t web_stream_read(web_stream *s, char *buf, size_t max);
void web_stream_free(web_stream *s);

#endif
