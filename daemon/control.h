/* daemon/control.h — the control socket: a listening Unix stream socket and its connections.
 *
 * The socket is created at `path`. What may stand there first: nothing, or a socket nobody listens on (left by a
 * crash: removed and replaced). A live socket is an error (another scicapd runs); so is anything else — a
 * regular file, a folder, a symlink, a device — which is never removed (-EEXIST naming what is there). The
 * socket gets `mode` and group `group` (when the group exists and the process may chown), and is listened on.
 * Each connection's peer credentials (SO_PEERCRED: pid, uid, gid) are taken at accept and logged.
 * Input is split into lines of at most max_line bytes; each complete line goes to on_line. A longer line is
 * answered "too_long" (check 1 of daemon/protocol.h) and skipped up to its newline; the connection stays.
 * Descriptors a peer passes (SCM_RIGHTS, sent with the first byte of a request line in one sendmsg) wait in the
 * connection until its line is complete; on_line may take them (scicapd_client_take_fds), and whatever it does
 * not take is closed when it returns, so a descriptor never outlives the request it came with.
 * Output is buffered per connection and written as the socket accepts it (never blocks the loop); a client that
 * lets more than 16 MiB pile up is disconnected (logged). Used only from the event-loop thread.
 *
 * Slots and deadlines (what sshd's MaxStartups/LoginGraceTime and chrony's command limits do): at most
 * max_clients connections, of which admin_slots are kept for peers hooks.is_admin accepts — beyond
 * max_clients - admin_slots an ordinary peer gets one "busy" line and is closed, an admin still gets in. A
 * request line must be complete within request_timeout_ms of its first byte (the first request: of the
 * connect), whether the bytes trickle or stop; a connection that is not watching and for which hooks.busy says
 * nothing is in flight is closed idle_timeout_ms after its last request (0: never). Either deadline answers one
 * "timeout" line and closes. So a peer that holds slots without finishing requests holds them for at most
 * request_timeout_ms, and never the admin ones unless it is an admin itself. One ordinary uid holds at most
 * max_per_uid connections (sshd's per-source limit): the next gets "busy" naming the cap, so one user's watches
 * cannot fill the slots of the others. A connection whose output has waited stall_timeout_ms without the peer
 * reading a byte (a watcher that stopped reading) is closed, so a watch never holds a slot forever for nothing. Deadlines are checked by
 * scicapd_control_expire; scicapd_control_next_deadline_ms says how long the loop may sleep.
 */
#ifndef SCICAP_DAEMON_CONTROL_H
#define SCICAP_DAEMON_CONTROL_H

#include <poll.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "base/error.h"
#include "base/log.h"

#define SCICAPD_CLIENT_MAX_FDS 253 /* the kernel's SCM_MAX_FD: what one sendmsg can carry */

typedef struct scicapd_client {
    uint64_t id;        /* 1, 2, ... never reused within a run */
    int fd;
    pid_t pid;
    uid_t uid;
    gid_t gid;
    int admin;          /* hooks.is_admin said yes at accept (kept for the connection's life) */
    int watching;       /* receives events (every one for an admin, its own uid's otherwise) */
    int64_t line_start_ns; /* CLOCK_MONOTONIC: connect, or first byte of the pending line; 0 between lines */
    int64_t last_request_ns; /* CLOCK_MONOTONIC of the last complete line (connect before the first) */
    char *in;           /* partial input line */
    size_t in_len;
    int skipping;       /* discarding the rest of an oversized line */
    char *out;          /* pending output */
    size_t out_len, out_off, out_cap;
    int closing;        /* close once the output is written */
    int64_t out_stall_ns; /* CLOCK_MONOTONIC since when output has waited without the peer reading any */
    int fds[SCICAPD_CLIENT_MAX_FDS]; /* descriptors passed with the pending line (close-on-exec) */
    int nfds;
} scicapd_client;

/* Move the descriptors passed with the current line into out (at most max; the rest stay, to be closed). */
int scicapd_client_take_fds(scicapd_client *c, int *out, int max);

typedef struct scicapd_control scicapd_control;

/* A complete request line (without its newline). The client may be sent replies to from inside. */
typedef void (*scicapd_line_fn)(void *user, scicapd_client *c, const char *line, size_t len);

typedef struct scicapd_control_hooks {
    scicapd_line_fn on_line;
    /* 1 when a peer with these credentials is an admin (may take the reserved slots). */
    int (*is_admin)(void *user, uid_t uid, gid_t gid);
    /* 1 when the idle connection c still waits for something (an unfinished job): keep it. May be NULL. */
    int (*busy)(void *user, const scicapd_client *c);
    void *user;
} scicapd_control_hooks;

typedef struct scicapd_control_limits {
    int max_clients;          /* connections at once, admin slots included, >= 1 */
    int admin_slots;          /* of those, kept for admins; clamped to max_clients - 1 */
    size_t max_line;          /* bytes per request line */
    int request_timeout_ms;   /* first byte (or connect) to newline */
    int idle_timeout_ms;      /* last request to close when nothing is in flight; 0 = never */
    int max_per_uid;          /* connections of one ordinary uid at once (admins: only max_clients); 0 = no cap */
    int stall_timeout_ms;     /* output waiting this long with nothing read by the peer (a watcher that stopped
                                 reading): closed; 0 = never */
} scicapd_control_limits;

/* Errors: -EADDRINUSE (a scicapd listens there), -EEXIST (something other than a socket is at path),
 * -ENAMETOOLONG, or -errno of socket/bind/chmod/listen; err names the path. hooks is copied. */
int scicapd_control_open(scicapd_control **out, const char *path, unsigned mode, const char *group,
                         const scicapd_control_limits *lim, const scicapd_control_hooks *hooks, const sci_log *log,
                         sci_error *err);
/* Closes every connection and removes the socket file. NULL is harmless. */
void scicapd_control_close(scicapd_control *ctl);
/* New limits (reload); connections over a smaller max_clients stay until they leave. */
void scicapd_control_set_limits(scicapd_control *ctl, const scicapd_control_limits *lim);
/* Answer "timeout" and close every connection past a deadline at now_ns (CLOCK_MONOTONIC). */
void scicapd_control_expire(scicapd_control *ctl, int64_t now_ns);
/* Milliseconds from now_ns to the nearest deadline (0 if one passed), or -1 when none is pending. */
int scicapd_control_next_deadline_ms(const scicapd_control *ctl, int64_t now_ns);

/* Fill up to max pollfds (listening socket first, then the connections). Returns how many. */
int scicapd_control_pollfds(scicapd_control *ctl, struct pollfd *fds, int max);
/* Handle the revents of the n pollfds filled by the last scicapd_control_pollfds. */
void scicapd_control_dispatch(scicapd_control *ctl, const struct pollfd *fds, int n);

/* Queue `line` (newline-terminated) for connection `client`; ignored if it is gone. */
void scicapd_control_send(scicapd_control *ctl, uint64_t client, const char *line);
void scicapd_control_send_to(scicapd_control *ctl, scicapd_client *c, const char *line);
/* To every watching connection except `except` (0: none) that may see events of uid `owner`: admins see
 * every event, others those of their own uid; owner < 0 (SCICAPD_OWNER_ALL) reaches every watcher. */
void scicapd_control_broadcast(scicapd_control *ctl, const char *line, uint64_t except, long owner);
int scicapd_control_clients(const scicapd_control *ctl);
/* Connections that receive events (`watch` answered), of those. */
int scicapd_control_watchers(const scicapd_control *ctl);
/* Stop accepting (shutdown): close the listening socket, keep the connections to say goodbye. */
void scicapd_control_stop_listening(scicapd_control *ctl);
/* Pending output on any connection? */
int scicapd_control_flushing(const scicapd_control *ctl);

#endif
