/* daemon/control.c — Unix socket, connections, line framing and output buffers. */
#include "daemon/control.h"

#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "daemon/protocol.h"

#define OUT_MAX ((size_t)16 << 20)

struct scicapd_control {
    int lfd;
    char path[108];
    int max_clients;
    size_t max_line;
    const sci_log *log;
    scicapd_line_fn on_line;
    void *user;
    scicapd_client **c;
    int n, cap;
    uint64_t next_id;
};

int scicapd_control_open(scicapd_control **out, const char *path, unsigned mode, const char *group,
                         int max_clients, size_t max_line, const sci_log *log, scicapd_line_fn on_line, void *user,
                         sci_error *err)
{
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    if (strlen(path) >= sizeof sa.sun_path)
        return sci_error_set(err, -ENAMETOOLONG, "control socket %s: path longer than %zu bytes", path,
                             sizeof sa.sun_path - 1);
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path);
    scicapd_control *ctl = calloc(1, sizeof *ctl);
    if (!ctl)
        return sci_error_set(err, -ENOMEM, "control: out of memory");
    ctl->lfd = -1;
    snprintf(ctl->path, sizeof ctl->path, "%s", path);
    ctl->max_clients = max_clients;
    ctl->max_line = max_line;
    ctl->log = log;
    ctl->on_line = on_line;
    ctl->user = user;
    ctl->next_id = 1;
    int rc;
    /* A socket file left by a crash: remove it if nobody answers on it. */
    int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (probe >= 0) {
        if (connect(probe, (struct sockaddr *)&sa, sizeof sa) == 0) {
            close(probe);
            free(ctl);
            return sci_error_set(err, -EADDRINUSE, "control socket %s: another scicapd is listening on it", path);
        }
        close(probe);
        if (errno == ECONNREFUSED)
            unlink(path);
    }
    ctl->lfd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (ctl->lfd < 0) {
        rc = sci_error_set(err, -errno, "control socket: socket(): %s", strerror(errno));
        goto fail;
    }
    if (bind(ctl->lfd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        rc = sci_error_set(err, -errno, "control socket %s: bind: %s", path, strerror(errno));
        goto fail;
    }
    if (chmod(path, mode) != 0) {
        rc = sci_error_set(err, -errno, "control socket %s: chmod %04o: %s", path, mode, strerror(errno));
        goto fail;
    }
    if (group && group[0]) {
        struct group *g = getgrnam(group);
        if (!g)
            sci_log_write(log, SCI_LOG_WARNING, "control socket %s: group \"%s\" does not exist; keeping the "
                          "process's group", path, group);
        else if (chown(path, (uid_t)-1, g->gr_gid) != 0)
            sci_log_write(log, SCI_LOG_WARNING, "control socket %s: chgrp %s: %s", path, group, strerror(errno));
    }
    if (listen(ctl->lfd, 64) != 0) {
        rc = sci_error_set(err, -errno, "control socket %s: listen: %s", path, strerror(errno));
        goto fail;
    }
    *out = ctl;
    return 0;
fail:
    if (ctl->lfd >= 0) {
        close(ctl->lfd);
        unlink(path);
    }
    free(ctl);
    return rc;
}

static void client_free(scicapd_client *c)
{
    close(c->fd);
    free(c->in);
    free(c->out);
    free(c);
}

void scicapd_control_stop_listening(scicapd_control *ctl)
{
    if (ctl && ctl->lfd >= 0) {
        close(ctl->lfd);
        ctl->lfd = -1;
        unlink(ctl->path);
    }
}

void scicapd_control_close(scicapd_control *ctl)
{
    if (!ctl)
        return;
    scicapd_control_stop_listening(ctl);
    for (int i = 0; i < ctl->n; i++)
        client_free(ctl->c[i]);
    free(ctl->c);
    free(ctl);
}

void scicapd_control_set_limits(scicapd_control *ctl, int max_clients, size_t max_line)
{
    ctl->max_clients = max_clients;
    ctl->max_line = max_line;
    for (int i = 0; i < ctl->n; i++) {
        char *in = realloc(ctl->c[i]->in, max_line + 1);
        if (in)
            ctl->c[i]->in = in;
        if (ctl->c[i]->in_len > max_line)
            ctl->c[i]->in_len = 0;
    }
}

int scicapd_control_clients(const scicapd_control *ctl) { return ctl->n; }

static void flush(scicapd_control *ctl, scicapd_client *c)
{
    while (c->out_off < c->out_len) {
        ssize_t w = send(c->fd, c->out + c->out_off, c->out_len - c->out_off, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK) {
                c->closing = 2; /* broken: drop now */
                c->out_len = c->out_off = 0;
            }
            return;
        }
        c->out_off += (size_t)w;
    }
    c->out_len = c->out_off = 0;
}

void scicapd_control_send_to(scicapd_control *ctl, scicapd_client *c, const char *line)
{
    if (!line || c->closing == 2)
        return;
    size_t n = strlen(line);
    if (c->out_off > 0 && c->out_off == c->out_len)
        c->out_len = c->out_off = 0;
    if (c->out_len + n > OUT_MAX) {
        sci_log_write(ctl->log, SCI_LOG_WARNING, "client %llu (pid %d): more than %zu bytes unread; disconnecting",
                      (unsigned long long)c->id, (int)c->pid, OUT_MAX);
        c->closing = 2;
        return;
    }
    if (c->out_len + n > c->out_cap) {
        size_t nc = c->out_cap ? c->out_cap : 4096;
        while (nc < c->out_len + n)
            nc *= 2;
        char *o = realloc(c->out, nc);
        if (!o) {
            c->closing = 2;
            return;
        }
        c->out = o;
        c->out_cap = nc;
    }
    memcpy(c->out + c->out_len, line, n);
    c->out_len += n;
    flush(ctl, c);
}

static scicapd_client *find(scicapd_control *ctl, uint64_t id)
{
    for (int i = 0; i < ctl->n; i++)
        if (ctl->c[i]->id == id)
            return ctl->c[i];
    return NULL;
}

void scicapd_control_send(scicapd_control *ctl, uint64_t client, const char *line)
{
    scicapd_client *c = client ? find(ctl, client) : NULL;
    if (c)
        scicapd_control_send_to(ctl, c, line);
}

void scicapd_control_broadcast(scicapd_control *ctl, const char *line, uint64_t except)
{
    for (int i = 0; i < ctl->n; i++)
        if (ctl->c[i]->watching && ctl->c[i]->id != except)
            scicapd_control_send_to(ctl, ctl->c[i], line);
}

int scicapd_control_flushing(const scicapd_control *ctl)
{
    for (int i = 0; i < ctl->n; i++)
        if (ctl->c[i]->out_len > ctl->c[i]->out_off && ctl->c[i]->closing != 2)
            return 1;
    return 0;
}

static void accept_one(scicapd_control *ctl)
{
    int fd = accept4(ctl->lfd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0)
        return;
    struct ucred cr = {0};
    socklen_t len = sizeof cr;
    getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cr, &len);
    if (ctl->n >= ctl->max_clients) {
        char *line = scicapd_reply_error(NULL, SCICAPD_E_BUSY, "too many clients");
        if (line) {
            ssize_t w = send(fd, line, strlen(line), MSG_NOSIGNAL | MSG_DONTWAIT);
            (void)w;
        }
        free(line);
        close(fd);
        sci_log_write(ctl->log, SCI_LOG_WARNING, "refused a connection from pid %d uid %d: %d clients already",
                      (int)cr.pid, (int)cr.uid, ctl->n);
        return;
    }
    scicapd_client *c = calloc(1, sizeof *c);
    if (c)
        c->in = malloc(ctl->max_line + 1);
    if (ctl->n == ctl->cap) {
        int nc = ctl->cap ? ctl->cap * 2 : 16;
        scicapd_client **v = realloc(ctl->c, (size_t)nc * sizeof *v);
        if (v) {
            ctl->c = v;
            ctl->cap = nc;
        }
    }
    if (!c || !c->in || ctl->n == ctl->cap) {
        if (c)
            free(c->in);
        free(c);
        close(fd);
        return;
    }
    c->fd = fd;
    c->id = ctl->next_id++;
    c->pid = cr.pid;
    c->uid = cr.uid;
    c->gid = cr.gid;
    ctl->c[ctl->n++] = c;
    sci_log_write(ctl->log, SCI_LOG_INFO, "client %llu connected: pid %d uid %d gid %d", (unsigned long long)c->id,
                  (int)c->pid, (int)c->uid, (int)c->gid);
}

/* Split the input into lines; returns -1 when the connection must close. */
static int read_client(scicapd_control *ctl, scicapd_client *c)
{
    for (;;) {
        if (c->in_len == ctl->max_line + 1 || (c->in_len > ctl->max_line)) {
            /* check 1: a line longer than the limit */
            char msg[96];
            snprintf(msg, sizeof msg, "request line longer than %zu bytes", ctl->max_line);
            char *line = scicapd_reply_error(NULL, SCICAPD_E_TOO_LONG, msg);
            scicapd_control_send_to(ctl, c, line);
            free(line);
            c->in_len = 0;
            c->skipping = 1;
        }
        ssize_t r = recv(c->fd, c->in + c->in_len, ctl->max_line + 1 - c->in_len, MSG_DONTWAIT);
        if (r < 0)
            return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : -1;
        if (r == 0)
            return -1;
        size_t start = 0, end = c->in_len + (size_t)r;
        for (size_t i = c->in_len; i < end; i++) {
            if (c->in[i] != '\n')
                continue;
            size_t len = i - start;
            if (len > 0 && c->in[start + len - 1] == '\r')
                len--;
            if (c->skipping)
                c->skipping = 0;
            else if (len > 0)
                ctl->on_line(ctl->user, c, c->in + start, len);
            start = i + 1;
            if (c->closing)
                return 0;
        }
        if (c->skipping) {
            c->in_len = 0; /* still inside the oversized line */
        } else {
            memmove(c->in, c->in + start, end - start);
            c->in_len = end - start;
        }
    }
}

int scicapd_control_pollfds(scicapd_control *ctl, struct pollfd *fds, int max)
{
    int k = 0;
    if (k < max)
        fds[k++] = (struct pollfd){.fd = ctl->lfd, .events = ctl->lfd >= 0 ? POLLIN : 0};
    for (int i = 0; i < ctl->n && k < max; i++) {
        scicapd_client *c = ctl->c[i];
        short ev = c->closing ? 0 : POLLIN;
        if (c->out_len > c->out_off)
            ev |= POLLOUT;
        fds[k++] = (struct pollfd){.fd = c->fd, .events = ev};
    }
    return k;
}

void scicapd_control_dispatch(scicapd_control *ctl, const struct pollfd *fds, int n)
{
    /* connections first (fds[1..n-1] map to ctl->c[0..] as of pollfds), accept last */
    for (int k = 1; k < n; k++) {
        scicapd_client *c = NULL;
        for (int i = 0; i < ctl->n; i++)
            if (ctl->c[i]->fd == fds[k].fd)
                c = ctl->c[i];
        if (!c)
            continue;
        if (fds[k].revents & POLLOUT)
            flush(ctl, c);
        if ((fds[k].revents & (POLLIN | POLLHUP | POLLERR)) && !c->closing && read_client(ctl, c) < 0)
            c->closing = 2;
    }
    int w = 0;
    for (int i = 0; i < ctl->n; i++) {
        scicapd_client *c = ctl->c[i];
        if (c->closing == 2 || (c->closing && c->out_len <= c->out_off)) {
            sci_log_write(ctl->log, SCI_LOG_INFO, "client %llu (pid %d) disconnected", (unsigned long long)c->id,
                          (int)c->pid);
            client_free(c);
            continue;
        }
        ctl->c[w++] = c;
    }
    ctl->n = w;
    if (n > 0 && ctl->lfd >= 0 && fds[0].fd == ctl->lfd && (fds[0].revents & POLLIN))
        for (int i = 0; i < 16; i++) {
            int before = ctl->n;
            accept_one(ctl);
            if (ctl->n == before)
                break;
        }
}
