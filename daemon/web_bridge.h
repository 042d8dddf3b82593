/* daemon/web_bridge.h — the web view as a client of the daemon's own control socket.
 *
 * Each call connects, sends one request line of protocol version 1 (docs/protocol.md), waits for its reply (the
 * events a job's connection also receives are skipped) and closes. So a web request goes through the same checks
 * as any client's, in the event loop, and the web's threads never touch the daemon's objects.
 *
 *     json_t *result; char msg[256];
 *     if (web_bridge_call("/run/scicapd/control.sock", "status", NULL, &result, msg, sizeof msg) == 0) ...
 *
 * Blocking, bounded: WEB_BRIDGE_TIMEOUT_MS for the whole call. Thread-safe (nothing shared).
 */
#ifndef SCICAP_DAEMON_WEB_BRIDGE_H
#define SCICAP_DAEMON_WEB_BRIDGE_H

#include <jansson.h>
#include <stddef.h>

#define WEB_BRIDGE_TIMEOUT_MS 3000
#define WEB_BRIDGE_REFUSED 1 /* not an errno: the daemon answered ok: false (msg holds its code and message) */

/* Send cmd with args (stolen; NULL: none). 0 with *result (new reference, the reply's "result"); -errno when the
 * socket could not be reached or did not answer in time (msg says which); WEB_BRIDGE_REFUSED (positive) when the
 * daemon refused the request: msg holds "code: message". */
int web_bridge_call(const char *socket_path, const char *cmd, json_t *args, json_t **result, char *msg,
                    size_t msg_n);

#endif
