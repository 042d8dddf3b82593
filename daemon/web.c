/* daemon/web.c — the web view's HTTP server: routes, checks, assets, token (see web.h). */
#include "daemon/web.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <jansson.h>
#include <microhttpd.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/clock.h"
#include "daemon/web_bridge.h"
#include "daemon/web_events.h"
#include "recon/solver.h"

#define WEB_URL_MAX 1024
#define WEB_BODY_MAX 4096
#define WEB_FILE_MAX (64LL << 20)   /* largest capture file served (a preview GIF of 400 frames is ~30 MB) */
#define WEB_TOKEN_HEX 64
#define WEB_EVENTS_KEPT 256
#define WEB_STATE_CACHE_NS 250000000LL /* /api/state asks the control socket at most 4 times a second */
#define WEB_JOBS_KEPT 256           /* jobs started through the web that it may cancel */

/* One header set for every response: the page loads only its own scripts, styles, images and streams. */
#define WEB_CSP "default-src 'self'; img-src 'self'; script-src 'self'; style-src 'self'; connect-src 'self'; " \
                "object-src 'none'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"

enum { ASSET_INDEX, ASSET_APP, ASSET_STYLE, ASSET_CHART, ASSET_COUNT };

static const struct {
    const char *url, *file, *type;
} asset_table[ASSET_COUNT] = {
    [ASSET_INDEX] = {"/", "index.html", "text/html; charset=utf-8"},
    [ASSET_APP] = {"/assets/app.js", "app.js", "text/javascript; charset=utf-8"},
    [ASSET_STYLE] = {"/assets/style.css", "style.css", "text/css; charset=utf-8"},
    [ASSET_CHART] = {"/assets/chart.min.js", NULL, "text/javascript; charset=utf-8"},
};

struct scicapd_web {
    scicapd_web_options o;
    char host[64], socket_path[1024], storage_root[1024];
    const sci_log *log;
    struct MHD_Daemon *mhd;
    int port;
    char token[WEB_TOKEN_HEX + 1];
    char *asset[ASSET_COUNT];
    size_t asset_len[ASSET_COUNT];
    char *curves;                /* the curves CSV, or NULL */
    size_t curves_len;
    web_events *events;
    int loopback;
    pthread_mutex_t mu;          /* state cache and the job list */
    char *state;                 /* last /api/state body */
    int64_t state_ns;
    unsigned long long jobs[WEB_JOBS_KEPT];
    int njobs;
};

typedef struct web_request {
    int post;
    char *body;
    size_t len;
    int refused;                 /* a response was queued at the first call */
    int too_big;                 /* the body passed WEB_BODY_MAX: dropped as it comes, answered 413 at its end */
} web_request;

/* ---- assets, read once at start ---- */

static int read_file(const char *path, char **out, size_t *len, sci_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return sci_error_set(err, -errno, "web: %s: %s", path, strerror(errno));
    char *buf = NULL;
    size_t cap = 0, n = 0, r;
    do {
        if (n + 65536 > cap) {
            char *b = realloc(buf, cap = n + 65536);
            if (!b) {
                free(buf);
                fclose(f);
                return sci_error_set(err, -ENOMEM, "web: %s: out of memory", path);
            }
            buf = b;
        }
        r = fread(buf + n, 1, cap - n, f);
        n += r;
    } while (r > 0);
    fclose(f);
    *out = buf;
    *len = n;
    return 0;
}

/* The installed copy (make install: SCICAP_DATADIR/web), else the build tree's (<exe dir>/../daemon/web). */
static void assets_default(char *buf, size_t n)
{
    snprintf(buf, n, "%s/web", SCICAP_DATADIR);
    char probe[1200];
    snprintf(probe, sizeof probe, "%s/index.html", buf);
    if (access(probe, R_OK) == 0)
        return;
    char exe[1024];
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (len <= 0)
        return;
    exe[len] = '\0';
    char *slash = strrchr(exe, '/');
    if (slash) {
        *slash = '\0';
        snprintf(buf, n, "%s/../daemon/web", exe);
    }
}

static int assets_load(scicapd_web *w, sci_error *err)
{
    char dir[1100], path[1300];
    if (w->o.assets_dir)
        snprintf(dir, sizeof dir, "%s", w->o.assets_dir);
    else
        assets_default(dir, sizeof dir);
    for (int i = 0; i < ASSET_COUNT; i++) {
        if (asset_table[i].file)
            snprintf(path, sizeof path, "%s/%s", dir, asset_table[i].file);
        else
            snprintf(path, sizeof path, "%s",
                     w->o.chartjs_path ? w->o.chartjs_path : "/usr/share/javascript/chart.js/chart.min.js");
        int rc = read_file(path, &w->asset[i], &w->asset_len[i], err);
        if (rc < 0) {
            if (!asset_table[i].file)
                sci_error_set(err, rc, "web: Chart.js not found at %s (Debian package libjs-chart.js; `make deps`)",
                              path);
            return rc;
        }
    }
    return 0;
}

/* Optional: a daemon without measured curves still serves the page. */
static void curves_load(scicapd_web *w)
{
    sci_error e = {0};
    if (w->o.curves_path && read_file(w->o.curves_path, &w->curves, &w->curves_len, &e) < 0)
        sci_log_write(w->log, SCI_LOG_INFO, "%s: the page goes without its accuracy-against-time chart", e.msg);
}

/* ---- the token ---- */

static int token_write(scicapd_web *w, sci_error *err)
{
    unsigned char raw[WEB_TOKEN_HEX / 2];
    if (getrandom(raw, sizeof raw, 0) != (ssize_t)sizeof raw)
        return sci_error_set(err, -EIO, "web: getrandom: %s", strerror(errno));
    for (size_t i = 0; i < sizeof raw; i++)
        snprintf(w->token + 2 * i, 3, "%02x", raw[i]);
    const char *path = w->o.token_file;
    unlink(path); /* a new file each start: never write through a link or into someone's open descriptor */
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
    if (fd < 0)
        return sci_error_set(err, -errno, "web: token file %s: %s", path, strerror(errno));
    struct group *g = w->o.token_group && w->o.token_group[0] ? getgrnam(w->o.token_group) : NULL;
    if (g && fchown(fd, (uid_t)-1, g->gr_gid) != 0)
        sci_log_write(w->log, SCI_LOG_WARNING, "web: token file %s: chgrp %s: %s", path, w->o.token_group,
                      strerror(errno));
    int rc = 0;
    if (fchmod(fd, 0640) != 0 || write(fd, w->token, WEB_TOKEN_HEX) != WEB_TOKEN_HEX || write(fd, "\n", 1) != 1)
        rc = sci_error_set(err, -errno, "web: token file %s: %s", path, strerror(errno));
    close(fd);
    return rc;
}

/* Constant time in the token's length whatever the candidate: no early exit on the first differing byte. */
static int token_equal(const char *expected, const char *given)
{
    size_t n = strlen(given);
    unsigned char diff = n != WEB_TOKEN_HEX;
    for (size_t i = 0; i < WEB_TOKEN_HEX; i++)
        diff |= (unsigned char)expected[i] ^ (unsigned char)(i < n ? given[i] : 0);
    return diff == 0;
}

/* ---- responses ---- */

static enum MHD_Result respond(struct MHD_Connection *c, unsigned status, const char *type, struct MHD_Response *r)
{
    if (!r)
        return MHD_NO;
    MHD_add_response_header(r, "Content-Security-Policy", WEB_CSP);
    MHD_add_response_header(r, "X-Content-Type-Options", "nosniff");
    MHD_add_response_header(r, "Referrer-Policy", "no-referrer");
    MHD_add_response_header(r, "X-Frame-Options", "DENY");
    if (type)
        MHD_add_response_header(r, "Content-Type", type);
    enum MHD_Result ok = MHD_queue_response(c, status, r);
    MHD_destroy_response(r);
    return ok;
}

static enum MHD_Result respond_copy(struct MHD_Connection *c, unsigned status, const char *type, const char *body,
                                    size_t len)
{
    return respond(c, status, type,
                   MHD_create_response_from_buffer(len, (void *)body, MHD_RESPMEM_MUST_COPY));
}

static enum MHD_Result respond_error(struct MHD_Connection *c, unsigned status, const char *msg)
{
    char body[256];
    int n = snprintf(body, sizeof body, "{\"error\": \"%s\"}\n", msg);
    return respond_copy(c, status, "application/json", body, (size_t)n);
}

static enum MHD_Result respond_json(struct MHD_Connection *c, unsigned status, json_t *o)
{
    char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    if (!s)
        return respond_error(c, 500, "out of memory");
    struct MHD_Response *r = MHD_create_response_from_buffer(strlen(s), s, MHD_RESPMEM_MUST_FREE);
    if (r)
        MHD_add_response_header(r, "Cache-Control", "no-store");
    else
        free(s);
    return respond(c, status, "application/json", r);
}

/* ---- URL checks ---- */

/* The URL as sent (no percent-decoding, see the unescape callback): only [A-Za-z0-9/_.-], no "..", no "//". */
static int url_clean(const char *url)
{
    if (url[0] != '/' || strlen(url) > WEB_URL_MAX || strstr(url, "..") || strstr(url, "//"))
        return 0;
    for (const char *p = url; *p; p++)
        if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') || *p == '/' ||
              *p == '_' || *p == '.' || *p == '-'))
            return 0;
    return 1;
}

/* Keep URLs undecoded: "%2e%2e" and "%2f" stay what they are and url_clean refuses them. */
static size_t unescape_none(void *cls, struct MHD_Connection *c, char *s)
{
    (void)cls, (void)c;
    return strlen(s);
}

/* With a loopback address, a browser must have been pointed at it by address or "localhost": a page from
 * another site whose name was rebound to 127.0.0.1 sends its own name and is refused. */
static int host_allowed(const scicapd_web *w, struct MHD_Connection *c)
{
    if (!w->loopback)
        return 1;
    const char *h = MHD_lookup_connection_value(c, MHD_HEADER_KIND, "Host");
    if (!h)
        return 0;
    char want[3][96];
    snprintf(want[0], sizeof want[0], "127.0.0.1:%d", w->port);
    snprintf(want[1], sizeof want[1], "localhost:%d", w->port);
    snprintf(want[2], sizeof want[2], strchr(w->host, ':') ? "[%s]:%d" : "%s:%d", w->host, w->port);
    for (int i = 0; i < 3; i++)
        if (strcmp(h, want[i]) == 0)
            return 1;
    return 0;
}

/* cNNNNNN: the store's ids (daemon/store.c), 6 to 12 digits. */
static int capture_id_ok(const char *s, size_t n)
{
    if (n < 7 || n > 13 || s[0] != 'c')
        return 0;
    for (size_t i = 1; i < n; i++)
        if (s[i] < '0' || s[i] > '9')
            return 0;
    return 1;
}

/* A reconstruction folder: a method name, optionally ".N" (gap-tv, pnp-ffdnet.2). */
static int recon_folder_ok(const char *s, size_t n)
{
    size_t i = 0;
    while (i < n && ((s[i] >= 'a' && s[i] <= 'z') || (s[i] >= '0' && s[i] <= '9') || s[i] == '-'))
        i++;
    if (i == 0 || i > 32)
        return 0;
    if (i == n)
        return 1;
    if (s[i] != '.' || n - i < 2 || n - i > 5)
        return 0;
    for (i++; i < n; i++)
        if (s[i] < '0' || s[i] > '9')
            return 0;
    return 1;
}

/* preview_NNN.png */
static int preview_ok(const char *s)
{
    return strlen(s) == 15 && strncmp(s, "preview_", 8) == 0 && s[8] >= '0' && s[8] <= '9' && s[9] >= '0' &&
           s[9] <= '9' && s[10] >= '0' && s[10] <= '9' && strcmp(s + 11, ".png") == 0;
}

/* The file a /captures/ URL names (`rest` after "/captures/"), as a path under the store, with its type; 0 when
 * it is not one of the capture files the view shows. */
static int capture_file(const scicapd_web *w, const char *rest, char *path, size_t n, const char **type)
{
    const char *slash = strchr(rest, '/');
    if (!slash || !capture_id_ok(rest, (size_t)(slash - rest)))
        return 0;
    const char *file = slash + 1;
    if (strcmp(file, "preview_meas_000.png") == 0 || strcmp(file, "preview_truth.gif") == 0) {
        *type = strstr(file, ".gif") ? "image/gif" : "image/png";
    } else if (strncmp(file, "recon/", 6) == 0) {
        const char *folder = file + 6, *s2 = strchr(folder, '/');
        if (!s2 || !recon_folder_ok(folder, (size_t)(s2 - folder)))
            return 0;
        const char *name = s2 + 1;
        if (preview_ok(name))
            *type = "image/png";
        else if (strcmp(name, "preview.gif") == 0)
            *type = "image/gif";
        else if (strcmp(name, "trace.csv") == 0)
            *type = "text/csv; charset=utf-8";
        else if (strcmp(name, "result.json") == 0)
            *type = "application/json";
        else
            return 0;
    } else {
        return 0;
    }
    return snprintf(path, n, "%s/captures/%s", w->storage_root, rest) < (int)n;
}

/* ---- routes ---- */

static enum MHD_Result serve_file(scicapd_web *w, struct MHD_Connection *c, const char *rest)
{
    char path[2200];
    const char *type = NULL;
    if (!capture_file(w, rest, path, sizeof path, &type))
        return respond_error(c, 404, "no such capture file");
    /* O_NOFOLLOW: the store makes no links to follow; one planted there must not lead out of it */
    int fd = open(path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
    struct stat st;
    if (fd < 0)
        return respond_error(c, 404, "no such capture file");
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || st.st_size > WEB_FILE_MAX) {
        close(fd);
        return respond_error(c, 404, "no such capture file");
    }
    struct MHD_Response *r = MHD_create_response_from_fd((uint64_t)st.st_size, fd); /* closes fd */
    if (r)
        MHD_add_response_header(r, "Cache-Control", "no-cache");
    else
        close(fd);
    return respond(c, 200, type, r);
}

/* {status, jobs, captures, control}: three control-socket calls, kept WEB_STATE_CACHE_NS. */

/* The control form's methods, from the solver table (a method added there appears in the page with no other edit):
 * name, help line, and whether it needs a camera (a static scene seen by a moving camera). */
static json_t *web_methods_json(void)
{
    size_t n = 0;
    const solver_ops *const *m = solver_list(&n);
    json_t *a = json_array();
    for (size_t i = 0; a && i < n; i++)
        json_array_append_new(a, json_pack("{s:s, s:s, s:b}", "name", m[i]->name, "summary", m[i]->summary,
                                           "needs_camera", (m[i]->caps & SOLVER_NEEDS_CAMERA) != 0));
    return a;
}
static enum MHD_Result serve_state(scicapd_web *w, struct MHD_Connection *c)
{
    int64_t now = sci_clock_mono_ns();
    pthread_mutex_lock(&w->mu);
    if (w->state && now - w->state_ns < WEB_STATE_CACHE_NS) {
        enum MHD_Result ok = respond_copy(c, 200, "application/json", w->state, strlen(w->state));
        pthread_mutex_unlock(&w->mu);
        return ok;
    }
    pthread_mutex_unlock(&w->mu);
    json_t *status = NULL, *jobs = NULL, *caps = NULL;
    char msg[256];
    if (web_bridge_call(w->socket_path, "status", NULL, &status, msg, sizeof msg) < 0 ||
        web_bridge_call(w->socket_path, "jobs", NULL, &jobs, msg, sizeof msg) < 0 ||
        web_bridge_call(w->socket_path, "captures", json_pack("{s:i}", "limit", 24), &caps, msg, sizeof msg) < 0) {
        json_decref(status);
        json_decref(jobs);
        json_decref(caps);
        return respond_json(c, 503, json_pack("{s:s}", "error", msg));
    }
    json_t *o = json_pack("{s:o, s:O, s:o, s:b, s:o}", "status", status, "jobs", json_object_get(jobs, "jobs"),
                          "captures", caps, "control", w->o.control, "methods", web_methods_json());
    json_decref(jobs);
    char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    if (!s)
        return respond_error(c, 500, "out of memory");
    pthread_mutex_lock(&w->mu);
    free(w->state);
    w->state = s;
    w->state_ns = now;
    enum MHD_Result ok = respond_copy(c, 200, "application/json", s, strlen(s));
    pthread_mutex_unlock(&w->mu);
    return ok;
}

static ssize_t events_read(void *cls, uint64_t pos, char *buf, size_t max)
{
    (void)pos;
    ssize_t n = web_stream_read(cls, buf, max);
    return n < 0 ? MHD_CONTENT_READER_END_OF_STREAM : n;
}

static void events_free(void *cls) { web_stream_free(cls); }

static enum MHD_Result serve_events(scicapd_web *w, struct MHD_Connection *c)
{
    /* keep-alive well inside the connection timeout, so an idle stream is never closed for silence */
    int keepalive_ms = w->o.timeout_s * 1000 / 3;
    web_stream *s = web_stream_new(w->events, keepalive_ms < 1000 ? 300 : keepalive_ms);
    if (!s)
        return respond_error(c, 500, "out of memory");
    struct MHD_Response *r = MHD_create_response_from_callback(MHD_SIZE_UNKNOWN, 4096, events_read, s, events_free);
    if (!r) {
        web_stream_free(s);
        return respond_error(c, 500, "out of memory");
    }
    MHD_add_response_header(r, "Cache-Control", "no-store");
    return respond(c, 200, "text/event-stream", r);
}

static void jobs_remember(scicapd_web *w, json_t *result)
{
    json_int_t id = json_integer_value(json_object_get(result, "job"));
    if (id <= 0)
        return;
    pthread_mutex_lock(&w->mu);
    w->jobs[w->njobs++ % WEB_JOBS_KEPT] = (unsigned long long)id;
    pthread_mutex_unlock(&w->mu);
}

static int jobs_started_here(scicapd_web *w, json_int_t id)
{
    int found = 0;
    pthread_mutex_lock(&w->mu);
    int n = w->njobs < WEB_JOBS_KEPT ? w->njobs : WEB_JOBS_KEPT;
    for (int i = 0; i < n; i++)
        found |= w->jobs[i] == (unsigned long long)id;
    pthread_mutex_unlock(&w->mu);
    return found;
}

/* POST /api/capture | reconstruct | cancel: the body is the command's args, checked by the daemon as any
 * client's (protocol check 5). The web runs as the daemon's user, which the control socket takes for an admin:
 * cancel is therefore held to the jobs started through the web, so the token gives no more than a socket user's
 * rights over the jobs of others. */
static enum MHD_Result serve_control(scicapd_web *w, struct MHD_Connection *c, const char *cmd, web_request *q)
{
    json_error_t je;
    json_t *args = q->len ? json_loadb(q->body, q->len, 0, &je) : json_object();
    if (!json_is_object(args)) {
        json_decref(args);
        return respond_error(c, 400, "the body must be a JSON object (the command's args)");
    }
    if (strcmp(cmd, "cancel") == 0 && !jobs_started_here(w, json_integer_value(json_object_get(args, "job")))) {
        json_decref(args);
        return respond_error(c, 403, "the web view cancels only the jobs it started");
    }
    json_t *result = NULL;
    char msg[512];
    int rc = web_bridge_call(w->socket_path, cmd, args, &result, msg, sizeof msg);
    if (rc == WEB_BRIDGE_REFUSED)
        return respond_json(c, 422, json_pack("{s:s}", "error", msg));
    if (rc < 0)
        return respond_json(c, 503, json_pack("{s:s}", "error", msg));
    if (strcmp(cmd, "cancel") != 0)
        jobs_remember(w, result);
    sci_log_write(w->log, SCI_LOG_NOTICE, "web: %s by %s", cmd, "the token's holder");
    return respond_json(c, 200, result);
}

/* Before the body: the route, the switch, the token. NULL when the request may go on, else a response. */
static unsigned control_refusal(scicapd_web *w, struct MHD_Connection *c, const char **why)
{
    if (!w->o.control) {
        *why = "control is off (web.control in the configuration)";
        return 403;
    }
    const char *auth = MHD_lookup_connection_value(c, MHD_HEADER_KIND, "Authorization");
    if (!auth || strncmp(auth, "Bearer ", 7) != 0) {
        *why = "a token is needed (Authorization: Bearer TOKEN; the token file is in web.token_file)";
        return 401;
    }
    if (!token_equal(w->token, auth + 7)) {
        *why = "wrong token";
        return 403;
    }
    return 0;
}

static const char *control_command(const char *url)
{
    static const char *const cmds[] = {"capture", "reconstruct", "cancel"};
    if (strncmp(url, "/api/", 5) != 0)
        return NULL;
    for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++)
        if (strcmp(url + 5, cmds[i]) == 0)
            return cmds[i];
    return NULL;
}

static enum MHD_Result serve_get(scicapd_web *w, struct MHD_Connection *c, const char *url)
{
    for (int i = 0; i < ASSET_COUNT; i++)
        if (strcmp(url, asset_table[i].url) == 0) {
            struct MHD_Response *r =
                MHD_create_response_from_buffer(w->asset_len[i], w->asset[i], MHD_RESPMEM_PERSISTENT);
            return respond(c, 200, asset_table[i].type, r);
        }
    if (strcmp(url, "/favicon.ico") == 0) /* browsers ask for it unprompted: no icon, and no 404 to log */
        return respond(c, 204, NULL, MHD_create_response_from_buffer(0, (void *)"", MHD_RESPMEM_PERSISTENT));
    if (strcmp(url, "/api/state") == 0)
        return serve_state(w, c);
    if (strcmp(url, "/api/events") == 0)
        return serve_events(w, c);
    if (strcmp(url, "/api/curves") == 0 && w->curves)
        return respond(c, 200, "text/csv; charset=utf-8",
                       MHD_create_response_from_buffer(w->curves_len, w->curves, MHD_RESPMEM_PERSISTENT));
    if (strncmp(url, "/captures/", 10) == 0)
        return serve_file(w, c, url + 10);
    return respond_error(c, 404, "no such page");
}

/* The first call for a request: everything that can be refused before a body is read. */
static enum MHD_Result first_call(scicapd_web *w, struct MHD_Connection *c, const char *url, const char *method,
                                  web_request *q)
{
    const char *len = MHD_lookup_connection_value(c, MHD_HEADER_KIND, "Content-Length");
    const char *why = NULL;
    unsigned status = 0;
    q->post = strcmp(method, "POST") == 0;
    if (strlen(url) > WEB_URL_MAX)
        status = 414, why = "URL too long";
    else if (!url_clean(url))
        status = 400, why = "malformed path";
    else if (!host_allowed(w, c))
        status = 421, why = "the Host header does not name this server";
    else if (len && strtoull(len, NULL, 10) > WEB_BODY_MAX)
        status = 413, why = "request body too large";
    else if (q->post && !control_command(url))
        status = 404, why = "no such page";
    else if (q->post)
        status = control_refusal(w, c, &why);
    else if (strcmp(method, "GET") != 0 && strcmp(method, "HEAD") != 0)
        status = 405, why = "method not allowed";
    if (!status)
        return MHD_YES;
    q->refused = 1;
    if (status != 404 && status != 405)
        sci_log_write(w->log, SCI_LOG_INFO, "web: %s %.120s refused (%u: %s)", method, url, status, why);
    return respond_error(c, status, why);
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *c, const char *url, const char *method,
                                  const char *version, const char *upload, size_t *upload_size, void **con_cls)
{
    (void)version;
    scicapd_web *w = cls;
    web_request *q = *con_cls;
    if (!q) {
        if (!(q = calloc(1, sizeof *q)))
            return MHD_NO;
        *con_cls = q;
        enum MHD_Result ok = first_call(w, c, url, method, q);
        if (q->refused || ok != MHD_YES || q->post)
            return ok;
        return serve_get(w, c, url);
    }
    if (q->refused)
        return MHD_YES; /* the refusal is queued; the body, if any, is dropped unread */
    if (*upload_size) {
        /* the library takes a response only once the upload is over: until then the rest is read and dropped
         * (the connection's timeout bounds how long a sender can keep that up) */
        if (q->too_big || q->len + *upload_size > WEB_BODY_MAX) {
            q->too_big = 1;
            *upload_size = 0;
            return MHD_YES;
        }
        char *b = realloc(q->body, q->len + *upload_size);
        if (!b)
            return MHD_NO;
        memcpy(b + q->len, upload, *upload_size);
        q->body = b;
        q->len += *upload_size;
        *upload_size = 0;
        return MHD_YES;
    }
    if (q->too_big)
        return respond_error(c, 413, "request body too large");
    return serve_control(w, c, control_command(url), q);
}

static void on_completed(void *cls, struct MHD_Connection *c, void **con_cls, enum MHD_RequestTerminationCode t)
{
    (void)cls, (void)c, (void)t;
    web_request *q = *con_cls;
    if (q) {
        free(q->body);
        free(q);
        *con_cls = NULL;
    }
}

static void on_mhd_log(void *cls, const char *fmt, va_list ap)
{
    char msg[400];
    vsnprintf(msg, sizeof msg, fmt, ap);
    size_t n = strlen(msg);
    if (n && msg[n - 1] == '\n')
        msg[n - 1] = '\0';
    sci_log_write(((scicapd_web *)cls)->log, SCI_LOG_INFO, "web: %s", msg);
}

/* ---- life ---- */

static int listen_start(scicapd_web *w, sci_error *err)
{
    struct sockaddr_storage ss = {0};
    unsigned flags = MHD_USE_THREAD_PER_CONNECTION | MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_ERROR_LOG;
    if (strchr(w->host, ':')) {
        struct sockaddr_in6 *a = (struct sockaddr_in6 *)&ss;
        a->sin6_family = AF_INET6;
        a->sin6_port = htons((uint16_t)w->o.port);
        if (inet_pton(AF_INET6, w->host, &a->sin6_addr) != 1)
            return sci_error_set(err, -EINVAL, "web.listen: \"%s\" is not an IPv6 address", w->host);
        w->loopback = IN6_IS_ADDR_LOOPBACK(&a->sin6_addr);
        flags |= MHD_USE_IPv6;
    } else {
        struct sockaddr_in *a = (struct sockaddr_in *)&ss;
        a->sin_family = AF_INET;
        a->sin_port = htons((uint16_t)w->o.port);
        if (inet_pton(AF_INET, w->host, &a->sin_addr) != 1)
            return sci_error_set(err, -EINVAL, "web.listen: \"%s\" is not an IPv4 address", w->host);
        w->loopback = (ntohl(a->sin_addr.s_addr) >> 24) == 127;
    }
    w->mhd = MHD_start_daemon(flags, (uint16_t)w->o.port, NULL, NULL, on_request, w,
                              MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&ss,
                              MHD_OPTION_CONNECTION_LIMIT, (unsigned)w->o.max_connections,
                              MHD_OPTION_CONNECTION_TIMEOUT, (unsigned)w->o.timeout_s,
                              /* headers and URL of one request must fit: larger ones are refused by the
                               * library (431/414) before the handler sees them */
                              MHD_OPTION_CONNECTION_MEMORY_LIMIT, (size_t)16384,
                              MHD_OPTION_THREAD_STACK_SIZE, (size_t)(256 << 10),
                              MHD_OPTION_UNESCAPE_CALLBACK, unescape_none, w,
                              MHD_OPTION_NOTIFY_COMPLETED, on_completed, w,
                              MHD_OPTION_EXTERNAL_LOGGER, on_mhd_log, w,
                              MHD_OPTION_END);
    if (!w->mhd)
        return sci_error_set(err, -EADDRINUSE, "web: cannot listen on %s port %d (in use, not an address of this "
                             "machine, or TCP refused by the service's sandbox: docs/web.md, Under systemd)",
                             w->host, w->o.port);
    const union MHD_DaemonInfo *i = MHD_get_daemon_info(w->mhd, MHD_DAEMON_INFO_BIND_PORT);
    w->port = i && i->port ? i->port : w->o.port;
    return 0;
}

int scicapd_web_start(scicapd_web **out, const scicapd_web_options *o, const sci_log *log, sci_error *err)
{
    scicapd_web *w = calloc(1, sizeof *w);
    if (!w)
        return sci_error_set(err, -ENOMEM, "web: out of memory");
    w->o = *o;
    w->log = log;
    snprintf(w->host, sizeof w->host, "%s", o->host);
    snprintf(w->socket_path, sizeof w->socket_path, "%s", o->socket_path);
    snprintf(w->storage_root, sizeof w->storage_root, "%s", o->storage_root);
    pthread_mutex_init(&w->mu, NULL);
    int rc;
    if ((rc = web_events_new(&w->events, WEB_EVENTS_KEPT)) < 0) {
        sci_error_set(err, rc, "web: out of memory");
        goto fail;
    }
    curves_load(w);
    if ((rc = assets_load(w, err)) < 0 || (o->control && (rc = token_write(w, err)) < 0) ||
        (rc = listen_start(w, err)) < 0)
        goto fail;
    sci_log_write(log, SCI_LOG_NOTICE, "web view on http://%s%s%s:%d/ (%s)", strchr(w->host, ':') ? "[" : "",
                  w->host, strchr(w->host, ':') ? "]" : "", w->port,
                  o->control ? "control with the token" : "read-only");
    *out = w;
    return 0;
fail:
    scicapd_web_stop(w);
    return rc;
}

int scicapd_web_port(const scicapd_web *w) { return w->port; }

void scicapd_web_publish(scicapd_web *w, const char *line)
{
    if (w && line)
        web_events_push(w->events, line);
}

void scicapd_web_stop(scicapd_web *w)
{
    if (!w)
        return;
    if (w->events)
        web_events_close(w->events); /* the streams end, so their threads can be joined */
    if (w->mhd)
        MHD_stop_daemon(w->mhd);
    if (w->o.control && w->token[0])
        unlink(w->o.token_file);
    web_events_free(w->events);
    for (int i = 0; i < ASSET_COUNT; i++)
        free(w->asset[i]);
    free(w->state);
    free(w->curves);
    pthread_mutex_destroy(&w->mu);
    free(w);
}
