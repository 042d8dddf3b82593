#include "io/staging.h"

#include <errno.h>
#include <ftw.h>
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

int sci_staging_name(char *buf, size_t n, const char *dir)
{
    if ((size_t)snprintf(buf, n, "%s.tmp-%d", dir, (int)getpid()) >= n)
        return -ENAMETOOLONG;
    sci_staging_remove(buf);
    return 0;
}

int sci_staging_publish(const char *tmp, const char *dir, int overwrite, const volatile sig_atomic_t *stop,
                        sci_error *err)
{
    sigset_t block, old;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &block, &old);
    int rc = 0;
    struct stat st;
    char aside[4200];
    aside[0] = 0;
    if (stop && *stop) {
        rc = sci_error_set(err, SCI_ECANCELED, "%s: interrupted; not written", dir);
    } else if (lstat(dir, &st) == 0) {
        if (!overwrite)
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
    return rc;
}
