/* io/sandbox.c — a parser in a child process (see the header). */
#include "io/sandbox.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static long long now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (long long)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

/* Append what fd has to *buf until EOF or the deadline. 0 at EOF, -ETIMEDOUT, -ENOMEM or -errno. */
static int read_all(int fd, long long deadline, char **buf, size_t *len)
{
    size_t cap = 0;
    for (;;) {
        int left = (int)(deadline - now_ms());
        if (left <= 0)
            return -ETIMEDOUT;
        struct pollfd p = {.fd = fd, .events = POLLIN};
        int r = poll(&p, 1, left);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return -errno;
        if (r == 0)
            return -ETIMEDOUT;
        if (*len == cap) {
            size_t nc = cap ? cap * 2 : 65536;
            char *nb = realloc(*buf, nc);
            if (!nb)
                return -ENOMEM;
            *buf = nb;
            cap = nc;
        }
        ssize_t n = read(fd, *buf + *len, cap - *len);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0)
            return -errno;
        if (n == 0)
            return 0;
        *len += (size_t)n;
    }
}

static void child(sci_sandbox_fn fn, void *arg, int fd)
{
    /* a crash must end the child: handlers inherited from the parent (a test runner's, which would go on
     * running the parent's code here) are reset */
    static const int fatal[] = {SIGPIPE, SIGSEGV, SIGBUS, SIGABRT, SIGILL, SIGFPE};
    for (size_t i = 0; i < sizeof fatal / sizeof fatal[0]; i++)
        signal(fatal[i], SIG_DFL);
    int rc = fn(arg, fd);
    close(fd);
    _exit(rc < 0 ? 1 : 0); /* no atexit handlers or stdio flushes of the parent's state */
}

int sci_sandbox_run(sci_sandbox_fn fn, void *arg, int timeout_ms, void **bytes, size_t *len, const char *what,
                    sci_error *err)
{
    *bytes = NULL;
    *len = 0;
    int p[2];
    if (pipe2(p, O_CLOEXEC) != 0)
        return sci_error_set(err, -errno, "%s: pipe: %s", what, strerror(errno));
    pid_t pid = fork();
    if (pid < 0) {
        int e = errno;
        close(p[0]);
        close(p[1]);
        return sci_error_set(err, -e, "%s: fork: %s", what, strerror(e));
    }
    if (pid == 0) {
        close(p[0]);
        child(fn, arg, p[1]);
    }
    close(p[1]);
    char *buf = NULL;
    int rc = read_all(p[0], now_ms() + timeout_ms, &buf, len);
    close(p[0]);
    if (rc < 0)
        kill(pid, SIGKILL); /* hung (or we cannot take more): it must not outlive the read */
    int st = 0;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR)
        ;
    if (rc == -ETIMEDOUT)
        rc = sci_error_set(err, rc, "%s: reading it took longer than %d ms; given up", what, timeout_ms);
    else if (rc < 0)
        rc = sci_error_set(err, rc, "%s: %s", what, strerror(-rc));
    else if (WIFSIGNALED(st))
        rc = sci_error_set(err, SCI_EFORMAT, "%s: damaged: the HDF5 library crashed reading it (%s)", what,
                           strsignal(WTERMSIG(st)));
    else if (!WIFEXITED(st) || WEXITSTATUS(st) != 0)
        rc = sci_error_set(err, SCI_EFORMAT, "%s: its reader failed (exit status %d)", what, WEXITSTATUS(st));
    if (rc < 0) {
        free(buf);
        *len = 0;
        return rc;
    }
    *bytes = buf;
    return 0;
}
