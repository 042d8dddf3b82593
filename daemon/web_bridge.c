/* daemon/web_bridge.c — one request over the control socket (see web_bridge.h). */
#include "daemon/web_bridge.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "base/clock.h"

#define BRIDGE_LINE_MAX (1 << 20) /* a reply of `captures` with 24 entries is a few KB; jobs up to ~100 KB */

static int bridge_connect(const char *path, char *msg, size_t n)
{
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0 || connect(fd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        int e = errno;
        snprintf(msg, n, "control socket %s: %s", path, strerror(e));
        if (fd >= 0)
            close(fd);
        return -e;
    }
    return fd;
}

static int bridge_send(int fd, const char *cmd, json_t *args, char *msg, size_t n)
{
    json_t *req = json_pack("{s:i, s:s, s:s, s:o*}", "v", 1, "id", "web", "cmd", cmd, "args", args);
    char *line = req ? json_dumps(req, JSON_COMPACT) : NULL;
    json_decref(req);
    if (!line) {
        snprintf(msg, n, "out of memory");
        return -ENOMEM;
    }
    size_t len = strlen(line);
    line[len] = '\0';
    int rc = 0;
    if (send(fd, line, len, MSG_NOSIGNAL) != (ssize_t)len || send(fd, "\n", 1, MSG_NOSIGNAL) != 1) {
        rc = -errno;
        snprintf(msg, n, "control socket: send: %s", strerror(errno));
    }
    free(line);
    return rc;
}

/* The next complete line into *out (malloc'd), or -errno / -ETIMEDOUT by deadline_ns. */
static int bridge_read_line(int fd, char **buf, size_t *len, size_t *cap, int64_t deadline_ns, char **out)
{
    for (;;) {
        char *nl = *len ? memchr(*buf, '\n', *len) : NULL;
        if (nl) {
            size_t k = (size_t)(nl - *buf);
            *out = strndup(*buf, k);
            memmove(*buf, nl + 1, *len - k - 1);
            *len -= k + 1;
            return *out ? 0 : -ENOMEM;
        }
        if (*len == *cap) {
            if (*cap >= BRIDGE_LINE_MAX)
                return -EMSGSIZE;
            char *b = realloc(*buf, *cap = *cap ? *cap * 2 : 8192);
            if (!b)
                return -ENOMEM;
            *buf = b;
        }
        int64_t left_ms = (deadline_ns - sci_clock_mono_ns()) / 1000000;
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (left_ms <= 0 || poll(&p, 1, (int)left_ms) == 0)
            return -ETIMEDOUT;
        ssize_t r = recv(fd, *buf + *len, *cap - *len, 0);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            return r == 0 ? -ECONNRESET : -errno;
        *len += (size_t)r;
    }
}

/* The reply to our request: the first line with "ok" (events carry "event" and are skipped). */
static int bridge_reply(int fd, json_t **result, char *msg, size_t n)
{
    int64_t deadline = sci_clock_mono_ns() + (int64_t)WEB_BRIDGE_TIMEOUT_MS * 1000000;
    char *buf = NULL, *line = NULL;
    size_t len = 0, cap = 0;
    int rc;
    while ((rc = bridge_read_line(fd, &buf, &len, &cap, deadline, &line)) == 0) {
        json_t *o = json_loads(line, 0, NULL);
        free(line);
        json_t *ok = json_object_get(o, "ok");
        if (!ok) {
            json_decref(o);
            continue;
        }
        if (json_is_true(ok)) {
            *result = json_incref(json_object_get(o, "result"));
            if (!*result)
                *result = json_object();
        } else {
            json_t *e = json_object_get(o, "error");
            snprintf(msg, n, "%s: %s", json_string_value(json_object_get(e, "code")) ?: "error",
                     json_string_value(json_object_get(e, "message")) ?: "refused");
            rc = WEB_BRIDGE_REFUSED;
        }
        json_decref(o);
        break;
    }
    if (rc < 0)
        snprintf(msg, n, "control socket: no reply: %s", strerror(-rc));
    free(buf);
    return rc;
}

int web_bridge_call(const char *socket_path, const char *cmd, json_t *args, json_t **result, char *msg,
                    size_t msg_n)
{
    *result = NULL;
    int fd = bridge_connect(socket_path, msg, msg_n);
    if (fd < 0) {
        json_decref(args);
        return fd;
    }
    int rc = bridge_send(fd, cmd, args, msg, msg_n);
    if (rc == 0)
        rc = bridge_reply(fd, result, msg, msg_n);
    close(fd);
    return rc;
}
