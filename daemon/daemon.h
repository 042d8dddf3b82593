/* daemon/daemon.h — scicapd as an object: everything main() (or a test) needs to run the daemon.
 *
 *     scicapd *d;
 *     if (scicapd_new(&d, &opts, &log, &err) < 0) { ... err.msg ...; return 1; }   // config, storage, devices,
 *     scicapd_ready(d);                       // socket listening, threads running: READY=1
 *     int rc = scicapd_run(d);                // event loop until SIGTERM/SIGINT or "shutdown"
 *     scicapd_free(d);                        // STOPPING=1, then teardown in reverse order
 *
 * Threads: the event loop (the caller of scicapd_run) owns the socket and the configuration; one acquisition
 * thread, one storage writer, `workers` reconstruction threads; hand-over through bounded queues and a
 * mailbox. Signals: scicapd_new blocks SIGTERM, SIGINT and SIGHUP in the calling thread (so in every thread it
 * starts) and reads them through a signalfd; SIGHUP reloads the configuration. Threads that existed before
 * (OpenBLAS starts a pool from a library constructor) get a handler that forwards the signal to the main thread
 * (tid == pid), so scicapd_new must be called from the process's main thread.
 * No hidden globals: two daemons may run in one process on different sockets and storage roots.
 */
#ifndef SCICAP_DAEMON_DAEMON_H
#define SCICAP_DAEMON_DAEMON_H

#include "base/error.h"
#include "base/log.h"

typedef struct scicapd scicapd;

typedef struct scicapd_options {
    const char *config_path;   /* NULL: built-in defaults */
    const char *socket_path;   /* overrides control.socket (may be NULL) */
    const char *storage_root;  /* overrides storage.root */
    const char *runtime_dir;   /* overrides storage.runtime_dir (created if missing) */
    int fsync;                 /* -1: as configured; 0/1 override */
} scicapd_options;

int scicapd_new(scicapd **out, const scicapd_options *o, const sci_log *log, sci_error *err);
/* Tell systemd the daemon is ready (READY=1 with a STATUS line). */
void scicapd_ready(scicapd *d);
/* Serve until asked to stop. Returns 0, or a negative code if the loop failed. */
int scicapd_run(scicapd *d);
/* Ask scicapd_run to return (thread-safe, async-signal-safe). */
void scicapd_request_stop(scicapd *d);
/* STOPPING=1; stop accepting; cancel reconstructions; finish the current snapshot and store what was acquired;
 * join the threads; close the devices and the socket. NULL is harmless. */
void scicapd_free(scicapd *d);

#endif
