/* daemon/control.h — the control socket: a listening Unix stream socket and its connections.
 *
 * The socket is created at `path` (a stale socket left by a crash is removed; a live one is an error: another
 * scicapd runs), given `mode` and group `group` (when the group exists and the process may chown), and
 * listened on. Each connection's peer credentials (SO_PEERCRED: pid, uid, gid) are taken at accept and logged.
 * Input is split into lines of at most max_line bytes; each complete line goes to on_line. A longer line is
 * answered "too_long" (check 1 of daemon/protocol.h) and skipped up to its newline; the connection stays.
 * Beyond max_clients a new connection gets one "busy" line and is closed. Output is buffered per connection
 * and written as the socket accepts it (never blocks the loop); a client that lets more than 16 MiB pile up is
 * disconnected (logged). Used only from the event-loop thread.
 */
#ifndef SCICAP_DAEMON_CONTROL_H
#define SCICAP_DAEMON_CONTROL_H

#include <poll.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "base/error.h"
#include "base/log.h"

typedef struct scicapd_client {
    uint64_t id;        /* 1, 2, ... never reused within a run */
    int fd;
    pid_t pid;
    uid_t uid;
    gid_t gid;
    int watching;       /* receives every event */
    char *in;           /* partial input line */
    size_t in_len;
    int skipping;       /* discarding the rest of an oversized line */
    char *out;          /* pending output */
    size_t out_len, out_off, out_cap;
    int closing;        /* close once the output is written */
} scicapd_client;

typedef struct scicapd_control scicapd_control;

/* A complete request line (without its newline). The client may be sent replies to from inside. */
typedef void (*scicapd_line_fn)(void *user, scicapd_client *c, const char *line, size_t len);

int scicapd_control_open(scicapd_control **out, const char *path, unsigned mode, const char *group,
                         int max_clients, size_t max_line, const sci_log *log, scicapd_line_fn on_line, void *user,
                         sci_error *err);
/* Closes every connection and removes the socket file. NULL is harmless. */
void scicapd_control_close(scicapd_control *ctl);
void scicapd_control_set_limits(scicapd_control *ctl, int max_clients, size_t max_line);

/* Fill up to max pollfds (listening socket first, then the connections). Returns how many. */
int scicapd_control_pollfds(scicapd_control *ctl, struct pollfd *fds, int max);
/* Handle the revents of the n pollfds filled by the last scicapd_control_pollfds. */
void scicapd_control_dispatch(scicapd_control *ctl, const struct pollfd *fds, int n);

/* Queue `line` (newline-terminated) for connection `client`; ignored if it is gone. */
void scicapd_control_send(scicapd_control *ctl, uint64_t client, const char *line);
void scicapd_control_send_to(scicapd_control *ctl, scicapd_client *c, const char *line);
/* To every watching connection except `except` (0: none). */
void scicapd_control_broadcast(scicapd_control *ctl, const char *line, uint64_t except);
int scicapd_control_clients(const scicapd_control *ctl);
/* Stop accepting (shutdown): close the listening socket, keep the connections to say goodbye. */
void scicapd_control_stop_listening(scicapd_control *ctl);
/* Pending output on any connection? */
int scicapd_control_flushing(const scicapd_control *ctl);

#endif
