/* scicap status|devices|capture|calibrate|jobs|cancel|watch|reload|shutdown, scicap recon --capture: the
 * daemon's client. One request per run; --wait follows the job's events until it ends. */
#include "cli/client.h"

#include <errno.h>
#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

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
        else if (!strcmp(ev, "capture.done") || !strcmp(ev, "calibrate.done"))
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

enum { O_SOCKET = 1000, O_MASK_SET, O_COUNT, O_EXPOSURE, O_PATTERN, O_DARK_US, O_SYNC, O_RECON, O_METHOD, O_PRESET,
       O_WAIT, O_DARK, O_MASKS, O_AVERAGE, O_CAPTURE, O_ITERS, O_BUDGET, O_HELP };

/* One getopt table per command, so each accepts exactly its own options and its --help lists exactly those
 * (tests/integration/test_cli_help.c reads these tables). */
static const struct option plain_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};
static const struct option capture_opts[] = {
    {"socket", required_argument, 0, O_SOCKET}, {"mask-set", required_argument, 0, O_MASK_SET},
    {"count", required_argument, 0, O_COUNT}, {"exposure-us", required_argument, 0, O_EXPOSURE},
    {"pattern-us", required_argument, 0, O_PATTERN}, {"dark-us", required_argument, 0, O_DARK_US},
    {"sync", required_argument, 0, O_SYNC}, {"recon", optional_argument, 0, O_RECON},
    {"method", required_argument, 0, O_METHOD}, {"preset", required_argument, 0, O_PRESET},
    {"wait", no_argument, 0, O_WAIT}, {"help", no_argument, 0, O_HELP}, {0, 0, 0, 0}};
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
    {"mask-set", "S", "the mask set the DMD shows (a name from the daemon's configuration)"},
    {"count", "N", "snapshots to capture (default 1)"},
    {"exposure-us", "U", "camera exposure per snapshot, microseconds"},
    {"pattern-us", "U", "DMD display time per mask, microseconds"},
    {"dark-us", "U", "DMD dark time after each mask, microseconds"},
    {"sync", "MODE", "host-master (the host triggers both) or dmd-master (the DMD triggers the camera)"},
    {"recon", "[METHOD]", "queue a reconstruction of each snapshot: gap-tv (default) or admm-tv;\n"
                          "                     '--recon METHOD' and '--recon=METHOD' both work"},
    {"method", "M", "gap-tv or admm-tv"},
    {"preset", "P", "fast, default or quality"},
    {"wait", NULL, "wait for the job (and its reconstructions) to finish, with progress"},
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
    {"status", "scicap status [--socket PATH]", "The daemon's state, queues and counters.", plain_opts},
    {"devices", "scicap devices [--socket PATH]", "The devices the daemon drives, their identities and state.",
     plain_opts},
    {"capture",
     "scicap capture [--mask-set S] [--count N] [--exposure-us U] [--pattern-us U] [--dark-us U]\n"
     "                      [--sync host-master|dmd-master] [--recon [METHOD]] [--method M] [--preset P] [--wait]",
     "Capture coded snapshots on the bench (and reconstruct them with --recon).", capture_opts},
    {"calibrate", "scicap calibrate --dark|--masks [--mask-set S] [--average N]",
     "Measure the dark frame or the masks as the camera sees them; waits for the result.", calibrate_opts},
    {"jobs", "scicap jobs [--socket PATH]", "Queued, running and recent jobs.", plain_opts},
    {"cancel", "scicap cancel [--socket PATH] JOB", "Cancel a queued or running job.", plain_opts},
    {"watch", "scicap watch [--socket PATH]", "Follow the daemon's event stream with a progress bar (Ctrl-C ends).",
     plain_opts},
    {"reload", "scicap reload [--socket PATH]", "Reload the daemon's configuration (admin).", plain_opts},
    {"shutdown", "scicap shutdown [--socket PATH]", "Stop the daemon (admin).", plain_opts},
    {"reconstruct",
     "scicap recon --capture ID [--method gap-tv|admm-tv] [--preset fast|default|quality] [--iters N] [--wait]\n"
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
                fprintf(f, "  %-18s %s\n", left, opt_help[i].text);
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

static volatile sig_atomic_t interrupted;
static void on_sigint(int s) { (void)s; interrupted = 1; }

static int run(int argc, char **argv, int recon_mode)
{
    const char *cmd = recon_mode ? "reconstruct" : argv[0];
    const client_cmd *cc = find_cmd(cmd);
    const char *sock = default_socket();
    json_t *args = json_object(), *params = NULL;
    int wait = 0, kind = -1, c;
    long long v;
    optind = 1;
    opterr = 1;
    while ((c = getopt_long(argc, argv, "", cc->opts, NULL)) != -1) {
        switch (c) {
        case O_SOCKET: sock = optarg; break;
        case O_MASK_SET: json_object_set_new(args, "mask_set", json_string(optarg)); break;
        case O_SYNC: json_object_set_new(args, "sync_mode", json_string(optarg)); break;
        case O_METHOD: json_object_set_new(args, "method", json_string(optarg)); break;
        case O_PRESET: json_object_set_new(args, "preset", json_string(optarg)); break;
        case O_CAPTURE: json_object_set_new(args, "capture", json_string(optarg)); break;
        case O_RECON: {
            /* --recon takes an optional method; getopt only binds "--recon=M", so take "--recon M" here too
             * (capture has no positional arguments, so a following method name cannot be anything else). */
            const char *m = optarg;
            if (!m && optind < argc && (!strcmp(argv[optind], "gap-tv") || !strcmp(argv[optind], "admm-tv")))
                m = argv[optind++];
            if (m && strcmp(m, "gap-tv") && strcmp(m, "admm-tv")) {
                fprintf(stderr, "scicap capture: --recon reconstructs with gap-tv or admm-tv, not '%s'\n", m);
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
    conn cn = {.fd = -1};
    if (conn_open(&cn, sock) < 0) {
        json_decref(args);
        return 1;
    }
    /* conn_send steals non-empty args (freed with the request): decide before, never look at args after */
    json_t *send_args = json_object_size(args) ? args : NULL;
    if (!send_args)
        json_decref(args);
    args = NULL;
    if (conn_send(&cn, cmd, send_args) < 0) {
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
            if (json_object_get(m, "event"))
                print_event(&cn, m);
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
    if (json_object_get(r, "job") && json_object_size(r) == 2 && json_object_get(r, "state")) {
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
