/* daemon/web.h — the bench in a browser: scicapd's live web view (HTTP through libmicrohttpd; docs/web.md).
 *
 *     scicapd_web_options o = {.host = "127.0.0.1", .port = 8080, .socket_path = cfg->socket_path,
 *                              .storage_root = cfg->storage_root, .max_connections = 64, .timeout_s = 10};
 *     scicapd_web *w;
 *     if (scicapd_web_start(&w, &o, log, &err) < 0) ... err.msg ...
 *     scicapd_web_publish(w, line);     // from the event loop: every event line it delivers to watchers
 *     scicapd_web_stop(w);              // closes every HTTP connection, joins the server's threads
 *
 * What it serves (fixed routes, nothing else; everything else 404):
 *   GET /                       the page (assets read once at start; no path from a URL reaches the file system
 *   GET /assets/NAME            except through the capture routes below)
 *   GET /api/state              {status, jobs, captures, control}: what `scicap status`, `jobs` and `captures`
 *                               show, asked over the control socket (the web acts as one more client)
 *   GET /api/curves             the measured accuracy-against-time curves (scicap bench CSV), read at start
 *   GET /api/events             server-sent events: each event line the daemon delivers to watchers
 *   GET /captures/ID/FILE       a capture's previews, and a reconstruction's previews, trace.csv, result.json;
 *                               ID and FILE must match a strict pattern (traversal cannot be expressed)
 *   POST /api/capture | /api/reconstruct | /api/cancel
 *                               only with control on, and with the token (Authorization: Bearer TOKEN)
 *
 * Security: the URL is taken as sent (never percent-decoded): '%', "..", and any byte outside [A-Za-z0-9/_.-]
 * are refused (400). Bodies over 4 KiB and URLs over 1 KiB are refused (413, 414). With a loopback address the
 * Host header must name it (a DNS-rebinding page cannot read the API). Every response carries a
 * Content-Security-Policy (default-src 'self') and X-Content-Type-Options: nosniff. The token (64 hex digits from
 * getrandom) is written at start to token_file, mode 0640, group token_group; it is compared in constant time.
 * A missing token is 401, a wrong one 403, control off 403.
 *
 * Threads: libmicrohttpd runs its own listening thread and one thread per connection (at most max_connections;
 * a connection silent for timeout_s is closed), so no HTTP client can hold the event loop, the control socket or
 * the capture path. scicapd_web_publish is thread-safe and never blocks on a client (it copies the line into a
 * ring of the last 256 events; a stream that falls behind gets a "reset" event and reloads the state).
 * Errors: 0 or -errno with err naming the address, file or package at fault.
 */
#ifndef SCICAP_DAEMON_WEB_H
#define SCICAP_DAEMON_WEB_H

#include "base/error.h"
#include "base/log.h"

typedef struct scicapd_web scicapd_web;

typedef struct scicapd_web_options {
    const char *host;          /* numeric IPv4 or IPv6 address to listen on ("127.0.0.1") */
    int port;                  /* TCP port; 0 = any free one (scicapd_web_port says which) */
    int control;               /* 1: the POST routes work with the token; 0: read-only (POST is 403) */
    const char *token_file;    /* where the token is written (control only); required then */
    const char *token_group;   /* group of the token file ("" or unknown: the process's group) */
    const char *socket_path;   /* the control socket the web asks for state and forwards control to */
    const char *storage_root;  /* captures are read from ROOT/captures/ID/ */
    const char *assets_dir;    /* index.html, app.js, style.css; NULL = installed or build-tree copy */
    const char *chartjs_path;  /* Chart.js UMD build; NULL = /usr/share/javascript/chart.js/chart.min.js */
    const char *curves_path;   /* accuracy-against-time CSV (reconstruction.curves); NULL or unreadable: the
                                  page goes without its method chart and /api/curves is 404 */
    int max_connections;       /* HTTP connections at once, >= 4 */
    int timeout_s;             /* idle HTTP connection closed after this many seconds, >= 1 */
} scicapd_web_options;

/* Read the assets, write the token (control only), and start listening. Errors: -ENOENT naming a missing asset
 * (or the libjs-chart.js package), -EADDRINUSE, -EINVAL (bad address), -errno of the token file. o is copied. */
int scicapd_web_start(scicapd_web **out, const scicapd_web_options *o, const sci_log *log, sci_error *err);
/* The port listened on (the chosen one when o->port was 0). */
int scicapd_web_port(const scicapd_web *w);
/* Hand an event line (newline-terminated JSON, borrowed for the call) to the open event streams. NULL w is
 * harmless. Thread-safe, O(length of the line), never waits for a client. */
void scicapd_web_publish(scicapd_web *w, const char *line);
/* End every stream, close the connections, join the threads, free. NULL is harmless. Blocks at most for a
 * control-socket call in flight (3 s). */
void scicapd_web_stop(scicapd_web *w);

#endif
