/* daemon/control.c — Unix socket, connections, line framing and output buffers. */
#include "daemon/control.h"

#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <malloc.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "base/clock.h"
#include "daemon/protocol.h"

#define OUT_MAX ((size_t)16 << 20)
/* An output buffer larger than this is freed once drained, not kept for the connection's life: a watcher that
 * once fell behind by megabytes would otherwise hold them until it disconnects. */
#define OUT_KEEP ((size_t)64 << 10)
/* Closed connections' buffers past this total are handed back to the kernel (malloc_trim): glibc keeps freed
 * heap, and after one 16 MiB buffer is freed its dynamic mmap threshold puts the next ones on the heap too, so
 * 29 backed-up connections left ~400 MiB resident after they closed. */
#define TRIM_AFTER ((size_t)1 << 20)

struct scicapd_control {
    int lfd;
    char path[108];
    scicapd_control_limits lim;
    const sci_log *log;
    scicapd_control_hooks hooks;
    scicapd_client **c;
    int n, cap;
    uint64_t next_id;
};

static void limits_set(scicapd_control *ctl, const scicapd_control_limits *lim)
{
    ctl->lim = *lim;
    if (ctl->lim.max_clients < 1)
        ctl->lim.max_clients = 1;
    if (ctl->lim.admin_slots > ctl->lim.max_clients - 1)
        ctl->lim.admin_slots = ctl->lim.max_clients - 1;
    if (ctl->lim.admin_slots < 0)
        ctl->lim.admin_slots = 0;
}

static const char *file_kind(mode_t m)
{
    return S_ISREG(m) ? "a regular file" : S_ISDIR(m) ? "a folder" : S_ISLNK(m) ? "a symbolic link"
         : S_ISCHR(m) || S_ISBLK(m) ? "a device node" : S_ISFIFO(m) ? "a FIFO" : "something other than a socket";
}

/* What stands at path before bind: nothing (0), a stale socket (removed, 0), a live socket (-EADDRINUSE), or
 * anything else (-EEXIST, left alone: --socket pointed at the wrong file must not destroy it). */
static int clear_path(const char *path, const struct sockaddr_un *sa, sci_error *err)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return errno == ENOENT ? 0 : sci_error_set(err, -errno, "control socket %s: %s", path, strerror(errno));
    if (!S_ISSOCK(st.st_mode))
        return sci_error_set(err, -EEXIST, "control socket %s: %s stands there; refusing to replace it (remove it "
                             "or choose another --socket / control.socket)", path, file_kind(st.st_mode));
    int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (probe < 0)
        return sci_error_set(err, -errno, "control socket: socket(): %s", strerror(errno));
    int rc = connect(probe, (const struct sockaddr *)sa, sizeof *sa) == 0 ? 0 : -errno;
    close(probe);
    if (rc == 0)
        return sci_error_set(err, -EADDRINUSE, "control socket %s: another scicapd is listening on it", path);
    if (rc != -ECONNREFUSED) /* e.g. EACCES: not ours to judge stale */
        return sci_error_set(err, rc, "control socket %s: cannot tell whether it is stale: %s", path, strerror(-rc));
    if (unlink(path) != 0 && errno != ENOENT)
        return sci_error_set(err, -errno, "control socket %s: cannot remove the stale socket: %s", path,
                             strerror(errno));
    return 0;
}

int scicapd_control_open(scicapd_control **out, const char *path, unsigned mode, const char *group,
                         const scicapd_control_limits *lim, const scicapd_control_hooks *hooks, const sci_log *log,
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
    limits_set(ctl, lim);
    ctl->log = log;
    ctl->hooks = *hooks;
    ctl->next_id = 1;
    int rc, bound = 0;
    struct stat st;
    if ((rc = clear_path(path, &sa, err)) < 0)
        goto fail;
    ctl->lfd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (ctl->lfd < 0) {
        rc = sci_error_set(err, -errno, "control socket: socket(): %s", strerror(errno));
        goto fail;
    }
    if (bind(ctl->lfd, (struct sockaddr *)&sa, sizeof sa) != 0) {
        rc = sci_error_set(err, -errno, "control socket %s: bind: %s", path, strerror(errno));
        goto fail;
    }
    bound = 1; /* from here the file is ours to remove on failure */
    if (chmod(path, mode) != 0) {
        rc = sci_error_set(err, -errno, "control socket %s: chmod %04o: %s", path, mode, strerror(errno));
        goto fail;
    }
    if (group && group[0]) {
        struct group *g = getgrnam(group);
        if (!g)
            sci_log_write(log, SCI_LOG_WARNING, "control socket %s: group \"%s\" does not exist; keeping the "
                          "process's group", path, group);
        else if (stat(path, &st) == 0 && st.st_gid == g->gr_gid)
            ; /* already right (the unit's Group=): no chown, which its SystemCallFilter refuses */
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
    if (ctl->lfd >= 0)
        close(ctl->lfd);
    if (bound)
        unlink(path);
    free(ctl);
    return rc;
}

static void close_passed(scicapd_client *c)
{
    for (int i = 0; i < c->nfds; i++)
        close(c->fds[i]);
    c->nfds = 0;
}

int scicapd_client_take_fds(scicapd_client *c, int *out, int max)
{
    int n = c->nfds < max ? c->nfds : max;
    memcpy(out, c->fds, (size_t)n * sizeof *out);
    memmove(c->fds, c->fds + n, (size_t)(c->nfds - n) * sizeof *c->fds);
    c->nfds -= n;
    return n;
}

/* recv with the descriptors a peer passed kept in c->fds (beyond the table's room: closed). */
static ssize_t recv_with_fds(scicapd_client *c, void *buf, size_t len)
{
    union {
        char b[CMSG_SPACE(sizeof(int) * SCICAPD_CLIENT_MAX_FDS)];
        struct cmsghdr align;
    } ctl;
    struct iovec iov = {.iov_base = buf, .iov_len = len};
    struct msghdr m = {.msg_iov = &iov, .msg_iovlen = 1, .msg_control = ctl.b, .msg_controllen = sizeof ctl.b};
    ssize_t r = recvmsg(c->fd, &m, MSG_DONTWAIT | MSG_CMSG_CLOEXEC);
    if (r < 0)
        return r;
    for (struct cmsghdr *h = CMSG_FIRSTHDR(&m); h; h = CMSG_NXTHDR(&m, h)) {
        if (h->cmsg_level != SOL_SOCKET || h->cmsg_type != SCM_RIGHTS)
            continue;
        int n = (int)((h->cmsg_len - CMSG_LEN(0)) / sizeof(int));
        const unsigned char *p = CMSG_DATA(h);
        for (int i = 0; i < n; i++) {
            int fd;
            memcpy(&fd, p + (size_t)i * sizeof fd, sizeof fd);
            if (c->nfds < SCICAPD_CLIENT_MAX_FDS)
                c->fds[c->nfds++] = fd;
            else
                close(fd);
        }
    }
    return r;
}

static void client_free(scicapd_client *c)
{
    close_passed(c);
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

void scicapd_control_set_limits(scicapd_control *ctl, const scicapd_control_limits *lim)
{
    limits_set(ctl, lim);
    size_t max_line = ctl->lim.max_line;
    for (int i = 0; i < ctl->n; i++) {
        char *in = realloc(ctl->c[i]->in, max_line + 1);
        if (in)
            ctl->c[i]->in = in;
        if (ctl->c[i]->in_len > max_line)
            ctl->c[i]->in_len = 0;
    }
}

int scicapd_control_clients(const scicapd_control *ctl) { return ctl->n; }

int scicapd_control_watchers(const scicapd_control *ctl)
{
    int n = 0;
    for (int i = 0; i < ctl->n; i++)
        n += ctl->c[i]->watching != 0;
    return n;
}

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
        c->out_stall_ns = sci_clock_mono_ns(); /* the peer reads: its stall count starts again */
    }
    c->out_len = c->out_off = 0;
    if (c->out_cap > OUT_KEEP) {
        free(c->out);
        c->out = NULL;
        c->out_cap = 0;
    }
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
    if (c->out_len == c->out_off)
        c->out_stall_ns = sci_clock_mono_ns(); /* output starts to wait now */
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

void scicapd_control_broadcast(scicapd_control *ctl, const char *line, uint64_t except, long owner)
{
    for (int i = 0; i < ctl->n; i++) {
        scicapd_client *c = ctl->c[i];
        if (c->watching && c->id != except && (owner < 0 || c->admin || (long)c->uid == owner))
            scicapd_control_send_to(ctl, c, line);
    }
}

int scicapd_control_flushing(const scicapd_control *ctl)
{
    for (int i = 0; i < ctl->n; i++)
        if (ctl->c[i]->out_len > ctl->c[i]->out_off && ctl->c[i]->closing != 2)
            return 1;
    return 0;
}

/* One "busy" line, then closed: the client prints why (cli/client.c). */
static void refuse(scicapd_control *ctl, int fd, const struct ucred *cr, const char *msg)
{
    char *line = scicapd_reply_error(NULL, SCICAPD_E_BUSY, msg);
    if (line) {
        ssize_t w = send(fd, line, strlen(line), MSG_NOSIGNAL | MSG_DONTWAIT);
        (void)w;
    }
    free(line);
    close(fd);
    sci_log_write(ctl->log, SCI_LOG_WARNING, "refused a connection from pid %d uid %d: %s", (int)cr->pid,
                  (int)cr->uid, msg);
}

static void accept_one(scicapd_control *ctl)
{
    int fd = accept4(ctl->lfd, NULL, NULL, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0)
        return;
    struct ucred cr = {0};
    socklen_t len = sizeof cr;
    if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cr, &len) != 0) {
        /* without credentials the peer would pass for uid 0: refuse it */
        sci_log_write(ctl->log, SCI_LOG_ERR, "refused a connection: SO_PEERCRED: %s", strerror(errno));
        close(fd);
        return;
    }
    int admin = ctl->hooks.is_admin ? ctl->hooks.is_admin(ctl->hooks.user, cr.uid, cr.gid) : 0;
    int limit = admin ? ctl->lim.max_clients : ctl->lim.max_clients - ctl->lim.admin_slots;
    int mine = 0;
    for (int i = 0; i < ctl->n; i++)
        mine += ctl->c[i]->uid == cr.uid && ctl->c[i]->closing != 2;
    if (!admin && ctl->lim.max_per_uid > 0 && mine >= ctl->lim.max_per_uid) {
        char msg[160];
        snprintf(msg, sizeof msg, "too many connections of uid %d (%d; control.max_per_uid)", (int)cr.uid, mine);
        refuse(ctl, fd, &cr, msg);
        return;
    }
    if (ctl->n >= limit) {
        char msg[160];
        if (admin || ctl->lim.admin_slots == 0)
            snprintf(msg, sizeof msg, "too many clients (%d)", ctl->n);
        else
            snprintf(msg, sizeof msg, "too many clients (%d; the other %d slots are kept for admins)", ctl->n,
                     ctl->lim.admin_slots);
        refuse(ctl, fd, &cr, msg);
        return;
    }
    scicapd_client *c = calloc(1, sizeof *c);
    if (c)
        c->in = malloc(ctl->lim.max_line + 1);
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
    c->admin = admin;
    c->line_start_ns = c->last_request_ns = sci_clock_mono_ns(); /* the first request is due like any line */
    ctl->c[ctl->n++] = c;
    sci_log_write(ctl->log, SCI_LOG_INFO, "client %llu connected: pid %d uid %d gid %d", (unsigned long long)c->id,
                  (int)c->pid, (int)c->uid, (int)c->gid);
}

/* Split the input into lines; returns -1 when the connection must close. */
static int read_client(scicapd_control *ctl, scicapd_client *c)
{
    for (;;) {
        if (c->in_len == ctl->lim.max_line + 1 || (c->in_len > ctl->lim.max_line)) {
            /* check 1: a line longer than the limit */
            char msg[96];
            snprintf(msg, sizeof msg, "request line longer than %zu bytes", ctl->lim.max_line);
            char *line = scicapd_reply_error(NULL, SCICAPD_E_TOO_LONG, msg);
            scicapd_control_send_to(ctl, c, line);
            free(line);
            c->in_len = 0;
            c->skipping = 1;
        }
        ssize_t r = recv_with_fds(c, c->in + c->in_len, ctl->lim.max_line + 1 - c->in_len);
        if (r < 0)
            return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? 0 : -1;
        if (r == 0)
            return -1;
        int64_t now = sci_clock_mono_ns();
        if (!c->line_start_ns)
            c->line_start_ns = now; /* the first byte of a line starts its deadline; later bytes do not move it */
        size_t start = 0, end = c->in_len + (size_t)r;
        for (size_t i = c->in_len; i < end; i++) {
            if (c->in[i] != '\n')
                continue;
            size_t len = i - start;
            if (len > 0 && c->in[start + len - 1] == '\r')
                len--;
            if (c->skipping)
                c->skipping = 0;
            else if (len > 0) {
                c->last_request_ns = now;
                ctl->hooks.on_line(ctl->hooks.user, c, c->in + start, len);
            }
            close_passed(c); /* what the request did not take */
            start = i + 1;
            /* bytes after this newline, if any, begin the next line now */
            c->line_start_ns = end > start ? now : 0;
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

/* Free the connections marked closing whose output is written (or that are broken). */
static void reap(scicapd_control *ctl)
{
    int w = 0;
    size_t freed = 0;
    for (int i = 0; i < ctl->n; i++) {
        scicapd_client *c = ctl->c[i];
        if (c->closing == 2 || (c->closing && c->out_len <= c->out_off)) {
            sci_log_write(ctl->log, SCI_LOG_INFO, "client %llu (pid %d) disconnected", (unsigned long long)c->id,
                          (int)c->pid);
            freed += c->out_cap + ctl->lim.max_line;
            client_free(c);
            continue;
        }
        ctl->c[w++] = c;
    }
    ctl->n = w;
    if (freed >= TRIM_AFTER)
        malloc_trim(0);
}

/* The CLOCK_MONOTONIC time at which c is due to be closed, or 0 when no deadline runs. idle_ok: count the idle
 * deadline (the caller decides whether watching or jobs in flight exempt it). */
static int64_t deadline_of(const scicapd_control *ctl, const scicapd_client *c, int idle_ok)
{
    if (c->closing)
        return 0;
    if (c->out_len > c->out_off && ctl->lim.stall_timeout_ms > 0)
        return c->out_stall_ns + (int64_t)ctl->lim.stall_timeout_ms * 1000000;
    if (c->line_start_ns)
        return c->line_start_ns + (int64_t)ctl->lim.request_timeout_ms * 1000000;
    if (idle_ok && ctl->lim.idle_timeout_ms > 0)
        return c->last_request_ns + (int64_t)ctl->lim.idle_timeout_ms * 1000000;
    return 0;
}

static int idle_applies(const scicapd_control *ctl, const scicapd_client *c)
{
    return !c->watching && !(ctl->hooks.busy && ctl->hooks.busy(ctl->hooks.user, c));
}

void scicapd_control_expire(scicapd_control *ctl, int64_t now_ns)
{
    int closed = 0;
    for (int i = 0; i < ctl->n; i++) {
        scicapd_client *c = ctl->c[i];
        int64_t due = deadline_of(ctl, c, 1);
        if (!due || now_ns < due)
            continue;
        int stalled = c->out_len > c->out_off && ctl->lim.stall_timeout_ms > 0;
        if (stalled) { /* it does not read: no last line would reach it */
            sci_log_write(ctl->log, SCI_LOG_NOTICE, "client %llu (pid %d uid %d): %zu bytes unread for %d ms; "
                          "closing", (unsigned long long)c->id, (int)c->pid, (int)c->uid, c->out_len - c->out_off,
                          ctl->lim.stall_timeout_ms);
            c->closing = 2;
            closed++;
            continue;
        }
        if (!c->line_start_ns && !idle_applies(ctl, c)) {
            c->last_request_ns = now_ns; /* waiting for its job: kept, and the idle count starts again */
            continue;
        }
        char msg[128];
        if (c->line_start_ns)
            snprintf(msg, sizeof msg, "request not complete within %d ms; closing", ctl->lim.request_timeout_ms);
        else
            snprintf(msg, sizeof msg, "idle for %d ms with nothing in flight; closing", ctl->lim.idle_timeout_ms);
        sci_log_write(ctl->log, SCI_LOG_NOTICE, "client %llu (pid %d uid %d): %s", (unsigned long long)c->id,
                      (int)c->pid, (int)c->uid, msg);
        char *line = scicapd_reply_error(NULL, SCICAPD_E_TIMEOUT, msg);
        scicapd_control_send_to(ctl, c, line); /* into the kernel's buffer if there is room; never waited for */
        free(line);
        c->closing = 2;
        closed++;
    }
    if (closed)
        reap(ctl);
}

int scicapd_control_next_deadline_ms(const scicapd_control *ctl, int64_t now_ns)
{
    int64_t best = 0;
    for (int i = 0; i < ctl->n; i++) {
        /* without asking busy(): expire restarts the idle count of a connection it keeps */
        int64_t due = deadline_of(ctl, ctl->c[i], !ctl->c[i]->watching);
        if (due && (!best || due < best))
            best = due;
    }
    if (!best)
        return -1;
    return best <= now_ns ? 0 : (int)((best - now_ns + 999999) / 1000000);
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
    reap(ctl);
    if (n > 0 && ctl->lfd >= 0 && fds[0].fd == ctl->lfd && (fds[0].revents & POLLIN))
        for (int i = 0; i < 16; i++) {
            int before = ctl->n;
            accept_one(ctl);
            if (ctl->n == before)
                break;
        }
}
