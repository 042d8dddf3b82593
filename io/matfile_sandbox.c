/* io/matfile_sandbox.c — v7.3 files read in a child (see the header). The bytes are this machine's own layout:
 * writer and reader are the same program, one fork apart. */
#include "io/matfile_sandbox.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "io/sandbox.h"

int sci_mat_is_v73(const char *path, const char *mask_path)
{
    const char *paths[2] = {path, mask_path};
    for (int i = 0; i < 2; i++) {
        unsigned char hdr[128];
        FILE *f = paths[i] ? fopen(paths[i], "rb") : NULL;
        if (!f)
            continue;
        size_t got = fread(hdr, 1, sizeof hdr, f);
        fclose(f);
        /* the version field, written in the file's byte order ("IM" or "MI" at 126) */
        if (got == sizeof hdr && ((hdr[124] == 0x00 && hdr[125] == 0x02) || (hdr[124] == 0x02 && hdr[125] == 0x00)))
            return 1;
    }
    return 0;
}

static int put(int fd, const void *p, size_t n)
{
    const char *c = p;
    while (n > 0) {
        ssize_t w = write(fd, c, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -EIO;
        c += w;
        n -= (size_t)w;
    }
    return 0;
}

/* A cursor over the child's bytes: a short buffer is a child that died mid-write. */
typedef struct cursor {
    const char *p;
    size_t left;
} cursor;

static int take(cursor *c, void *out, size_t n)
{
    if (c->left < n)
        return -1;
    memcpy(out, c->p, n);
    c->p += n;
    c->left -= n;
    return 0;
}

/* ---- read ---- */

typedef struct read_args {
    sci_mat_read_fn read;
    const char *path;
    const sci_mat_options *o;
    double legacy;
} read_args;

static int put_cube(int fd, const sci_cube *c)
{
    int32_t d[4] = {c != NULL, c ? c->w : 0, c ? c->h : 0, c ? c->n : 0};
    int rc = put(fd, d, sizeof d);
    return rc < 0 || !c ? rc : put(fd, c->data, sci_cube_count(c) * sizeof(float));
}

static int read_child(void *arg, int fd)
{
    read_args *a = arg;
    sci_problem **pp = NULL;
    int k = 0;
    sci_mat_info info = {0};
    sci_error err = {0};
    int32_t rc = a->read(a->path, a->o, a->legacy, &pp, &k, &info, &err);
    int32_t kk = rc < 0 ? 0 : k;
    int w = put(fd, &rc, sizeof rc) | put(fd, &err, sizeof err) | put(fd, &info, sizeof info) |
            put(fd, &kk, sizeof kk);
    for (int i = 0; w == 0 && i < kk; i++) {
        w = put(fd, pp[i]->name, sizeof pp[i]->name) | put(fd, &pp[i]->peak, sizeof pp[i]->peak);
        w |= put_cube(fd, pp[i]->meas) | put_cube(fd, pp[i]->mask) | put_cube(fd, pp[i]->truth);
    }
    return w;
}

static int take_cube(cursor *c, sci_cube **out, sci_error *err)
{
    int32_t d[4];
    *out = NULL;
    if (take(c, d, sizeof d) < 0)
        return -1;
    if (!d[0])
        return 0;
    if (sci_cube_new(out, d[1], d[2], d[3], err) < 0)
        return -1;
    return take(c, (*out)->data, sci_cube_count(*out) * sizeof(float));
}

static int decode_read(cursor *c, sci_problem ***out, int *k, sci_mat_info *info, sci_error *err)
{
    int32_t rc, kk;
    sci_error child_err;
    sci_mat_info ci;
    if (take(c, &rc, sizeof rc) < 0 || take(c, &child_err, sizeof child_err) < 0 || take(c, &ci, sizeof ci) < 0 ||
        take(c, &kk, sizeof kk) < 0 || kk < 0)
        return -1;
    if (rc < 0) {
        *err = child_err;
        return rc;
    }
    sci_problem **pp = calloc(kk > 0 ? (size_t)kk : 1, sizeof *pp);
    if (!pp)
        return sci_error_set(err, -ENOMEM, "out of memory");
    for (int i = 0; i < kk; i++) {
        sci_problem *p = pp[i] = calloc(1, sizeof *p);
        if (!p || take(c, p->name, sizeof p->name) < 0 || take(c, &p->peak, sizeof p->peak) < 0 ||
            take_cube(c, &p->meas, err) < 0 || take_cube(c, &p->mask, err) < 0 || take_cube(c, &p->truth, err) < 0) {
            sci_problem_array_free(pp, i + 1);
            return -1;
        }
    }
    if (info)
        *info = ci;
    *out = pp;
    *k = kk;
    return rc;
}

int sci_mat_read_sandboxed(sci_mat_read_fn read, const char *path, const sci_mat_options *o, double legacy,
                           sci_problem ***out, int *k, sci_mat_info *info, sci_error *err)
{
    *out = NULL;
    *k = 0;
    read_args a = {.read = read, .path = path, .o = o, .legacy = legacy};
    void *bytes;
    size_t len;
    int rc = sci_sandbox_run(read_child, &a, SCI_MAT_SANDBOX_TIMEOUT_MS, &bytes, &len, path, err);
    if (rc < 0)
        return rc;
    cursor c = {bytes, len};
    rc = decode_read(&c, out, k, info, err);
    free(bytes);
    if (rc == -1)
        rc = sci_error_set(err, SCI_EFORMAT, "%s: its reader stopped mid-answer (%zu bytes)", path, len);
    return rc;
}

/* ---- probe ---- */

typedef struct probe_args {
    sci_mat_probe_fn probe;
    const char *path;
    const sci_mat_options *o;
} probe_args;

static int probe_child(void *arg, int fd)
{
    probe_args *a = arg;
    long long d[4] = {0};
    sci_error err = {0};
    int32_t rc = a->probe(a->path, a->o, &d[0], &d[1], &d[2], &d[3], &err);
    return put(fd, &rc, sizeof rc) | put(fd, &err, sizeof err) | put(fd, d, sizeof d);
}

int sci_mat_probe_sandboxed(sci_mat_probe_fn probe, const char *path, const sci_mat_options *o, long long *w,
                            long long *h, long long *n, long long *k, sci_error *err)
{
    probe_args a = {.probe = probe, .path = path, .o = o};
    void *bytes;
    size_t len;
    int rc = sci_sandbox_run(probe_child, &a, SCI_MAT_SANDBOX_TIMEOUT_MS, &bytes, &len, path, err);
    if (rc < 0)
        return rc;
    cursor c = {bytes, len};
    int32_t crc;
    sci_error ce;
    long long d[4];
    if (take(&c, &crc, sizeof crc) < 0 || take(&c, &ce, sizeof ce) < 0 || take(&c, d, sizeof d) < 0) {
        free(bytes);
        return sci_error_set(err, SCI_EFORMAT, "%s: its reader stopped mid-answer (%zu bytes)", path, len);
    }
    free(bytes);
    *w = d[0];
    *h = d[1];
    *n = d[2];
    *k = d[3];
    if (crc < 0)
        *err = ce;
    return crc;
}
