/* base/file.c — see file.h. */
#include "base/file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int sci_file_read(const char *path, size_t max_bytes, void **out, size_t *len, sci_error *err)
{
    *out = NULL;
    *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    char *buf = NULL;
    size_t n = 0, cap = 0;
    for (;;) {
        if (n + 65536 + 1 > cap) {
            cap = cap ? cap * 2 : 65536 + 1;
            if (cap > max_bytes + 65536 + 1)
                cap = max_bytes + 65536 + 1;
            char *t = realloc(buf, cap);
            if (!t) {
                free(buf);
                fclose(f);
                return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
            }
            buf = t;
        }
        errno = 0;
        size_t got = fread(buf + n, 1, cap - 1 - n, f);
        n += got;
        if (n > max_bytes) {
            free(buf);
            fclose(f);
            return sci_error_set(err, -EFBIG, "%s: larger than %zu bytes", path, max_bytes);
        }
        if (got == 0)
            break;
    }
    int bad = ferror(f);
    int e = errno;
    fclose(f);
    if (bad) {
        free(buf);
        return sci_error_set(err, e ? -e : -EIO, "%s: read error (%s)", path, strerror(e ? e : EIO));
    }
    buf[n] = 0;
    *out = buf;
    *len = n;
    return 0;
}

/* ---- atomic replace ---- */

/* Split `path` into a malloc'd folder ("." when there is none) and a pointer to its last component. */
static char *file_dir_of(const char *path, const char **base)
{
    const char *slash = strrchr(path, '/');
    *base = slash ? slash + 1 : path;
    if (!slash)
        return strdup(".");
    size_t n = slash == path ? 1 : (size_t)(slash - path); /* "/x" lives in "/" */
    char *dir = malloc(n + 1);
    if (dir) {
        memcpy(dir, path, n);
        dir[n] = 0;
    }
    return dir;
}

/* fsync a folder so a rename inside it survives power loss. Returns 0 or -errno. */
static int file_sync_dir(const char *dir)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return -errno;
    int rc = fsync(fd) == 0 ? 0 : -errno;
    close(fd);
    return rc;
}

/* Run the writer on the open temporary file, then flush, fsync and close it (always closed on return).
 * Returns 0 or a negative code with err set. */
static int file_fill(FILE *f, const char *path, unsigned flags, sci_file_writer write, void *user, sci_error *err)
{
    sci_error werr = {0};
    int rc = write(f, user, &werr);
    if (rc < 0) {
        fclose(f);
        if (werr.msg[0])
            return sci_error_set(err, rc, "%s", werr.msg);
        return sci_error_set(err, rc, "%s: %s", path, sci_strerror(rc));
    }
    errno = 0;
    int bad = ferror(f) || fflush(f) != 0;
    if (!bad && !(flags & SCI_FILE_NO_SYNC))
        bad = fsync(fileno(f)) != 0;
    int e = errno;
    if (fclose(f) != 0 && !bad) {
        bad = 1;
        e = errno;
    }
    if (bad) {
        e = e ? e : EIO;
        return sci_error_set(err, -e, "%s: cannot write: %s", path, strerror(e));
    }
    return 0;
}

int sci_file_write_atomic_with(const char *path, mode_t mode, unsigned flags, sci_file_writer write, void *user,
                               sci_error *err)
{
    const char *base;
    char *dir = file_dir_of(path, &base);
    char *tmp = dir ? malloc(strlen(dir) + strlen(base) + 10) : NULL;
    if (!tmp) {
        free(dir);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
    }
    sprintf(tmp, "%s/.%s.XXXXXX", dir, base);
    int rc = 0;
    int fd = mkostemp(tmp, O_CLOEXEC);
    if (fd < 0) {
        rc = sci_error_set(err, -errno, "%s: cannot create a temporary file: %s", path, strerror(errno));
        goto out_free;
    }
    FILE *f = fchmod(fd, mode) == 0 ? fdopen(fd, "wb") : NULL;
    if (!f) {
        rc = sci_error_set(err, -errno, "%s: %s", tmp, strerror(errno));
        close(fd);
        goto out_unlink;
    }
    if ((rc = file_fill(f, path, flags, write, user, err)) < 0)
        goto out_unlink;
    if (rename(tmp, path) != 0) {
        rc = sci_error_set(err, -errno, "%s: cannot replace: %s", path, strerror(errno));
        goto out_unlink;
    }
    if (!(flags & SCI_FILE_NO_SYNC) && (rc = file_sync_dir(dir)) < 0)
        sci_error_set(err, rc, "%s: fsync of the folder failed: %s", dir, strerror(-rc));
    goto out_free;
out_unlink:
    unlink(tmp);
out_free:
    free(tmp);
    free(dir);
    return rc;
}

typedef struct file_bytes {
    const void *data;
    size_t len;
} file_bytes;

static int file_write_bytes(FILE *f, void *user, sci_error *err)
{
    (void)err;
    const file_bytes *b = user;
    if (b->len && fwrite(b->data, 1, b->len, f) != b->len)
        return errno ? -errno : -EIO;
    return 0;
}

int sci_file_write_atomic(const char *path, const void *data, size_t len, mode_t mode, unsigned flags,
                          sci_error *err)
{
    file_bytes b = {data, len};
    return sci_file_write_atomic_with(path, mode, flags, file_write_bytes, &b, err);
}
