/* daemon/notify.h — telling systemd how the daemon is (sd_notify(3) from libsystemd).
 *
 * Without NOTIFY_SOCKET in the environment every call is a no-op, so scicapd runs as an ordinary process.
 * The watchdog interval comes from WATCHDOG_USEC (sd_watchdog_enabled); the event loop calls
 * scicapd_notify_watchdog after checking that the threads made progress, at least every interval / 2.
 * Called from the event-loop thread only.
 */
#ifndef SCICAP_DAEMON_NOTIFY_H
#define SCICAP_DAEMON_NOTIFY_H

#include <stdint.h>

typedef struct scicapd_notify {
    uint64_t watchdog_usec; /* 0: no watchdog */
    int64_t last_ping_ns;
} scicapd_notify;

void scicapd_notify_init(scicapd_notify *n);
void scicapd_notify_ready(scicapd_notify *n, const char *status);
void scicapd_notify_reloading(scicapd_notify *n);
void scicapd_notify_stopping(scicapd_notify *n, const char *status);
/* STATUS= line (printf-style). */
void scicapd_notify_status(scicapd_notify *n, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
void scicapd_notify_watchdog(scicapd_notify *n);
/* Period at which the loop should ping, ns (watchdog / 2), or 0. */
int64_t scicapd_notify_watchdog_period_ns(const scicapd_notify *n);

#endif
