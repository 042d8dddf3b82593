/* scicap status|devices|capture|calibrate|jobs|captures|cancel|watch|reload|shutdown, scicap recon --capture: the
 * daemon's client. One request per run; --wait follows the job's events until it ends. Output is for people
 * (lines, no JSON); --json, where a command has it, prints what the daemon sent instead. */
#include "cli/client.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "recon/solver.h"

typedef struct conn {
    int fd;
    FILE *in;
    const char *path;
    int tty;
    const char *who;    /* the command as the user typed it, for messages ("recon" for recon --capture) */
    int raw;            /* --json: errors as the daemon sent them */
} conn;

static int conn_open(conn *c, const char *path)
{
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    c->path = path;
    c->tty = isatty(2);
    if (strlen(path) >= sizeof sa.sun_path) {
        fprintf(stderr, "scicap: socket path too long: %s\n", path);
        return -1;
    }
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path);
    c->fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (c->fd < 0 || connect(c->fd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        fprintf(stderr, "scicap: cannot connect to scicapd at %s: %s%s\n", path, strerror(errno),
                errno == ENOENT || errno == ECONNREFUSED ? " (is scicapd running? --socket or $SCICAP_SOCKET)" : "");
        if (c->fd >= 0)
            close(c->fd);
        return -1;
    }
    c->in = fdopen(dup(c->fd), "r");
    return c->in ? 0 : -1;
}

static void conn_close(conn *c)
{
    if (c->in)
        fclose(c->in);
    if (c->fd >= 0)
        close(c->fd);
}

/* A write failed: a daemon that refused the connection (no free slot, too many of this uid's) wrote one error
 * line before closing it; that line, not the write's EPIPE, says why. Prints it or the write's error. */
static void conn_write_failed(conn *c, int e)
{
    char buf[1024];
    size_t len = 0;
    struct pollfd p = {.fd = c->fd, .events = POLLIN};
    while (len < sizeof buf - 1 && poll(&p, 1, 1000) > 0) {
        ssize_t r = recv(c->fd, buf + len, sizeof buf - 1 - len, MSG_DONTWAIT);
        if (r <= 0)
            break;
        len += (size_t)r;
        if (memchr(buf, '\n', len))
            break;
    }
    buf[len] = '\0';
    json_t *m = len ? json_loads(buf, JSON_DISABLE_EOF_CHECK, NULL) : NULL;
    json_t *err = json_object_get(m, "error");
    const char *code = json_string_value(json_object_get(err, "code"));
    const char *msg = json_string_value(json_object_get(err, "message"));
    if (code && msg)
        fprintf(stderr, "scicap: scicapd at %s refused the connection (%s): %s\n", c->path, code, msg);
    else
        fprintf(stderr, "scicap: %s: write failed: %s\n", c->path, strerror(e));
    json_decref(m);
}

static int conn_send(conn *c, const char *cmd, json_t *args /* stolen, may be NULL */)
{
    json_t *req = json_pack("{s:i, s:i, s:s}", "v", 1, "id", 1, "cmd", cmd);
    if (args)
        json_object_set_new(req, "args", args);
    char *s = json_dumps(req, JSON_COMPACT);
    json_decref(req);
    size_t n = strlen(s);
    s[n] = '\n';
    ssize_t w = send(c->fd, s, n + 1, MSG_NOSIGNAL);
    free(s);
    if (w != (ssize_t)(n + 1)) {
        conn_write_failed(c, errno);
        return -1;
    }
    return 0;
}

/* The request line with open descriptors attached (SCM_RIGHTS, with its first byte): the daemon reads those
 * files through them, with our rights, never by path. `args` stolen. */
static int conn_send_fds(conn *c, const char *cmd, json_t *args, const int *fds, int nfds)
{
    json_t *req = json_pack("{s:i, s:i, s:s, s:o}", "v", 1, "id", 1, "cmd", cmd, "args", args);
    char *s = json_dumps(req, JSON_COMPACT);
    json_decref(req);
    size_t n = strlen(s);
    s[n++] = '\n';
    union {
        char b[CMSG_SPACE(sizeof(int) * 253)];
        struct cmsghdr align;
    } ctl;
    struct iovec iov = {.iov_base = s, .iov_len = n};
    struct msghdr m = {.msg_iov = &iov, .msg_iovlen = 1, .msg_control = ctl.b,
                       .msg_controllen = CMSG_SPACE(sizeof(int) * (size_t)nfds)};
    struct cmsghdr *h = CMSG_FIRSTHDR(&m);
    h->cmsg_level = SOL_SOCKET;
    h->cmsg_type = SCM_RIGHTS;
    h->cmsg_len = CMSG_LEN(sizeof(int) * (size_t)nfds);
    memcpy(CMSG_DATA(h), fds, sizeof(int) * (size_t)nfds);
    ssize_t w = sendmsg(c->fd, &m, MSG_NOSIGNAL);
    size_t off = w > 0 ? (size_t)w : 0;
    while (w >= 0 && off < n) { /* the rest of a long line: the descriptors went with its first byte */
        w = send(c->fd, s + off, n - off, MSG_NOSIGNAL);
        off += w > 0 ? (size_t)w : 0;
    }
    free(s);
    if (w < 0) {
        conn_write_failed(c, errno);
        return -1;
    }
    return 0;
}

/* Next message; NULL when the daemon closed the connection. */
static json_t *conn_read(conn *c)
{
    char *line = NULL;
    size_t cap = 0;
    ssize_t n = getline(&line, &cap, c->in);
    if (n <= 0) {
        free(line);
        return NULL;
    }
    json_error_t je;
    json_t *m = json_loads(line, 0, &je);
    if (!m)
        fprintf(stderr, "scicap: unreadable message from scicapd: %s\n", je.text);
    free(line);
    return m;
}


static const char *option_of_arg(const char *arg);

/* A failed reply for people: the daemon's reason, naming our option instead of the request's JSON path and
 * position ("--method: unknown method 'x' (...)"); the error object itself with --json. */
static void print_error(const conn *c, const json_t *e)
{
    if (c->raw) {
        char *s = json_dumps(e, JSON_COMPACT | JSON_PRESERVE_ORDER);
        fprintf(stderr, "%s\n", s ? s : "");
        free(s);
        return;
    }
    const char *reason = json_string_value(json_object_get(e, "reason"));
    const char *arg = json_string_value(json_object_get(e, "arg"));
    const char *msg = json_string_value(json_object_get(e, "message"));
    const char *opt = arg ? option_of_arg(arg) : NULL;
    if (reason)
        fprintf(stderr, "scicap %s: %s%s%s\n", c->who, opt ? opt : "", opt ? ": " : "", reason);
    else
        fprintf(stderr, "scicap %s: %s\n", c->who, msg ? msg : "the daemon refused the request");
}

/* Wait for the reply to our request (events before it are ignored). Returns the result (new ref) or NULL
 * after printing the error. */
static json_t *conn_reply(conn *c)
{
    json_t *m;
    while ((m = conn_read(c))) {
        if (json_object_get(m, "event")) {
            json_decref(m);
            continue;
        }
        if (json_is_true(json_object_get(m, "ok"))) {
            json_t *r = json_incref(json_object_get(m, "result"));
            json_decref(m);
            return r;
        }
        print_error(c, json_object_get(m, "error"));
        json_decref(m);
        return NULL;
    }
    fprintf(stderr, "scicap %s: scicapd closed the connection\n", c->who);
    return NULL;
}

static void print_json(const json_t *j)
{
    char *s = json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
    printf("%s\n", s);
    free(s);
}

static const char *str(const json_t *o, const char *k)
{
    const char *s = json_string_value(json_object_get(o, k));
    return s ? s : "";
}

/* ---- status and devices for people (--json prints the reply as it came) ---- */

/* A scalar as text into buf ("" for objects and arrays). */
static const char *scalar(const json_t *v, char *buf, size_t n)
{
    if (json_is_string(v))
        snprintf(buf, n, "%s", json_string_value(v));
    else if (json_is_integer(v))
        snprintf(buf, n, "%lld", (long long)json_integer_value(v));
    else if (json_is_real(v))
        snprintf(buf, n, "%g", json_real_value(v));
    else if (json_is_boolean(v))
        snprintf(buf, n, "%s", json_is_true(v) ? "yes" : "no");
    else if (json_is_null(v))
        snprintf(buf, n, "-");
    else
        buf[0] = '\0';
    return buf;
}

/* Every field of a device but the ones its heading shows, one "key  value" line each; nested objects
 * (identity, settings) flattened as "identity.card". */
static void print_fields(FILE *f, const json_t *o, const char *prefix, int indent)
{
    const char *k;
    const json_t *v;
    json_object_foreach((json_t *)o, k, v) {
        if (!prefix[0] && (!strcmp(k, "backend") || !strcmp(k, "connected")))
            continue;
        char key[128], val[512];
        snprintf(key, sizeof key, "%s%s%s", prefix, prefix[0] ? "." : "", k);
        if (json_is_object(v)) {
            print_fields(f, v, key, indent);
        } else if (json_is_array(v)) {
            char *a = json_dumps(v, JSON_COMPACT);
            fprintf(f, "%*s%-26s %s\n", indent, "", key, a ? a : "");
            free(a);
        } else if (strcmp(key, "identity.backend") != 0) {
            fprintf(f, "%*s%-26s %s\n", indent, "", key, scalar(v, val, sizeof val));
        }
    }
}

/* "dmd      dlpc900  connected" and the device's fields below. */
static void print_devices(FILE *f, const json_t *devs)
{
    const char *name;
    const json_t *d;
    json_object_foreach((json_t *)devs, name, d) {
        const json_t *up = json_object_get(d, "connected");
        fprintf(f, "%-8s %-8s %s\n", name, str(d, "backend")[0] ? str(d, "backend") : "?",
                !up ? "" : json_is_true(up) ? "connected" : "NOT CONNECTED");
        print_fields(f, d, "", 2);
    }
}

static void print_queue(FILE *f, const json_t *queues, const char *name, int last)
{
    const json_t *q = json_object_get(queues, name);
    fprintf(f, "%s %lld/%lld%s", name, (long long)json_integer_value(json_array_get(q, 0)),
            (long long)json_integer_value(json_array_get(q, 1)), last ? "\n" : ", ");
}

static void print_status(FILE *f, const json_t *r)
{
    const json_t *jobs = json_object_get(r, "jobs"), *rec = json_object_get(r, "recovered");
    const json_t *queues = json_object_get(r, "queues"), *timing = json_object_get(r, "timing");
    long long up = (long long)json_number_value(json_object_get(r, "uptime_s"));
    int stopping = json_is_true(json_object_get(r, "stopping"));
    int dmd = json_is_true(json_object_get(r, "dmd_connected"));
    fprintf(f, "scicapd %s (protocol %lld), pid %lld, up %lldh %02lldm %02llds\n", str(r, "version"),
            (long long)json_integer_value(json_object_get(r, "protocol")),
            (long long)json_integer_value(json_object_get(r, "pid")), up / 3600, up / 60 % 60, up % 60);
    fprintf(f, "%-10s %s\n", "state", stopping ? "stopping" : dmd ? "ready" : "ready, but the DMD is not connected");
    fprintf(f, "%-10s %s\n", "config", str(r, "config"));
    fprintf(f, "%-10s %s\n", "socket", str(r, "socket"));
    fprintf(f, "%-10s %s (%lld captures stored since start)\n", "storage", str(r, "storage"),
            (long long)json_integer_value(json_object_get(r, "captures_stored")));
    fprintf(f, "%-10s ", "queues");
    print_queue(f, queues, "capture", 0);
    print_queue(f, queues, "reconstruction", 0);
    print_queue(f, queues, "storage", 1);
    fprintf(f, "%-10s %lld queued, %lld running, %lld finished; %lld reconstruction workers busy\n", "jobs",
            (long long)json_integer_value(json_object_get(jobs, "queued")),
            (long long)json_integer_value(json_object_get(jobs, "running")),
            (long long)json_integer_value(json_object_get(jobs, "finished")),
            (long long)json_integer_value(json_object_get(r, "workers_busy")));
    fprintf(f, "%-10s %lld connected", "clients", (long long)json_integer_value(json_object_get(r, "clients")));
    if (json_object_get(r, "watchers")) /* an older daemon does not say */
        fprintf(f, ", %lld watching", (long long)json_integer_value(json_object_get(r, "watchers")));
    fprintf(f, "\n");
    fprintf(f, "%-10s %lld captures found, %lld partial folders removed, %lld reconstructions resumed\n",
            "at start", (long long)json_integer_value(json_object_get(rec, "captures")),
            (long long)json_integer_value(json_object_get(rec, "removed_partial")),
            (long long)json_integer_value(json_object_get(rec, "reconstructions_resumed")));
    if (json_object_size(timing)) {
        fprintf(f, "\ntime per run of each stage since start (mean; CPU of the thread that ran it):\n");
        const char *k;
        const json_t *t;
        json_object_foreach((json_t *)timing, k, t) {
            long long n = (long long)json_integer_value(json_object_get(t, "count"));
            if (n > 0)
                fprintf(f, "  %-12s %6lld runs  %8.1f ms wall  %8.1f ms CPU\n", k, n,
                        json_number_value(json_object_get(t, "wall_ms")),
                        json_number_value(json_object_get(t, "cpu_ms")));
        }
    }
    fprintf(f, "\ndevices:\n");
    const char *name;
    const json_t *d;
    json_object_foreach(json_object_get(r, "devices"), name, d) {
        const json_t *on = json_object_get(d, "connected");
        fprintf(f, "  %-8s %-8s %s\n", name, str(d, "backend"),
                !on ? "" : json_is_true(on) ? "connected" : "NOT CONNECTED");
    }
    fprintf(f, "(scicap devices for their identities and settings)\n");
}


/* ---- events for people: one line each (the progress bar redraws one line on a terminal) ---- */

static double num(const json_t *o, const char *k) { return json_number_value(json_object_get(o, k)); }
static long long integer(const json_t *o, const char *k) { return (long long)json_integer_value(json_object_get(o, k)); }

/* " PSNR 23.18 dB", else " relative residual 3.2e-04" (no truth: the measurement's fit is all there is), else "". */
static const char *quality(const json_t *d, char *buf, size_t n)
{
    const json_t *p = json_object_get(d, "psnr"), *r = json_object_get(d, "residual");
    if (json_is_number(p))
        snprintf(buf, n, " PSNR %.2f dB", json_number_value(p));
    else if (json_is_number(r) && json_number_value(r) >= 0)
        snprintf(buf, n, " relative residual %.2e", json_number_value(r));
    else
        buf[0] = '\0';
    return buf;
}

static void progress_bar(conn *c, const json_t *d, long long job)
{
    int it = (int)integer(d, "iter"), n = (int)integer(d, "iters");
    int w = 30, fill = n > 0 ? it * w / n : 0;
    char bar[64], q[64];
    for (int i = 0; i < w; i++)
        bar[i] = i < fill ? '#' : '.';
    bar[w] = '\0';
    quality(d, q, sizeof q);
    if (c->tty)
        fprintf(stderr, "\r  job %lld [%s] %4d/%d %s  ETA %5.1f s ", job, bar, it, n, q, num(d, "eta_s"));
    else if (it == n)
        fprintf(stderr, "  job %lld: %d/%d iterations,%s\n", job, it, n, q);
}

/* The outputs of a job as "a, b, c" into buf. */
static const char *joined(const json_t *a, char *buf, size_t n)
{
    size_t i, off = 0;
    const json_t *v;
    buf[0] = '\0';
    json_array_foreach((json_t *)a, i, v) {
        const char *s = json_string_value(v);
        const char *cap = s ? strstr(s, "/captures/") : NULL; /* a reconstruction: from its capture on */
        if (off < n)
            off += (size_t)snprintf(buf + off, n - off, "%s%s", i ? ", " : "", cap ? cap + 10 : s ? s : "?");
    }
    return buf;
}

static void ev_capture_started(long long job, const json_t *d)
{
    printf("job %lld: capture of %lld snapshot(s) with mask set %s started\n", job, integer(d, "count"),
           str(d, "mask_set"));
}

static void ev_capture_snapshot(long long job, const json_t *d)
{
    printf("job %lld: snapshot %lld of %lld taken, sync %s%s\n", job, integer(d, "index") + 1, integer(d, "count"),
           str(d, "sync"), json_is_true(json_object_get(d, "broken")) ? " (BROKEN: stored flagged)" : "");
}

static void ev_capture_stored(long long job, const json_t *d)
{
    printf("job %lld: stored %s (%s)%s, %.0f ms after the request\n", job, str(d, "capture"), str(d, "dir"),
           json_is_true(json_object_get(d, "broken")) ? " BROKEN SYNC" : "", num(d, "latency_ms"));
}

static void ev_capture_done(long long job, const json_t *d)
{
    char outs[1024];
    printf("job %lld: capture done: %lld of %lld snapshot(s) stored (%s) in %.2f s\n", job, integer(d, "done"),
           integer(d, "total"), joined(json_object_get(d, "outputs"), outs, sizeof outs), num(d, "run_s"));
}

static void ev_failed(long long job, const json_t *d, const char *what)
{
    printf("job %lld: %s failed", job, what);
    if (json_object_get(d, "index"))
        printf(" at snapshot %lld", integer(d, "index") + 1);
    printf(": %s\n", str(d, "error"));
}

static void ev_capture_failed(long long job, const json_t *d) { ev_failed(job, d, "capture"); }
static void ev_calibrate_failed(long long job, const json_t *d) { ev_failed(job, d, "calibration"); }

static void ev_capture_canceled(long long job, const json_t *d)
{
    printf("job %lld: capture canceled after %lld snapshot(s)\n", job, integer(d, "acquired"));
}

static void ev_calibrate_started(long long job, const json_t *d)
{
    printf("job %lld: %s calibration started%s%s\n", job, str(d, "kind"), json_object_get(d, "mask_set") ? " for " : "",
           str(d, "mask_set"));
}

static void ev_calibrate_progress(long long job, const json_t *d)
{
    printf("job %lld: mask %lld of %lld measured\n", job, integer(d, "mask"), integer(d, "of"));
}

static void ev_calibrate_done(long long job, const json_t *d)
{
    printf("job %lld: %s calibration done -> %s\n", job, str(d, "kind"), str(d, "folder"));
}

static void ev_calibrate_canceled(long long job, const json_t *d)
{
    printf("job %lld: calibration canceled: %s\n", job, str(d, "error"));
}

static void ev_recon_queued(long long job, const json_t *d)
{
    printf("job %lld: %s of %s queued\n", job, str(d, "method"), str(d, "capture"));
}

static void ev_recon_rejected(long long job, const json_t *d)
{
    printf("job %lld: reconstruction of %s not queued: %s\n", job, str(d, "capture"), str(d, "reason"));
}

static void ev_recon_started(long long job, const json_t *d)
{
    printf("job %lld: %s of %s started%s\n", job, str(d, "method"), str(d, "capture"),
           json_object_get(d, "resume_bytes") ? ", going on from its checkpoint" : "");
}

static void ev_recon_checkpoint(long long job, const json_t *d)
{
    printf("job %lld: checkpoint at step %lld (%.1f MB)\n", job, integer(d, "iter"), num(d, "bytes") / 1e6);
}

static void ev_recon_done(long long job, const json_t *d)
{
    char q[64];
    printf("job %lld: %s of %s:%s in %.2f s -> %s\n", job, str(d, "method"), str(d, "capture"),
           quality(d, q, sizeof q), num(d, "solve_s"), str(d, "dir"));
}

static void ev_recon_ended(long long job, const json_t *d, const char *how)
{
    printf("job %lld: %s of %s %s: %s\n", job, json_object_get(d, "method") ? str(d, "method") : "reconstruction",
           str(d, "capture"), how, str(d, "error"));
}

static void ev_recon_failed(long long job, const json_t *d) { ev_recon_ended(job, d, "failed"); }
static void ev_recon_canceled(long long job, const json_t *d) { ev_recon_ended(job, d, "canceled"); }

static void ev_import_started(long long job, const json_t *d)
{
    printf("job %lld: import of a %s (%lld file(s)) started\n", job, str(d, "kind"), integer(d, "files"));
}

static void ev_import_stored(long long job, const json_t *d)
{
    printf("job %lld: stored %s (%s), snapshot %lld of %lld\n", job, str(d, "capture"), str(d, "dir"),
           integer(d, "index") + 1, integer(d, "count"));
}

static void ev_import_done(long long job, const json_t *d)
{
    printf("job %lld: imported %lld snapshots", job, integer(d, "snapshots"));
    if (json_object_get(d, "white"))
        printf(", values divided by %g%s%s", num(d, "white"), json_object_get(d, "scale_auto") ? ": " : "",
               str(d, "scale_auto"));
    printf("\n");
}

static void ev_import_ended(long long job, const json_t *d, const char *how)
{
    char ids[1024];
    size_t n = json_array_size(json_object_get(d, "captures"));
    printf("job %lld: import %s: %s", job, how, str(d, "error"));
    if (n)
        printf(" (stored before: %s)", joined(json_object_get(d, "captures"), ids, sizeof ids));
    printf("\n");
}

static void ev_import_failed(long long job, const json_t *d) { ev_import_ended(job, d, "failed"); }
static void ev_import_canceled(long long job, const json_t *d) { ev_import_ended(job, d, "canceled"); }

static void ev_device(const json_t *d, const char *what)
{
    printf("device %s%s%s %s\n", str(d, "device"), json_object_get(d, "serial") ? " serial " : "", str(d, "serial"),
           what);
}

static void ev_device_connected(long long job, const json_t *d) { ev_device(d, "connected"); }
static void ev_device_disconnected(long long job, const json_t *d) { ev_device(d, "disconnected"); }

/* An event no printer knows: its fields as "key value" pairs, nested ones flattened, never JSON. */
static void ev_other(const char *ev, long long job, const json_t *d)
{
    if (job)
        printf("job %lld: ", job);
    printf("%s", ev);
    const char *k;
    const json_t *v;
    int first = 1;
    json_object_foreach((json_t *)d, k, v) {
        char val[256];
        if (json_is_object(v) || json_is_array(v))
            snprintf(val, sizeof val, "(%zu %s)", json_is_array(v) ? json_array_size(v) : json_object_size(v),
                     json_is_array(v) ? "values" : "fields");
        else if (json_is_real(v))
            snprintf(val, sizeof val, "%.4g", json_real_value(v));
        else
            scalar(v, val, sizeof val);
        printf("%s%s %s", first ? ": " : ", ", k, val);
        first = 0;
    }
    printf("\n");
}

typedef void (*event_fn)(long long job, const json_t *data);

static const struct { const char *name; event_fn fn; } event_printers[] = {
    {"capture.started", ev_capture_started}, {"capture.snapshot", ev_capture_snapshot},
    {"capture.stored", ev_capture_stored}, {"capture.done", ev_capture_done},
    {"capture.failed", ev_capture_failed}, {"capture.canceled", ev_capture_canceled},
    {"calibrate.started", ev_calibrate_started}, {"calibrate.progress", ev_calibrate_progress},
    {"calibrate.done", ev_calibrate_done}, {"calibrate.failed", ev_calibrate_failed},
    {"calibrate.canceled", ev_calibrate_canceled}, {"recon.queued", ev_recon_queued},
    {"recon.rejected", ev_recon_rejected}, {"recon.started", ev_recon_started},
    {"recon.checkpoint", ev_recon_checkpoint}, {"recon.done", ev_recon_done}, {"recon.failed", ev_recon_failed},
    {"recon.canceled", ev_recon_canceled}, {"import.started", ev_import_started},
    {"import.stored", ev_import_stored}, {"import.done", ev_import_done}, {"import.failed", ev_import_failed},
    {"import.canceled", ev_import_canceled}, {"device.connected", ev_device_connected},
    {"device.disconnected", ev_device_disconnected},
};

/* Print one event in human form. */
static void print_event(conn *c, const json_t *m)
{
    const char *ev = str(m, "event");
    long long job = integer(m, "job");
    const json_t *d = json_object_get(m, "data");
    if (strcmp(ev, "recon.progress") == 0) {
        progress_bar(c, d, job);
        return;
    }
    if (c->tty)
        fprintf(stderr, "\r%80s\r", "");
    size_t i, n = sizeof event_printers / sizeof event_printers[0];
    for (i = 0; i < n && strcmp(event_printers[i].name, ev) != 0; i++)
        ;
    if (i < n)
        event_printers[i].fn(job, d);
    else
        ev_other(ev, job, d);
    fflush(stdout);
}

/* An event as the daemon sent it (--json). */
static void print_event_raw(const json_t *m)
{
    char *line = json_dumps(m, JSON_COMPACT | JSON_PRESERVE_ORDER);
    printf("%s\n", line ? line : "");
    free(line);
    fflush(stdout);
}


/* Follow events of our request until every job it started has ended. `recon` 1: also wait for the
 * reconstructions a capture queues. Returns 0 if all succeeded. */
static int follow(conn *c, int recon, int recon_only)
{
    int pending_capture = !recon_only, pending_recon = recon_only, failed = 0;
    json_t *m;
    while ((pending_capture || pending_recon) && (m = conn_read(c))) {
        const char *ev = str(m, "event");
        if (!ev[0] || json_integer_value(json_object_get(m, "id")) != 1) {
            json_decref(m);
            continue;
        }
        print_event(c, m);
        if (!strcmp(ev, "recon.queued"))
            pending_recon += recon;
        else if (!strcmp(ev, "recon.rejected"))
            failed = 1;
        else if (!strcmp(ev, "capture.done") || !strcmp(ev, "calibrate.done") || !strcmp(ev, "import.done"))
            pending_capture = 0;
        else if (strstr(ev, ".failed") || strstr(ev, ".canceled")) {
            failed = 1;
            if (!strncmp(ev, "recon", 5))
                pending_recon -= recon;
            else
                pending_capture = 0;
        } else if (!strcmp(ev, "recon.done"))
            pending_recon -= recon;
        json_decref(m);
    }
    return failed || pending_capture || pending_recon > 0 ? 1 : 0;
}

static const char *default_socket(void)
{
    const char *s = getenv("SCICAP_SOCKET");
    return s && s[0] ? s : CLI_CLIENT_DEFAULT_SOCKET;
}

enum { O_SOCKET = 1000, O_JSON, O_FROM, O_MASK, O_MASK_VAR, O_MEAS_VAR, O_TRUTH_VAR, O_SCALE, O_MASK_SET, O_COUNT,
       O_EXPOSURE, O_PATTERN, O_DARK_US, O_SYNC_MODE, O_RECON, O_METHOD, O_PRESET, O_WAIT, O_DARK, O_MASKS, O_AVERAGE,
       O_CAPTURE, O_ITERS, O_BUDGET, O_ALL, O_ALLOW_LARGE, O_HELP };

/* One getopt table per command, so each accepts exactly its own options and its --help lists exactly those
 * (tests/integration/test_cli_help.c reads these tables). */
static const struct option plain_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"json", no_argument, 0, O_JSON}, {"help", no_argument, 0, O_HELP},
    {0, 0, 0, 0}};
static const struct option list_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"json", no_argument, 0, O_JSON}, {"all", no_argument, 0, O_ALL},
    {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};
static const struct option capture_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"mask-set", required_argument, 0, O_MASK_SET},
    {"count", required_argument, 0, O_COUNT}, {"exposure-us", required_argument, 0, O_EXPOSURE},
    {"pattern-us", required_argument, 0, O_PATTERN}, {"dark-us", required_argument, 0, O_DARK_US},
    {"sync", required_argument, 0, O_SYNC_MODE}, {"recon", optional_argument, 0, O_RECON},
    {"method", required_argument, 0, O_METHOD}, {"preset", required_argument, 0, O_PRESET},
    {"wait", no_argument, 0, O_WAIT}, {"from", required_argument, 0, O_FROM}, {"mask", required_argument, 0, O_MASK},
    {"mask-var", required_argument, 0, O_MASK_VAR}, {"meas-var", required_argument, 0, O_MEAS_VAR},
    {"truth-var", required_argument, 0, O_TRUTH_VAR}, {"scale", required_argument, 0, O_SCALE},
    {"allow-large", no_argument, 0, O_ALLOW_LARGE}, {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};
static const struct option calibrate_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"dark", no_argument, 0, O_DARK}, {"masks", no_argument, 0, O_MASKS},
    {"mask-set", required_argument, 0, O_MASK_SET}, {"average", required_argument, 0, O_AVERAGE},
    {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};
static const struct option reconstruct_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"capture", required_argument, 0, O_CAPTURE},
    {"method", required_argument, 0, O_METHOD}, {"preset", required_argument, 0, O_PRESET},
    {"iters", required_argument, 0, O_ITERS}, {"budget", required_argument, 0, O_BUDGET},
    {"wait", no_argument, 0, O_WAIT}, {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};

/* What each option means, for every command's help, and the request argument it sets (`key`, a path under
 * "args"), so that a refused argument is reported as the option the user typed. */
static const struct { const char *name, *arg, *text, *key; } opt_help[] = {
    {"socket", "PATH", "the daemon's control socket (default $SCICAP_SOCKET, else " CLI_CLIENT_DEFAULT_SOCKET ")",
     NULL},
    {"json", NULL, "print the daemon's reply (watch: each event) as JSON, unformatted for people", NULL},
    {"all", NULL, "every one the daemon keeps, not only the active and the most recent", "limit"},
    {"mask-set", "S", "the mask set the DMD shows (a name from the daemon's configuration)", "mask_set"},
    {"count", "N", "snapshots to capture (default 1)", "count"},
    {"exposure-us", "U", "camera exposure per snapshot, microseconds", "exposure_us"},
    {"pattern-us", "U", "DMD display time per mask, microseconds", "pattern_us"},
    {"dark-us", "U", "DMD dark time after each mask, microseconds", "dark_us"},
    {"sync", "MODE", "host-master (the host triggers both) or dmd-master (the DMD triggers the camera)", "sync_mode"},
    {"recon", "[METHOD]", "queue a reconstruction of each snapshot ('--recon METHOD' and '--recon=METHOD' both\n"
                          "                     work; default: the daemon's reconstruction.method); methods:",
     "reconstruct"},
    {"method", "M", "the method (the NeRF ones need a capture with a camera):", "method"},
    {"preset", "P", "fast, balanced or best (default and quality: deprecated aliases)", "preset"},
    {"wait", NULL, "wait for the job (and its reconstructions) to finish, with progress", NULL},
    {"from", "FILE|DIR", "no bench: captures from a .mat or a problem folder, read by the daemon through\n"
                         "                     descriptors this command opens (your rights, not the daemon's)",
     "files"},
    {"mask", "FILE", "with --from FILE.mat: the .mat that holds the masks", "mask"},
    {"mask-var", "V", "with --from: the masks' variable (default mask)", "mask_var"},
    {"meas-var", "V", "with --from: the measurements' variable (default meas)", "meas_var"},
    {"truth-var", "V", "with --from: the ground truth's variable (default orig, optional)", "truth_var"},
    {"scale", "auto|N", "with --from: the data's white level (default auto: inferred from the data and said)", "scale"},
    {"allow-large", NULL, "with --from: lift the size limits scicap recon holds a file to (as its --allow-large);\n"
                          "                     the daemon grants it to its admins only (control.admin_group)",
     "allow_large"},
    {"dark", NULL, "measure the dark frame", "kind"},
    {"masks", NULL, "measure the masks as the camera sees them", NULL},
    {"average", "N", "frames averaged per measurement", "average"},
    {"capture", "ID", "the capture to reconstruct: c000042, c42 or 42 (scicap captures lists them)", "capture"},
    {"iters", "N", "iterations (overrides the preset)", "params.iters"},
    {"budget", "SECONDS", "the most accurate measured setting that fits in SECONDS (bench/results.csv)", "budget_s"},
    {"help", NULL, "this text", NULL},
};

/* "--method" for the request argument "method" (a key of our own options' requests), else NULL: the reason
 * alone is printed. Settings under params other than iters have no option of ours: named as the key. */
static const char *option_of_arg(const char *arg)
{
    static char buf[96];
    for (size_t i = 0; i < sizeof opt_help / sizeof opt_help[0]; i++)
        if (opt_help[i].key && !strcmp(opt_help[i].key, arg)) {
            snprintf(buf, sizeof buf, "--%s", opt_help[i].name);
            return buf;
        }
    if (!strncmp(arg, "params.", 7)) {
        snprintf(buf, sizeof buf, "setting %s", arg + 7);
        return buf;
    }
    return NULL;
}

#define CLI_IMPORT_MAX_FILES 250 /* the daemon's SCICAPD_IMPORT_MAX_FILES */
#define CLI_RECENT_JOBS 10       /* finished jobs `scicap jobs` shows without --all */
#define CLI_RECENT_CAPTURES 20   /* captures `scicap captures` shows without --all */
#define CLI_STR_(x) #x
#define CLI_STR(x) CLI_STR_(x)

/* One run of a command: what the options said, and the request being built. */
typedef struct client_req {
    const struct client_cmd *cmd;
    const char *sock, *from, *mask_file;
    json_t *args, *params;     /* owned until sent */
    int wait, kind, raw, all;
    int fds[CLI_IMPORT_MAX_FILES], nfds;
} client_req;

/* Positional arguments and the checks across options: 0, or 2 (usage, said why). */
typedef int (*client_check_fn)(client_req *q, int argc, char **argv);
/* The reply for people (or as JSON with q->raw), and what follows it: the exit status. */
typedef int (*client_show_fn)(conn *c, const json_t *r, const client_req *q);

typedef struct client_cmd {
    const char *name, *synopsis, *what;
    const struct option *opts;
    const char *request;       /* the protocol's command */
    client_check_fn check;     /* NULL: no positional argument */
    client_show_fn show;
    int own_json;              /* 1: show prints --json itself (watch: each event; cancel: and exits 1 if done) */
} client_cmd;

static int check_cancel(client_req *q, int argc, char **argv);
static int check_capture(client_req *q, int argc, char **argv);
static int check_calibrate(client_req *q, int argc, char **argv);
static int check_reconstruct(client_req *q, int argc, char **argv);
static int check_list(client_req *q, int argc, char **argv);
static int show_status(conn *c, const json_t *r, const client_req *q);
static int show_devices(conn *c, const json_t *r, const client_req *q);
static int show_queued(conn *c, const json_t *r, const client_req *q);
static int show_jobs(conn *c, const json_t *r, const client_req *q);
static int show_captures(conn *c, const json_t *r, const client_req *q);
static int show_cancel(conn *c, const json_t *r, const client_req *q);
static int show_watch(conn *c, const json_t *r, const client_req *q);
static int show_reload(conn *c, const json_t *r, const client_req *q);
static int show_shutdown(conn *c, const json_t *r, const client_req *q);

static const client_cmd client_cmds[] = {
    {"status", "scicap status [--socket PATH] [--json]", "The daemon's state, queues and counters.", plain_opts,
     "status", NULL, show_status, 0},
    {"devices", "scicap devices [--socket PATH] [--json]", "The devices the daemon drives, their identities and state.",
     plain_opts, "devices", NULL, show_devices, 0},
    {"capture",
     "scicap capture [--mask-set S] [--count N] [--exposure-us U] [--pattern-us U] [--dark-us U]\n"
     "                      [--sync host-master|dmd-master|camera-master] [--recon [METHOD]] [--method M]\n"
     "                      [--preset P] [--wait]\n"
     "       scicap capture --from FILE.mat|DIR [--mask FILE.mat] [--mask-var V] [--meas-var V] [--truth-var V]\n"
     "                      [--scale auto|N] [--allow-large] [--recon [METHOD]] [--method M] [--preset P] [--wait]",
     "Capture coded snapshots on the bench (and reconstruct them with --recon); with --from, store the snapshots\n"
     "of a file or problem folder as captures instead (each snapshot one capture, as from the bench).",
     capture_opts, "capture", check_capture, show_queued, 0},
    {"calibrate", "scicap calibrate --dark|--masks [--mask-set S] [--average N]",
     "Measure the dark frame or the masks as the camera sees them; waits for the result.", calibrate_opts,
     "calibrate", check_calibrate, show_queued, 0},
    {"jobs", "scicap jobs [--socket PATH] [--json] [--all]",
     "Queued and running jobs and the last " CLI_STR(CLI_RECENT_JOBS) " finished ones (--all: every job the daemon keeps).", list_opts,
     "jobs", check_list, show_jobs, 0},
    {"captures", "scicap captures [--socket PATH] [--json] [--all]",
     "The stored captures, the newest " CLI_STR(CLI_RECENT_CAPTURES) " (--all: every one), each with its reconstructions: method, PSNR\n"
     "(or the measurement residual without truth), time.", list_opts, "captures", check_list, show_captures, 0},
    {"cancel", "scicap cancel [--socket PATH] [--json] JOB",
     "Cancel a queued or running job (exit status 1 when it had already finished).", plain_opts, "cancel",
     check_cancel, show_cancel, 1},
    {"watch", "scicap watch [--socket PATH] [--json]",
     "Follow the daemon's event stream with a progress bar (Ctrl-C ends).", plain_opts, "watch", NULL, show_watch,
     1},
    {"reload", "scicap reload [--socket PATH] [--json]", "Reload the daemon's configuration (admin).", plain_opts,
     "reload", NULL, show_reload, 0},
    {"shutdown", "scicap shutdown [--socket PATH] [--json]", "Stop the daemon (admin).", plain_opts, "shutdown", NULL,
     show_shutdown, 0},
    {"reconstruct",
     "scicap recon --capture ID [--method M] [--preset fast|balanced|best] [--iters N] [--wait]\n"
     "       scicap recon --capture ID --budget SECONDS [--method M] [--wait]",
     "Ask the daemon to reconstruct one of its captures (files: scicap recon --help). A capture's second\n"
     "reconstruction by a method goes to recon/METHOD.2 (then .3, ...): nothing is replaced.", reconstruct_opts,
     "reconstruct", check_reconstruct, show_queued, 0},
};

static const client_cmd *find_cmd(const char *name)
{
    for (size_t i = 0; i < sizeof client_cmds / sizeof client_cmds[0]; i++)
        if (!strcmp(client_cmds[i].name, name))
            return &client_cmds[i];
    return NULL;
}

static void usage(FILE *f, const client_cmd *cmd)
{
    fprintf(f, "usage: %s\n\n%s\n\noptions:\n", cmd->synopsis, cmd->what);
    for (const struct option *o = cmd->opts; o->name; o++)
        for (size_t i = 0; i < sizeof opt_help / sizeof opt_help[0]; i++)
            if (!strcmp(opt_help[i].name, o->name)) {
                char left[48];
                snprintf(left, sizeof left, "--%s%s%s", o->name, opt_help[i].arg ? " " : "",
                         opt_help[i].arg ? opt_help[i].arg : "");
                char names[256] = "";
                if (!strcmp(o->name, "method") || !strcmp(o->name, "recon")) /* the method table's, by name */
                    solver_names_text(names, sizeof names, ", ");
                fprintf(f, "  %-18s %s%s%s\n", left, opt_help[i].text, names[0] ? " " : "", names);
            }
    fprintf(f, "\nExit status: 0 success, 1 failure, 2 usage.\n");
}

void cli_client_usage(FILE *f, const char *name)
{
    const client_cmd *c = find_cmd(name);
    if (c)
        usage(f, c);
}

static int parse_count(const char *s, const char *opt, long long *out)
{
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (errno || *end || end == s || v < 0) {
        fprintf(stderr, "scicap: %s wants a non-negative integer, got '%s'\n", opt, s);
        return -1;
    }
    *out = v;
    return 0;
}

/* ---- capture --from: the files opened here, with the user's rights, and passed to the daemon ---- */

static void close_all(int *fds, int n)
{
    for (int i = 0; i < n; i++)
        close(fds[i]);
}

static int by_name(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* A problem folder's files the daemon reads (problem.json, the *.json sidecars, the *.exr stacks; not the
 * previews), opened, their names appended to `files`. Count, or -1 after printing why. */
static int open_folder(const char *dir, json_t *files, int *fds)
{
    DIR *d = opendir(dir);
    if (!d) {
        fprintf(stderr, "scicap capture: %s: %s\n", dir, strerror(errno));
        return -1;
    }
    char *names[CLI_IMPORT_MAX_FILES + 1];
    int n = 0, too_many = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        size_t l = strlen(e->d_name);
        if (e->d_name[0] == '.' || l < 5 || (strcmp(e->d_name + l - 5, ".json") && strcmp(e->d_name + l - 4, ".exr")))
            continue;
        if (n == CLI_IMPORT_MAX_FILES) {
            too_many = 1;
            break;
        }
        names[n++] = strdup(e->d_name);
    }
    int dfd = dirfd(d), rc = n;
    if (too_many) {
        fprintf(stderr, "scicap capture: %s holds more than %d files to pass; pass a .mat instead\n", dir,
                CLI_IMPORT_MAX_FILES);
        rc = -1;
    }
    qsort(names, (size_t)n, sizeof *names, by_name);
    for (int i = 0; i < n && rc >= 0; i++) {
        fds[i] = openat(dfd, names[i], O_RDONLY | O_CLOEXEC);
        if (fds[i] < 0) {
            fprintf(stderr, "scicap capture: %s/%s: %s\n", dir, names[i], strerror(errno));
            close_all(fds, i);
            rc = -1;
        } else {
            json_array_append_new(files, json_string(names[i]));
        }
    }
    for (int i = 0; i < n; i++)
        free(names[i]);
    closedir(d);
    return rc;
}

/* Open --from (and --mask) and complete the import request's args. Count of descriptors, -1 (runtime error)
 * or -2 (usage) after printing why. */
static int open_import(const char *from, const char *mask_file, json_t *args, int *fds)
{
    struct stat sb;
    if (stat(from, &sb) != 0) {
        fprintf(stderr, "scicap capture: %s: %s\n", from, strerror(errno));
        return -1;
    }
    json_t *files = json_array();
    json_object_set_new(args, "files", files);
    if (S_ISDIR(sb.st_mode)) {
        if (mask_file || json_object_get(args, "mask_var") || json_object_get(args, "meas_var") ||
            json_object_get(args, "truth_var") || json_object_get(args, "scale")) {
            fprintf(stderr, "scicap capture: %s is a problem folder: it names its parts and its scale itself "
                            "(--mask, --mask-var, --meas-var, --truth-var and --scale are for a .mat)\n", from);
            return -2;
        }
        json_object_set_new(args, "kind", json_string("folder"));
        return open_folder(from, files, fds);
    }
    json_object_set_new(args, "kind", json_string("mat"));
    const char *paths[2] = {from, mask_file};
    int n = 0;
    for (int i = 0; i < 2 && paths[i]; i++) {
        fds[n] = open(paths[i], O_RDONLY | O_CLOEXEC);
        if (fds[n] < 0) {
            fprintf(stderr, "scicap capture: %s: %s\n", paths[i], strerror(errno));
            close_all(fds, n);
            return -1;
        }
        const char *slash = strrchr(paths[i], '/');
        char name[80];
        snprintf(name, sizeof name, "%s%.60s", i && !strcmp(slash ? slash + 1 : paths[i], json_string_value(
                 json_array_get(files, 0))) ? "mask-" : "", slash ? slash + 1 : paths[i]);
        json_array_append_new(files, json_string(name));
        if (i == 1)
            json_object_set_new(args, "mask", json_string(name));
        n++;
    }
    return n;
}


static volatile sig_atomic_t interrupted;
static void on_sigint(int s) { (void)s; interrupted = 1; }

/* ---- options into the request ---- */

static int set_scale(client_req *q, const char *v)
{
    char *end;
    double sc = strtod(v, &end);
    if (!strcmp(v, "auto"))
        json_object_set_new(q->args, "scale", json_string("auto"));
    else if (*end || end == v || !(sc > 0)) {
        fprintf(stderr, "scicap: --scale wants auto or a white level > 0, got '%s'\n", v);
        return 2;
    } else
        json_object_set_new(q->args, "scale", json_real(sc));
    return 0;
}

/* --recon takes an optional method; getopt only binds "--recon=M", so take "--recon M" here too (capture has no
 * positional arguments, so a following method name cannot be anything else). */
static int set_recon(client_req *q, const char *m, int argc, char **argv)
{
    if (!m && optind < argc && solver_find(argv[optind]))
        m = argv[optind++];
    if (m && !solver_find(m)) {
        char names[256];
        fprintf(stderr, "scicap capture: --recon reconstructs with %s, not '%s'\n",
                solver_names_text(names, sizeof names, ", "), m);
        return 2;
    }
    json_object_set_new(q->args, "reconstruct", json_true());
    if (m)
        json_object_set_new(q->args, "method", json_string(m));
    return 0;
}

static int set_budget(client_req *q, const char *v)
{
    char *end;
    double b = strtod(v, &end);
    if (*end || end == v || !(b > 0)) {
        fprintf(stderr, "scicap: --budget wants a time in seconds, got '%s'\n", v);
        return 2;
    }
    json_object_set_new(q->args, "budget_s", json_real(b));
    return 0;
}

/* An option with an integer (count, exposure-us, pattern-us, dark-us, average, iters). */
static int set_integer(client_req *q, int c, const char *v, const char *opt)
{
    static const char *const keys[] = {[O_COUNT - O_COUNT] = "count", [O_EXPOSURE - O_COUNT] = "exposure_us",
                                       [O_PATTERN - O_COUNT] = "pattern_us", [O_DARK_US - O_COUNT] = "dark_us"};
    long long n;
    if (parse_count(v, opt, &n) < 0)
        return 2;
    if (c == O_AVERAGE)
        json_object_set_new(q->args, "average", json_integer(n));
    else if (c == O_ITERS)
        json_object_set_new(q->params ? q->params : (q->params = json_object()), "iters", json_integer(n));
    else
        json_object_set_new(q->args, keys[c - O_COUNT], json_integer(n));
    return 0;
}

static int set_string(client_req *q, int c, const char *v)
{
    static const struct { int opt; const char *key; } keys[] = {
        {O_MASK_VAR, "mask_var"}, {O_MEAS_VAR, "meas_var"}, {O_TRUTH_VAR, "truth_var"}, {O_MASK_SET, "mask_set"},
        {O_SYNC_MODE, "sync_mode"}, {O_METHOD, "method"}, {O_PRESET, "preset"}, {O_CAPTURE, "capture"}};
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
        if (keys[i].opt == c)
            json_object_set_new(q->args, keys[i].key, json_string(v));
    return 0;
}

/* One option into q: 0, 1 (--help printed), 2 (usage error, said why). */
static int take_option(client_req *q, int c, int argc, char **argv)
{
    switch (c) {
    case O_SOCKET: q->sock = optarg; return 0;
    case O_JSON: q->raw = 1; return 0;
    case O_ALL: q->all = 1; return 0;
    case O_FROM: q->from = optarg; return 0;
    case O_MASK: q->mask_file = optarg; return 0;
    case O_WAIT: q->wait = 1; return 0;
    case O_ALLOW_LARGE: json_object_set_new(q->args, "allow_large", json_true()); return 0;
    case O_DARK: q->kind = 0; return 0;
    case O_MASKS: q->kind = 1; return 0;
    case O_SCALE: return set_scale(q, optarg);
    case O_RECON: return set_recon(q, optarg, argc, argv);
    case O_BUDGET: return set_budget(q, optarg);
    case O_COUNT: case O_EXPOSURE: case O_PATTERN: case O_DARK_US: case O_AVERAGE: case O_ITERS:
        return set_integer(q, c, optarg, argv[optind - 1]);
    case O_MASK_VAR: case O_MEAS_VAR: case O_TRUTH_VAR: case O_MASK_SET: case O_SYNC_MODE: case O_METHOD:
    case O_PRESET: case O_CAPTURE:
        return set_string(q, c, optarg);
    case O_HELP: usage(stdout, q->cmd); return 1;
    default: return 2;
    }
}

static int parse_options(client_req *q, int argc, char **argv)
{
    int c, rc = 0;
    optind = 1;
    opterr = 1;
    while (rc == 0 && (c = getopt_long(argc, argv, "", q->cmd->opts, NULL)) != -1)
        rc = take_option(q, c, argc, argv);
    if (rc == 0 && q->params) {
        json_object_set_new(q->args, "params", q->params);
        q->params = NULL;
    }
    if (rc == 0 && q->cmd->check)
        rc = q->cmd->check(q, argc, argv);
    else if (rc == 0 && optind < argc) {
        fprintf(stderr, "scicap %s: unexpected argument '%s'\n", q->cmd->name, argv[optind]);
        rc = 2;
    }
    return rc;
}

/* ---- checks of each command ---- */

static int no_positional(const client_req *q, int argc, char **argv, const char *who)
{
    if (optind >= argc)
        return 0;
    fprintf(stderr, "scicap %s: unexpected argument '%s'\n", who, argv[optind]);
    return 2;
}

static int check_cancel(client_req *q, int argc, char **argv)
{
    long long v;
    if (optind >= argc) {
        fprintf(stderr, "scicap cancel: which job? (scicap jobs lists them)\n");
        return 2;
    }
    if (parse_count(argv[optind], "JOB", &v) < 0)
        return 2;
    json_object_set_new(q->args, "job", json_integer(v));
    optind++;
    return no_positional(q, argc, argv, "cancel");
}

static int check_list(client_req *q, int argc, char **argv)
{
    if (q->all == 0 && !strcmp(q->cmd->request, "captures"))
        json_object_set_new(q->args, "limit", json_integer(CLI_RECENT_CAPTURES));
    return no_positional(q, argc, argv, q->cmd->name);
}

static int check_calibrate(client_req *q, int argc, char **argv)
{
    if (q->kind < 0) {
        fprintf(stderr, "scicap calibrate: say --dark or --masks\n");
        return 2;
    }
    json_object_set_new(q->args, "kind", json_string(q->kind ? "masks" : "dark"));
    q->wait = 1;
    return no_positional(q, argc, argv, "calibrate");
}

static int check_reconstruct(client_req *q, int argc, char **argv)
{
    if (!json_object_get(q->args, "capture")) {
        fprintf(stderr, "scicap recon: --capture ID is required to reconstruct through the daemon\n");
        return 2;
    }
    return no_positional(q, argc, argv, "recon");
}

static int check_capture(client_req *q, int argc, char **argv)
{
    static const char *const import_keys[] = {"mask_var", "meas_var", "truth_var", "scale", "allow_large", NULL};
    static const char *const bench_keys[] = {"mask_set", "pattern_us", "dark_us", "exposure_us", "sync_mode",
                                             "count", NULL};
    for (int i = 0; !q->from && import_keys[i]; i++)
        if (json_object_get(q->args, import_keys[i]) || q->mask_file) {
            fprintf(stderr, "scicap capture: --mask, --mask-var, --meas-var, --truth-var, --scale and --allow-large "
                            "go with --from\n");
            return 2;
        }
    for (int i = 0; q->from && bench_keys[i]; i++)
        if (json_object_get(q->args, bench_keys[i])) {
            fprintf(stderr, "scicap capture: --from takes the snapshots from the file, not the bench: no --%s\n",
                    bench_keys[i]);
            return 2;
        }
    return no_positional(q, argc, argv, "capture");
}

/* ---- replies for people ---- */

static int show_status(conn *c, const json_t *r, const client_req *q)
{
    print_status(stdout, r);
    return 0;
}

static int show_devices(conn *c, const json_t *r, const client_req *q)
{
    print_devices(stdout, r);
    return 0;
}

static int show_reload(conn *c, const json_t *r, const client_req *q)
{
    json_t *k;
    size_t i;
    printf("configuration reloaded from %s\n", str(r, "config")[0] ? str(r, "config") : "(built-in defaults)");
    json_array_foreach(json_object_get(r, "restart_needed"), i, k)
        printf("  %s changed: takes effect at the next restart\n", json_string_value(k));
    return 0;
}

static int show_shutdown(conn *c, const json_t *r, const client_req *q)
{
    printf("scicapd is stopping\n");
    return 0;
}

/* What a budget chose, before the job runs. */
static void print_budget(long long job, const json_t *b)
{
    printf("job %lld: budget %.3g s: %s %s, predicted %.3g s, expected PSNR %.2f dB (mean over the measured scenes)\n",
           job, num(b, "budget_s"), str(b, "method"), json_object_get(b, "setting") ? str(b, "setting") : "",
           num(b, "predicted_s"), num(b, "expected_psnr_db"));
}

static int show_queued(conn *c, const json_t *r, const client_req *q)
{
    long long job = integer(r, "job");
    if (json_object_get(r, "method"))
        printf("job %lld queued: %s (%s) of %s\n", job, str(r, "method"), str(r, "preset"), str(r, "capture"));
    else
        printf("job %lld queued\n", job);
    if (json_object_get(r, "budget"))
        print_budget(job, json_object_get(r, "budget"));
    fflush(stdout);
    return q->wait ? follow(c, 1, !strcmp(q->cmd->request, "reconstruct")) : 0;
}

static int is_finished(const char *state)
{
    return !strcmp(state, "done") || !strcmp(state, "failed") || !strcmp(state, "canceled");
}

static int show_cancel(conn *c, const json_t *r, const client_req *q)
{
    const char *state = str(r, "state");
    if (q->raw)
        print_json(r);
    if (is_finished(state)) {
        fprintf(stderr, "scicap cancel: job %lld already finished (%s): nothing to cancel\n", integer(r, "job"),
                state);
        return 1;
    }
    if (!q->raw)
        printf("job %lld: cancel requested (it was %s)\n", integer(r, "job"), state);
    return 0;
}

static int show_watch(conn *c, const json_t *r, const client_req *q)
{
    /* no SA_RESTART: Ctrl-C interrupts the blocking read at once instead of waiting for the next event */
    struct sigaction sa = {.sa_handler = on_sigint};
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    json_t *m;
    while (!interrupted && (m = conn_read(c))) {
        if (json_object_get(m, "event")) {
            if (q->raw)
                print_event_raw(m);
            else
                print_event(c, m);
        }
        json_decref(m);
    }
    return 0;
}

static int by_job(const void *a, const void *b)
{
    long long x = integer(*(json_t *const *)a, "job"), y = integer(*(json_t *const *)b, "job");
    return x < y ? -1 : x > y;
}

static void print_job(const json_t *j)
{
    char prog[32], ps[16] = "", outs[1024];
    snprintf(prog, sizeof prog, "%lld/%lld", integer(j, "done"), integer(j, "total"));
    if (json_object_get(j, "psnr"))
        snprintf(ps, sizeof ps, "%.2f", num(j, "psnr"));
    printf("%6lld  %-11s  %-9s  %9s  %-8s  %s\n", integer(j, "job"), str(j, "kind"), str(j, "state"), prog, ps,
           json_object_get(j, "error") ? str(j, "error") : joined(json_object_get(j, "outputs"), outs, sizeof outs));
}

/* The active jobs and the CLI_RECENT_JOBS newest finished ones (every one with --all), by job number. */
static int show_jobs(conn *c, const json_t *r, const client_req *q)
{
    const json_t *jobs = json_object_get(r, "jobs");
    size_t n = json_array_size(jobs), shown = 0, finished = 0;
    json_t **v = calloc(n ? n : 1, sizeof *v);
    if (!v)
        return 1;
    for (size_t i = 0; i < n; i++)
        v[i] = json_array_get(jobs, i);
    qsort(v, n, sizeof *v, by_job);
    for (size_t i = 0; i < n; i++)
        finished += is_finished(str(v[i], "state"));
    size_t hidden = !q->all && finished > CLI_RECENT_JOBS ? finished - CLI_RECENT_JOBS : 0, skipped = 0;
    printf("%6s  %-11s  %-9s  %9s  %-8s  %s\n", "job", "kind", "state", "progress", "psnr", "outputs / error");
    for (size_t i = 0; i < n; i++) {
        if (is_finished(str(v[i], "state")) && skipped < hidden) {
            skipped++;
            continue;
        }
        print_job(v[i]);
        shown++;
    }
    free(v);
    if (!shown)
        printf("(no jobs)\n");
    if (hidden)
        printf("(%zu older finished job%s hidden; scicap jobs --all lists them)\n", hidden, hidden == 1 ? "" : "s");
    return 0;
}

/* "2026-11-28T20:02:13Z" as "2026-11-28 20:02:13 UTC" ("-" when unknown). */
static const char *when(const json_t *o, char *buf, size_t n)
{
    const char *t = str(o, "time");
    if (strlen(t) == 20 && t[10] == 'T')
        snprintf(buf, n, "%.10s %.8s UTC", t, t + 11);
    else
        snprintf(buf, n, "%s", t[0] ? t : "-");
    return buf;
}

static void print_recon_line(const json_t *e)
{
    char q[64], t[40], it[32] = "";
    if (json_object_get(e, "iterations"))
        snprintf(it, sizeof it, ", %lld iterations", integer(e, "iterations"));
    printf("    recon/%-16s %s%s in %.2f s%s, %s\n", str(e, "folder"), str(e, "method"), quality(e, q, sizeof q),
           num(e, "solve_s"), it, when(e, t, sizeof t));
    const json_t *b = json_object_get(e, "budget");
    if (b)
        printf("    %-22s chosen for a budget of %.3g s (%s, predicted %.3g s, expected %.2f dB)\n", "",
               num(b, "budget_s"), json_object_get(b, "setting") ? str(b, "setting") : str(b, "method"),
               num(b, "predicted_s"), num(b, "expected_psnr_db"));
}

static void print_capture(const json_t *e)
{
    char t[40], size[48];
    snprintf(size, sizeof size, "%lldx%lldx%lld", integer(e, "w"), integer(e, "h"), integer(e, "frames"));
    printf("%-8s  %-23s  %-12s  %s%s%s%s%s\n", str(e, "capture"), when(e, t, sizeof t), size, str(e, "source"),
           json_object_get(e, "scene") ? " (scene " : "", str(e, "scene"), json_object_get(e, "scene") ? ")" : "",
           json_is_true(json_object_get(e, "truth")) ? ", with truth" : ", no truth");
    if (json_is_true(json_object_get(e, "broken")))
        printf("    broken sync: stored flagged\n");
    size_t i;
    const json_t *r;
    json_array_foreach(json_object_get(e, "recons"), i, r)
        print_recon_line(r);
}

static int show_captures(conn *c, const json_t *r, const client_req *q)
{
    const json_t *list = json_object_get(r, "captures");
    size_t i, n = json_array_size(list);
    long long total = integer(r, "total");
    const json_t *e;
    if (!n)
        printf("(no captures stored)\n");
    else
        printf("%-8s  %-23s  %-12s  %s\n", "capture", "taken", "w x h x N", "source");
    json_array_foreach(list, i, e)
        print_capture(e);
    if (total > (long long)n)
        printf("(%lld older capture%s hidden; scicap captures --all lists them)\n", total - (long long)n,
               total - (long long)n == 1 ? "" : "s");
    return 0;
}

/* ---- one run ---- */

/* Send q's request (the import's descriptors with it). Steals q->args. 0 or -1 (said why). */
static int send_request(conn *c, client_req *q, const char *request)
{
    /* conn_send steals non-empty args (freed with the request): decide before, never look at args after */
    json_t *args = json_object_size(q->args) ? q->args : NULL;
    if (!args)
        json_decref(q->args);
    q->args = NULL;
    int rc = q->from ? conn_send_fds(c, request, args, q->fds, q->nfds) : conn_send(c, request, args);
    close_all(q->fds, q->nfds); /* the daemon has its own copies of the descriptors now */
    q->nfds = 0;
    return rc;
}

/* Options into q, and with --from the files opened: 0, or the exit status to return (said why). */
static int prepare(client_req *q, int argc, char **argv, const char *who)
{
    int rc = parse_options(q, argc, argv);
    if (rc != 0) {
        json_decref(q->params);
        if (rc == 2)
            fprintf(stderr, "(scicap %s --help lists its options)\n", who);
        return rc == 1 ? 0 : rc;
    }
    if (q->from && (q->nfds = open_import(q->from, q->mask_file, q->args, q->fds)) < 0)
        return q->nfds == -2 ? 2 : 1;
    return -1;
}

/* The request to the daemon, its reply shown by the command's hook: the exit status. */
static int exchange(client_req *q, const char *who)
{
    conn cn = {.fd = -1, .who = who, .raw = q->raw};
    if (conn_open(&cn, q->sock) < 0) {
        json_decref(q->args);
        close_all(q->fds, q->nfds);
        return 1;
    }
    int rc = 1;
    json_t *r = NULL;
    if (send_request(&cn, q, q->from ? "import" : q->cmd->request) == 0 && (r = conn_reply(&cn))) {
        rc = 0;
        if (q->raw && !q->cmd->own_json)
            print_json(r);
        else
            rc = q->cmd->show(&cn, r, q);
    }
    json_decref(r);
    conn_close(&cn);
    return rc;
}

static int run(const client_cmd *cc, int argc, char **argv)
{
    client_req q = {.cmd = cc, .sock = default_socket(), .args = json_object(), .kind = -1};
    const char *who = strcmp(cc->name, "reconstruct") ? cc->name : "recon";
    int rc = prepare(&q, argc, argv, who);
    if (rc >= 0) {
        json_decref(q.args);
        return rc;
    }
    return exchange(&q, who);
}

int cli_client_main(int argc, char **argv)
{
    const client_cmd *cc = argc >= 1 ? find_cmd(argv[0]) : NULL;
    if (!cc || !strcmp(cc->name, "reconstruct")) {
        fprintf(stderr, "scicap: '%s' is not a daemon command\n", argc ? argv[0] : "?");
        return 2;
    }
    return run(cc, argc, argv);
}

int cli_client_recon(int argc, char **argv) { return run(find_cmd("reconstruct"), argc, argv); }
