/* scicap status|devices|capture|calibrate|jobs|cancel|watch|reload|shutdown, scicap recon --capture: the
 * daemon's client. One request per run; --wait follows the job's events until it ends. */
#include "cli/client.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <jansson.h>
#include <math.h>
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
        fprintf(stderr, "scicap: %s: write failed: %s\n", c->path, strerror(errno));
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
        fprintf(stderr, "scicap: %s: write failed: %s\n", c->path, strerror(errno));
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

/* Wait for the reply to our request (events before it are ignored). Returns the result (new ref) or NULL
 * after printing the error. */
static json_t *conn_reply(conn *c, const char *cmd)
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
        json_t *e = json_object_get(m, "error");
        fprintf(stderr, "scicap %s: %s: %s\n", cmd, json_string_value(json_object_get(e, "code")),
                json_string_value(json_object_get(e, "message")));
        json_decref(m);
        return NULL;
    }
    fprintf(stderr, "scicap %s: scicapd closed the connection\n", cmd);
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
    fprintf(f, "%-10s %lld connected\n", "clients", (long long)json_integer_value(json_object_get(r, "clients")));
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

static void progress_bar(conn *c, const json_t *d, long long job)
{
    int it = (int)json_integer_value(json_object_get(d, "iter")), n = (int)json_integer_value(json_object_get(d, "iters"));
    double psnr = json_number_value(json_object_get(d, "psnr"));
    double eta = json_number_value(json_object_get(d, "eta_s"));
    int w = 30, fill = n > 0 ? it * w / n : 0;
    char bar[64];
    for (int i = 0; i < w; i++)
        bar[i] = i < fill ? '#' : '.';
    bar[w] = '\0';
    if (c->tty)
        fprintf(stderr, "\r  job %lld [%s] %4d/%d  PSNR %6.2f dB  ETA %5.1f s ", job, bar, it, n,
                json_object_get(d, "psnr") ? psnr : NAN, eta);
    else if (it == n)
        fprintf(stderr, "  job %lld: %d/%d iterations, PSNR %.2f dB\n", job, it, n, psnr);
}

/* Print one event in human form. */
static void print_event(conn *c, const json_t *m)
{
    const char *ev = str(m, "event");
    long long job = json_integer_value(json_object_get(m, "job"));
    const json_t *d = json_object_get(m, "data");
    if (strcmp(ev, "recon.progress") == 0) {
        progress_bar(c, d, job);
        return;
    }
    if (c->tty)
        fprintf(stderr, "\r%80s\r", "");
    if (strcmp(ev, "capture.stored") == 0)
        printf("job %lld: stored %s (%s)%s, %.0f ms after the request\n", job, str(d, "capture"), str(d, "dir"),
               json_is_true(json_object_get(d, "broken")) ? " BROKEN SYNC" : "",
               json_number_value(json_object_get(d, "latency_ms")));
    else if (strcmp(ev, "import.stored") == 0)
        printf("job %lld: stored %s (%s), snapshot %lld of %lld\n", job, str(d, "capture"), str(d, "dir"),
               (long long)json_integer_value(json_object_get(d, "index")) + 1,
               (long long)json_integer_value(json_object_get(d, "count")));
    else if (strcmp(ev, "import.done") == 0) {
        printf("job %lld: imported %lld snapshots", job,
               (long long)json_integer_value(json_object_get(d, "snapshots")));
        if (json_object_get(d, "white"))
            printf(", values divided by %g%s%s", json_number_value(json_object_get(d, "white")),
                   json_object_get(d, "scale_auto") ? ": " : "", str(d, "scale_auto"));
        printf("\n");
    } else if (strcmp(ev, "recon.checkpoint") == 0)
        printf("job %lld: checkpoint at step %lld (%.1f MB)\n", job,
               (long long)json_integer_value(json_object_get(d, "iter")),
               json_number_value(json_object_get(d, "bytes")) / 1e6);
    else if (strcmp(ev, "recon.done") == 0)
        printf("job %lld: %s of %s: PSNR %.2f dB in %.2f s -> %s\n", job, str(d, "method"), str(d, "capture"),
               json_number_value(json_object_get(d, "psnr")), json_number_value(json_object_get(d, "solve_s")),
               str(d, "dir"));
    else {
        char *s = json_dumps(d, JSON_COMPACT);
        printf("job %lld: %s %s\n", job, ev, s);
        free(s);
    }
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
       O_CAPTURE, O_ITERS, O_BUDGET, O_HELP };

/* One getopt table per command, so each accepts exactly its own options and its --help lists exactly those
 * (tests/integration/test_cli_help.c reads these tables). */
static const struct option plain_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"json", no_argument, 0, O_JSON}, {"help", no_argument, 0, O_HELP},
    {0, 0, 0, 0}};
static const struct option capture_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"mask-set", required_argument, 0, O_MASK_SET},
    {"count", required_argument, 0, O_COUNT}, {"exposure-us", required_argument, 0, O_EXPOSURE},
    {"pattern-us", required_argument, 0, O_PATTERN}, {"dark-us", required_argument, 0, O_DARK_US},
    {"sync", required_argument, 0, O_SYNC_MODE}, {"recon", optional_argument, 0, O_RECON},
    {"method", required_argument, 0, O_METHOD}, {"preset", required_argument, 0, O_PRESET},
    {"wait", no_argument, 0, O_WAIT}, {"from", required_argument, 0, O_FROM}, {"mask", required_argument, 0, O_MASK},
    {"mask-var", required_argument, 0, O_MASK_VAR}, {"meas-var", required_argument, 0, O_MEAS_VAR},
    {"truth-var", required_argument, 0, O_TRUTH_VAR}, {"scale", required_argument, 0, O_SCALE},
    {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};
static const struct option calibrate_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"dark", no_argument, 0, O_DARK}, {"masks", no_argument, 0, O_MASKS},
    {"mask-set", required_argument, 0, O_MASK_SET}, {"average", required_argument, 0, O_AVERAGE},
    {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};
static const struct option reconstruct_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"capture", required_argument, 0, O_CAPTURE},
    {"method", required_argument, 0, O_METHOD}, {"preset", required_argument, 0, O_PRESET},
    {"iters", required_argument, 0, O_ITERS}, {"budget", required_argument, 0, O_BUDGET},
    {"wait", no_argument, 0, O_WAIT}, {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};

/* What each option means, for every command's help. */
static const struct { const char *name, *arg, *text; } opt_help[] = {
    {"socket", "PATH", "the daemon's control socket (default $SCICAP_SOCKET, else " CLI_CLIENT_DEFAULT_SOCKET ")"},
    {"json", NULL, "print the daemon's reply (watch: each event) as JSON, unformatted for people"},
    {"mask-set", "S", "the mask set the DMD shows (a name from the daemon's configuration)"},
    {"count", "N", "snapshots to capture (default 1)"},
    {"exposure-us", "U", "camera exposure per snapshot, microseconds"},
    {"pattern-us", "U", "DMD display time per mask, microseconds"},
    {"dark-us", "U", "DMD dark time after each mask, microseconds"},
    {"sync", "MODE", "host-master (the host triggers both) or dmd-master (the DMD triggers the camera)"},
    {"recon", "[METHOD]", "queue a reconstruction of each snapshot ('--recon METHOD' and '--recon=METHOD' both\n"
                          "                     work; default: the daemon's reconstruction.method); methods:"},
    {"method", "M", "the method (the NeRF ones need a capture with a camera):"},
    {"preset", "P", "fast, balanced or best (default and quality: deprecated aliases)"},
    {"wait", NULL, "wait for the job (and its reconstructions) to finish, with progress"},
    {"from", "FILE|DIR", "no bench: captures from a .mat or a problem folder, read by the daemon through\n"
                         "                     descriptors this command opens (your rights, not the daemon's)"},
    {"mask", "FILE", "with --from FILE.mat: the .mat that holds the masks"},
    {"mask-var", "V", "with --from: the masks' variable (default mask)"},
    {"meas-var", "V", "with --from: the measurements' variable (default meas)"},
    {"truth-var", "V", "with --from: the ground truth's variable (default orig, optional)"},
    {"scale", "auto|N", "with --from: the data's white level (default 255); auto reads it from the data"},
    {"dark", NULL, "measure the dark frame"},
    {"masks", NULL, "measure the masks as the camera sees them"},
    {"average", "N", "frames averaged per measurement"},
    {"capture", "ID", "the capture to reconstruct (see scicap jobs)"},
    {"iters", "N", "iterations (overrides the preset)"},
    {"budget", "SECONDS", "the most accurate measured setting that fits in SECONDS (bench/results.csv)"},
    {"help", NULL, "this text"},
};

typedef struct client_cmd {
    const char *name, *synopsis, *what;
    const struct option *opts;
} client_cmd;

static const client_cmd client_cmds[] = {
    {"status", "scicap status [--socket PATH] [--json]", "The daemon's state, queues and counters.", plain_opts},
    {"devices", "scicap devices [--socket PATH] [--json]", "The devices the daemon drives, their identities and state.",
     plain_opts},
    {"capture",
     "scicap capture [--mask-set S] [--count N] [--exposure-us U] [--pattern-us U] [--dark-us U]\n"
     "                      [--sync host-master|dmd-master] [--recon [METHOD]] [--method M] [--preset P] [--wait]\n"
     "       scicap capture --from FILE.mat|DIR [--mask FILE.mat] [--mask-var V] [--meas-var V] [--truth-var V]\n"
     "                      [--scale auto|N] [--recon [METHOD]] [--method M] [--preset P] [--wait]",
     "Capture coded snapshots on the bench (and reconstruct them with --recon); with --from, store the snapshots\n"
     "of a file or problem folder as captures instead (each snapshot one capture, as from the bench).",
     capture_opts},
    {"calibrate", "scicap calibrate --dark|--masks [--mask-set S] [--average N]",
     "Measure the dark frame or the masks as the camera sees them; waits for the result.", calibrate_opts},
    {"jobs", "scicap jobs [--socket PATH] [--json]", "Queued, running and recent jobs.", plain_opts},
    {"cancel", "scicap cancel [--socket PATH] [--json] JOB", "Cancel a queued or running job.", plain_opts},
    {"watch", "scicap watch [--socket PATH] [--json]",
     "Follow the daemon's event stream with a progress bar (Ctrl-C ends).", plain_opts},
    {"reload", "scicap reload [--socket PATH] [--json]", "Reload the daemon's configuration (admin).", plain_opts},
    {"shutdown", "scicap shutdown [--socket PATH] [--json]", "Stop the daemon (admin).", plain_opts},
    {"reconstruct",
     "scicap recon --capture ID [--method M] [--preset fast|balanced|best] [--iters N] [--wait]\n"
     "       scicap recon --capture ID --budget SECONDS [--method M] [--wait]",
     "Ask the daemon to reconstruct one of its captures (files: scicap recon --help).", reconstruct_opts},
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

#define CLI_IMPORT_MAX_FILES 250 /* the daemon's SCICAPD_IMPORT_MAX_FILES */

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

static int run(int argc, char **argv, int recon_mode)
{
    const char *cmd = recon_mode ? "reconstruct" : argv[0];
    const client_cmd *cc = find_cmd(cmd);
    const char *sock = default_socket();
    json_t *args = json_object(), *params = NULL;
    int wait = 0, kind = -1, raw = 0, c, fds[CLI_IMPORT_MAX_FILES], nfds = 0;
    const char *from = NULL, *mask_file = NULL;
    long long v;
    optind = 1;
    opterr = 1;
    while ((c = getopt_long(argc, argv, "", cc->opts, NULL)) != -1) {
        switch (c) {
        case O_SOCKET: sock = optarg; break;
        case O_JSON: raw = 1; break;
        case O_FROM: from = optarg; break;
        case O_MASK: mask_file = optarg; break;
        case O_MASK_VAR: json_object_set_new(args, "mask_var", json_string(optarg)); break;
        case O_MEAS_VAR: json_object_set_new(args, "meas_var", json_string(optarg)); break;
        case O_TRUTH_VAR: json_object_set_new(args, "truth_var", json_string(optarg)); break;
        case O_SCALE: {
            char *end;
            double sc = strtod(optarg, &end);
            if (!strcmp(optarg, "auto"))
                json_object_set_new(args, "scale", json_string("auto"));
            else if (*end || end == optarg || !(sc > 0)) {
                fprintf(stderr, "scicap: --scale wants auto or a white level > 0, got '%s'\n", optarg);
                goto usage_err;
            } else
                json_object_set_new(args, "scale", json_real(sc));
            break;
        }
        case O_MASK_SET: json_object_set_new(args, "mask_set", json_string(optarg)); break;
        case O_SYNC_MODE: json_object_set_new(args, "sync_mode", json_string(optarg)); break;
        case O_METHOD: json_object_set_new(args, "method", json_string(optarg)); break;
        case O_PRESET: json_object_set_new(args, "preset", json_string(optarg)); break;
        case O_CAPTURE: json_object_set_new(args, "capture", json_string(optarg)); break;
        case O_RECON: {
            /* --recon takes an optional method; getopt only binds "--recon=M", so take "--recon M" here too
             * (capture has no positional arguments, so a following method name cannot be anything else). */
            const char *m = optarg;
            if (!m && optind < argc && solver_find(argv[optind]))
                m = argv[optind++];
            if (m && !solver_find(m)) {
                char names[256];
                fprintf(stderr, "scicap capture: --recon reconstructs with %s, not '%s'\n",
                        solver_names_text(names, sizeof names, ", "), m);
                goto usage_err;
            }
            json_object_set_new(args, "reconstruct", json_true());
            if (m)
                json_object_set_new(args, "method", json_string(m));
            break;
        }
        case O_WAIT: wait = 1; break;
        case O_BUDGET: {
            char *end;
            double b = strtod(optarg, &end);
            if (*end || end == optarg || !(b > 0)) {
                fprintf(stderr, "scicap: --budget wants a time in seconds, got '%s'\n", optarg);
                goto usage_err;
            }
            json_object_set_new(args, "budget_s", json_real(b));
            break;
        }
        case O_DARK: kind = 0; break;
        case O_MASKS: kind = 1; break;
        case O_COUNT: case O_EXPOSURE: case O_PATTERN: case O_DARK_US: case O_AVERAGE: case O_ITERS: {
            static const char *const keys[] = {[O_COUNT - O_COUNT] = "count", [O_EXPOSURE - O_COUNT] = "exposure_us",
                                               [O_PATTERN - O_COUNT] = "pattern_us", [O_DARK_US - O_COUNT] = "dark_us"};
            if (parse_count(optarg, argv[optind - 1], &v) < 0)
                goto usage_err;
            if (c == O_AVERAGE)
                json_object_set_new(args, "average", json_integer(v));
            else if (c == O_ITERS) {
                if (!params)
                    params = json_object();
                json_object_set_new(params, "iters", json_integer(v));
            } else
                json_object_set_new(args, keys[c - O_COUNT], json_integer(v));
            break;
        }
        case O_HELP: usage(stdout, cc); json_decref(args); json_decref(params); return 0;
        default: goto usage_err;
        }
    }
    if (params)
        json_object_set_new(args, "params", params);
    const char *pos = optind < argc ? argv[optind] : NULL;
    if (!strcmp(cmd, "cancel")) {
        if (!pos || parse_count(pos, "JOB", &v) < 0)
            goto usage_err;
        json_object_set_new(args, "job", json_integer(v));
        if (optind + 1 < argc) {
            fprintf(stderr, "scicap cancel: unexpected argument '%s'\n", argv[optind + 1]);
            goto usage_err;
        }
    } else if (pos) {
        fprintf(stderr, "scicap %s: unexpected argument '%s'\n", cmd, pos);
        goto usage_err;
    }
    if (!strcmp(cmd, "calibrate")) {
        if (kind < 0) {
            fprintf(stderr, "scicap calibrate: say --dark or --masks\n");
            goto usage_err;
        }
        json_object_set_new(args, "kind", json_string(kind ? "masks" : "dark"));
        wait = 1;
    }
    if (recon_mode && !json_object_get(args, "capture")) {
        fprintf(stderr, "scicap recon: --capture ID is required to reconstruct through the daemon\n");
        goto usage_err;
    }
    static const char *const import_keys[] = {"mask_var", "meas_var", "truth_var", "scale", NULL};
    static const char *const bench_keys[] = {"mask_set", "pattern_us", "dark_us", "exposure_us", "sync_mode",
                                             "count", NULL};
    for (int i = 0; !from && import_keys[i]; i++)
        if (json_object_get(args, import_keys[i]) || mask_file) {
            fprintf(stderr, "scicap capture: --mask, --mask-var, --meas-var, --truth-var and --scale go with --from\n");
            goto usage_err;
        }
    for (int i = 0; from && bench_keys[i]; i++)
        if (json_object_get(args, bench_keys[i])) {
            fprintf(stderr, "scicap capture: --from takes the snapshots from the file, not the bench: no --%s\n",
                    bench_keys[i]);
            goto usage_err;
        }
    if (from) {
        if ((nfds = open_import(from, mask_file, args, fds)) < 0) {
            json_decref(args);
            return nfds == -2 ? 2 : 1;
        }
        cmd = "import";
    }
    conn cn = {.fd = -1};
    if (conn_open(&cn, sock) < 0) {
        json_decref(args);
        close_all(fds, nfds);
        return 1;
    }
    /* conn_send steals non-empty args (freed with the request): decide before, never look at args after */
    json_t *send_args = json_object_size(args) ? args : NULL;
    if (!send_args)
        json_decref(args);
    args = NULL;
    int sent = from ? conn_send_fds(&cn, cmd, send_args, fds, nfds) : conn_send(&cn, cmd, send_args);
    close_all(fds, nfds); /* the daemon has its own copies of the descriptors now */
    if (sent < 0) {
        conn_close(&cn);
        return 1;
    }
    int rc = 0;
    if (!strcmp(cmd, "watch")) {
        json_t *r = conn_reply(&cn, cmd);
        if (!r) {
            conn_close(&cn);
            return 1;
        }
        json_decref(r);
        signal(SIGINT, on_sigint);
        json_t *m;
        while (!interrupted && (m = conn_read(&cn))) {
            if (json_object_get(m, "event")) {
                if (raw) {
                    char *line = json_dumps(m, JSON_COMPACT | JSON_PRESERVE_ORDER);
                    printf("%s\n", line);
                    free(line);
                    fflush(stdout);
                } else {
                    print_event(&cn, m);
                }
            }
            json_decref(m);
        }
        conn_close(&cn);
        return 0;
    }
    json_t *r = conn_reply(&cn, cmd);
    if (!r) {
        conn_close(&cn);
        return 1;
    }
    if (raw) {
        print_json(r);
    } else if (!strcmp(cmd, "status")) {
        print_status(stdout, r);
    } else if (!strcmp(cmd, "devices")) {
        print_devices(stdout, r);
    } else if (!strcmp(cmd, "reload")) {
        json_t *rk = json_object_get(r, "restart_needed"), *k;
        size_t i;
        printf("configuration reloaded from %s\n", str(r, "config")[0] ? str(r, "config") : "(built-in defaults)");
        json_array_foreach(rk, i, k)
            printf("  %s changed: takes effect at the next restart\n", json_string_value(k));
    } else if (!strcmp(cmd, "shutdown")) {
        printf("scicapd is stopping\n");
    } else if (!strcmp(cmd, "cancel")) {
        printf("job %lld: cancel requested (state %s)\n", (long long)json_integer_value(json_object_get(r, "job")),
               str(r, "state"));
    } else if (json_object_get(r, "job") && json_object_size(r) == 2 && json_object_get(r, "state")) {
        printf("job %lld queued\n", (long long)json_integer_value(json_object_get(r, "job")));
        fflush(stdout);
        if (wait)
            rc = follow(&cn, 1, recon_mode);
    } else if (!strcmp(cmd, "jobs")) {
        json_t *jobs = json_object_get(r, "jobs"), *j;
        size_t i;
        printf("%6s  %-11s  %-9s  %9s  %-8s  %s\n", "job", "kind", "state", "progress", "psnr", "outputs / error");
        json_array_foreach(jobs, i, j) {
            char prog[32], ps[16] = "";
            snprintf(prog, sizeof prog, "%lld/%lld", (long long)json_integer_value(json_object_get(j, "done")),
                     (long long)json_integer_value(json_object_get(j, "total")));
            if (json_object_get(j, "psnr"))
                snprintf(ps, sizeof ps, "%.2f", json_number_value(json_object_get(j, "psnr")));
            char *outs = json_dumps(json_object_get(j, "outputs"), JSON_COMPACT);
            printf("%6lld  %-11s  %-9s  %9s  %-8s  %s\n", (long long)json_integer_value(json_object_get(j, "job")),
                   str(j, "kind"), str(j, "state"), prog, ps, json_object_get(j, "error") ? str(j, "error") : outs);
            free(outs);
        }
    } else if (json_object_size(r)) {
        print_json(r);
    }
    json_decref(r);
    conn_close(&cn);
    return rc;
usage_err:
    json_decref(args);
    json_decref(params);
    fprintf(stderr, "(scicap %s --help lists its options)\n", recon_mode ? "recon" : cmd);
    return 2;
}

int cli_client_main(int argc, char **argv)
{
    static const char *const cmds[] = {"status", "devices", "capture", "calibrate", "jobs", "cancel", "watch",
                                       "reload", "shutdown", NULL};
    for (int i = 0; cmds[i]; i++)
        if (argc >= 1 && !strcmp(argv[0], cmds[i]))
            return run(argc, argv, 0);
    fprintf(stderr, "scicap: '%s' is not a daemon command\n", argc ? argv[0] : "?");
    return 2;
}

int cli_client_recon(int argc, char **argv) { return run(argc, argv, 1); }
