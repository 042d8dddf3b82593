/* base/file.c — see file.h. */
#include "base/file.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
