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

/* "<dir>/.<stem>.tmp-XXXXXX<ext>" for `path` (malloc'd; *dir malloc'd too, "." when path has no slash). The
 * extension stays last because writers that open by name (OpenImageIO) pick the format by it; *suffix_len is
 * its length, for mkostemps. */
static char *file_tmp_template(const char *path, char **dir, int *suffix_len)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    size_t dn = !slash ? 1 : slash == path ? 1 : (size_t)(slash - path); /* "/x" lives in "/" */
    *dir = malloc(dn + 1);
    char *tmp = malloc(dn + strlen(base) + 16);
    if (!*dir || !tmp) {
        free(*dir);
        free(tmp);
        *dir = NULL;
        return NULL;
    }
    memcpy(*dir, slash ? path : ".", dn);
    (*dir)[dn] = 0;
    const char *dot = strrchr(base, '.');
    if (!dot || dot == base)
        dot = base + strlen(base);
    *suffix_len = (int)strlen(dot);
    sprintf(tmp, "%s/.%.*s.tmp-XXXXXX%s", *dir, (int)(dot - base), base, dot);
    return tmp;
}

/* fsync a file or folder by name. Returns 0 or -errno. */
static int file_sync_name(const char *name, int dir)
{
    int fd = open(name, O_RDONLY | O_CLOEXEC | (dir ? O_DIRECTORY : 0));
    if (fd < 0)
        return -errno;
    int rc = fsync(fd) == 0 ? 0 : -errno;
    close(fd);
    return rc;
}

/* A writer's failure as the caller's error: its own message when it set one. */
static int file_writer_failed(int rc, const sci_error *werr, const char *path, sci_error *err)
{
    if (werr->msg[0])
        return sci_error_set(err, rc, "%s", werr->msg);
    return sci_error_set(err, rc, "%s: %s", path, sci_strerror(rc));
}

/* How the temporary file gets its content: through a FILE on its descriptor, or by its name. */
typedef struct file_source {
    sci_file_writer stream;
    sci_file_name_writer named;
    void *user;
} file_source;

/* Fill the temporary file (fd, named tmp) from src, then flush and fsync it; fd is closed on return. Returns 0
 * or a negative code with err set. */
static int file_fill(int fd, const char *tmp, const char *path, unsigned flags, const file_source *src,
                     sci_error *err)
{
    sci_error werr = {0};
    int rc;
    if (src->named) {
        close(fd);
        if ((rc = src->named(tmp, src->user, &werr)) < 0)
            return file_writer_failed(rc, &werr, path, err);
        if (!(flags & SCI_FILE_NO_SYNC) && (rc = file_sync_name(tmp, 0)) < 0)
            return sci_error_set(err, rc, "%s: fsync failed: %s", path, strerror(-rc));
        return 0;
    }
    FILE *f = fdopen(fd, "wb");
    if (!f) {
        rc = -errno;
        close(fd);
        return sci_error_set(err, rc, "%s: %s", tmp, strerror(-rc));
    }
    if ((rc = src->stream(f, src->user, &werr)) < 0) {
        fclose(f);
        return file_writer_failed(rc, &werr, path, err);
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

/* The process's umask without changing it (umask(2) can only set it, which races with other threads): the
 * "Umask:" line of /proc/self/status (Linux 4.7 and later); 022 when it cannot be read. */
static mode_t file_umask(void)
{
    FILE *f = fopen("/proc/self/status", "re");
    unsigned mask = 022;
    char line[128];
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "Umask: %o", &mask) == 1)
            break;
    if (f)
        fclose(f);
    return (mode_t)mask;
}

static int file_replace(const char *path, mode_t mode, unsigned flags, const file_source *src, sci_error *err)
{
    char *dir;
    int suffix_len;
    char *tmp = file_tmp_template(path, &dir, &suffix_len);
    if (!tmp)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
    int rc = 0;
    int fd = mkostemps(tmp, suffix_len, O_CLOEXEC);
    if (fd < 0) {
        rc = sci_error_set(err, -errno, "%s: cannot create a temporary file: %s", path, strerror(errno));
        goto out_free;
    }
    /* mkstemp creates 0600; the file gets what open(path, O_CREAT, mode) would have given it */
    if (fchmod(fd, mode & ~file_umask()) != 0) {
        rc = sci_error_set(err, -errno, "%s: %s", tmp, strerror(errno));
        close(fd);
        goto out_unlink;
    }
    if ((rc = file_fill(fd, tmp, path, flags, src, err)) < 0)
        goto out_unlink;
    if (rename(tmp, path) != 0) {
        rc = sci_error_set(err, -errno, "%s: cannot replace: %s", path, strerror(errno));
        goto out_unlink;
    }
    if (!(flags & SCI_FILE_NO_SYNC) && (rc = file_sync_name(dir, 1)) < 0)
        sci_error_set(err, rc, "%s: fsync of the folder failed: %s", dir, strerror(-rc));
    goto out_free;
out_unlink:
    unlink(tmp);
out_free:
    free(tmp);
    free(dir);
    return rc;
}

int sci_file_write_atomic_with(const char *path, mode_t mode, unsigned flags, sci_file_writer write, void *user,
                               sci_error *err)
{
    const file_source src = {.stream = write, .user = user};
    return file_replace(path, mode, flags, &src, err);
}

int sci_file_write_atomic_named(const char *path, mode_t mode, unsigned flags, sci_file_name_writer write,
                                void *user, sci_error *err)
{
    const file_source src = {.named = write, .user = user};
    return file_replace(path, mode, flags, &src, err);
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
