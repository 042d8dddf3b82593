/* daemon/notify.c — sd_notify wrappers. */
#include "daemon/notify.h"

#include <stdarg.h>
#include <stdio.h>
#include <systemd/sd-daemon.h>

#include "base/clock.h"

void scicapd_notify_init(scicapd_notify *n)
{
    n->watchdog_usec = 0;
    n->last_ping_ns = 0;
    uint64_t usec = 0;
    if (sd_watchdog_enabled(0, &usec) > 0)
        n->watchdog_usec = usec;
}

void scicapd_notify_ready(scicapd_notify *n, const char *status)
{
    (void)n;
    sd_notifyf(0, "READY=1\nSTATUS=%s", status);
}

void scicapd_notify_reloading(scicapd_notify *n)
{
    (void)n;
    sd_notifyf(0, "RELOADING=1\nMONOTONIC_USEC=%lld", (long long)(sci_clock_mono_ns() / 1000));
}

void scicapd_notify_stopping(scicapd_notify *n, const char *status)
{
    (void)n;
    sd_notifyf(0, "STOPPING=1\nSTATUS=%s", status);
}

void scicapd_notify_status(scicapd_notify *n, const char *fmt, ...)
{
    (void)n;
    char buf[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    sd_notifyf(0, "STATUS=%s", buf);
}

void scicapd_notify_watchdog(scicapd_notify *n)
{
    n->last_ping_ns = sci_clock_mono_ns();
    sd_notify(0, "WATCHDOG=1");
}

int64_t scicapd_notify_watchdog_period_ns(const scicapd_notify *n) { return (int64_t)n->watchdog_usec * 500; }
