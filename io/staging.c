#include "io/staging.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <libgen.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static int rm_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw) { return remove(path); }

int sci_staging_remove(const char *dir)
{
    struct stat st;
    if (lstat(dir, &st) != 0)
        return errno == ENOENT ? 0 : -errno;
    return nftw(dir, rm_entry, 16, FTW_DEPTH | FTW_PHYS) == 0 ? 0 : -errno;
}

/* fsync every regular file and folder under the open folder fd, then fd itself; the first -errno, or 0. The
 * output folders are shallow; deeper than 16 levels is not followed (and not reported). */
static int sync_folder(int fd, int depth)
{
    int rc = 0, dup_fd = dup(fd);
    DIR *d = dup_fd >= 0 ? fdopendir(dup_fd) : NULL;
    if (!d) {
        rc = -errno;
        if (dup_fd >= 0)
            close(dup_fd);
    }
    for (struct dirent *e; d && (e = readdir(d)) != NULL;) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
            continue;
        /* an entry gone since readdir (another writer's staging folder renamed or removed meanwhile) is not
         * ours to sync: its own writer does */
        struct stat st;
        if (fstatat(fd, e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0) {
            rc = rc || errno == ENOENT ? rc : -errno;
            continue;
        }
        if (!S_ISREG(st.st_mode) && !(S_ISDIR(st.st_mode) && depth < 16))
            continue;
        int cfd = openat(fd, e->d_name, O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
        int crc = cfd < 0 ? (errno == ENOENT ? 0 : -errno)
                  : S_ISDIR(st.st_mode) ? sync_folder(cfd, depth + 1)
                  : fsync(cfd) == 0     ? 0
                                        : -errno;
        if (cfd >= 0)
            close(cfd);
        rc = rc ? rc : crc;
    }
    if (d)
        closedir(d);
    if (fsync(fd) != 0 && rc == 0)
        rc = -errno;
    return rc;
}

int sci_staging_sync(const char *path, int how)
{
    char parent[4096];
    if ((size_t)snprintf(parent, sizeof parent, "%s", path) >= sizeof parent)
        return -ENAMETOOLONG;
    /* O_NONBLOCK: a FIFO named here must not block the open; it is refused below */
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
    if (fd < 0)
        return -errno;
    struct stat st;
    int rc = fstat(fd, &st) != 0                        ? -errno
             : S_ISDIR(st.st_mode) && (how & SCI_SYNC_TREE) ? sync_folder(fd, 0)
             : !S_ISDIR(st.st_mode) && !S_ISREG(st.st_mode) ? -EINVAL
             : fsync(fd) == 0                               ? 0
                                                            : -errno;
    close(fd);
    if (!(how & SCI_SYNC_PARENT))
        return rc;
    int pfd = open(dirname(parent), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    int prc = pfd < 0 ? -errno : fsync(pfd) == 0 ? 0 : -errno;
    if (pfd >= 0)
        close(pfd);
    return rc < 0 ? rc : prc;
}

int sci_staging_name(char *buf, size_t n, const char *dir)
{
    if ((size_t)snprintf(buf, n, "%s.tmp-%d", dir, (int)getpid()) >= n)
        return -ENAMETOOLONG;
    sci_staging_remove(buf);
    return 0;
}

int sci_staging_publish(const char *tmp, const char *dir, int flags, const volatile sig_atomic_t *stop,
                        sci_error *err)
{
    /* before the signals are blocked: syncing a large tree may take a while, and a stop during it is honoured */
    int src = flags & SCI_STAGING_DURABLE ? sci_staging_sync(tmp, SCI_SYNC_TREE) : 0;
    if (src < 0) {
        sci_staging_remove(tmp);
        return sci_error_set(err, src, "%s: cannot make it durable: %s", dir, strerror(-src));
    }
    sigset_t block, old;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    sigaddset(&block, SIGHUP);  /* a closed terminal and Ctrl-\ stop the CLI as Ctrl-C does (cli/recon.c, */
    sigaddset(&block, SIGQUIT); /* cli/batch.c): they must not fall between the check and the rename either */
    pthread_sigmask(SIG_BLOCK, &block, &old);
    int rc = 0;
    struct stat st;
    char aside[4200];
    aside[0] = 0;
    if (stop && *stop) {
        rc = sci_error_set(err, SCI_ECANCELED, "%s: interrupted; not written", dir);
    } else if (lstat(dir, &st) == 0) {
        if (!(flags & SCI_STAGING_OVERWRITE))
            rc = sci_error_set(err, -EEXIST, "%s: already exists (use --force to replace it)", dir);
        else if ((size_t)snprintf(aside, sizeof aside, "%s.old-%d", dir, (int)getpid()) >= sizeof aside)
            rc = sci_error_set(err, -ENAMETOOLONG, "%s: name too long", dir);
        else if (sci_staging_remove(aside), rename(dir, aside) != 0)
            rc = sci_error_set(err, -errno, "%s: cannot replace: %s", dir, strerror(errno));
    }
    if (rc == 0 && rename(tmp, dir) != 0) {
        rc = sci_error_set(err, -errno, "%s: %s", dir, strerror(errno));
        if (aside[0])
            rename(aside, dir); /* put the old output back: a failed replace must not lose it */
        aside[0] = 0;
    }
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (rc < 0)
        sci_staging_remove(tmp);
    else if (aside[0])
        sci_staging_remove(aside);
    /* the rename reaches the disk with the folder holding `dir` */
    if (rc == 0 && (flags & SCI_STAGING_DURABLE) && (src = sci_staging_sync(dir, SCI_SYNC_PARENT)) < 0)
        rc = sci_error_set(err, src, "%s: published, but its name cannot be made durable: %s", dir, strerror(-src));
    return rc;
}
