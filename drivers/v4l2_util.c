#include "drivers/v4l2_util.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

static int sys_open(void *ctx, const char *path, int flags) { return open(path, flags); }
static int sys_close(void *ctx, int fd) { return close(fd); }
static int sys_ioctl(void *ctx, int fd, unsigned long req, void *arg) { return ioctl(fd, req, arg); }
static void *sys_mmap(void *ctx, size_t len, int prot, int flags, int fd, off_t off)
{
    return mmap(NULL, len, prot, flags, fd, off);
}
static int sys_munmap(void *ctx, void *p, size_t len) { return munmap(p, len); }
static int sys_poll(void *ctx, struct pollfd *fds, nfds_t n, int timeout_ms) { return poll(fds, n, timeout_ms); }

const v4l2_util_sys v4l2_util_sys_real = {
    .open = sys_open,
    .close = sys_close,
    .ioctl = sys_ioctl,
    .mmap = sys_mmap,
    .munmap = sys_munmap,
    .poll = sys_poll,
    .ctx = NULL,
};

int v4l2_util_ioctl(v4l2_util_dev *dev, unsigned long req, const char *name, void *arg)
{
    int r;
    do
        r = dev->sys->ioctl(dev->sys->ctx, dev->fd, req, arg);
    while (r < 0 && errno == EINTR);
    if (r < 0) {
        dev->last_ioctl = name;
        dev->last_errno = errno;
        return -errno;
    }
    return 0;
}

/* Preference: more significant bits first, unpacked before packed (unpacking Y10P costs CPU). */
static const enum pixfmt preference[] = {PIXFMT_Y16, PIXFMT_Y12, PIXFMT_Y10, PIXFMT_Y10P, PIXFMT_GREY};

static void list_offered(const v4l2_util_fmtdesc *offered, int n, char *buf, size_t len)
{
    size_t used = 0;
    buf[0] = '\0';
    for (int i = 0; i < n && used < len; i++) {
        char s[5];
        enum pixfmt_kind k = pixfmt_classify_fourcc(offered[i].fourcc, offered[i].flags & 1u);
        const char *why = k == PIXFMT_KIND_MONO ? "" : k == PIXFMT_KIND_COLOUR ? " (colour)"
                          : k == PIXFMT_KIND_COMPRESSED ? " (compressed)" : k == PIXFMT_KIND_MONO_OTHER ? " (mono, no unpacker)"
                          : " (unknown)";
        int w = snprintf(buf + used, len - used, "%s%s%s", i ? ", " : "", pixfmt_fourcc_str(offered[i].fourcc, s), why);
        if (w < 0)
            break;
        used += (size_t)w;
    }
    if (n == 0)
        snprintf(buf, len, "nothing");
}

int v4l2_util_choose_format(const v4l2_util_fmtdesc *offered, int n, enum pixfmt want, const char *device,
                            enum pixfmt *out, sci_error *err)
{
    char list[256];
    if (want != PIXFMT_NONE) {
        const pixfmt_info *in = pixfmt_info_get(want);
        if (!in)
            return sci_error_set(err, -EINVAL, "%s: requested pixel format %d is not valid", device, (int)want);
        for (int i = 0; i < n; i++)
            if (offered[i].fourcc == in->fourcc) {
                *out = want;
                return 0;
            }
        list_offered(offered, n, list, sizeof list);
        return sci_error_set(err, -ENOTSUP, "%s: does not offer format %s; it offers %s", device, in->name, list);
    }
    for (size_t p = 0; p < sizeof preference / sizeof preference[0]; p++)
        for (int i = 0; i < n; i++)
            if (offered[i].fourcc == pixfmt_info_get(preference[p])->fourcc && !(offered[i].flags & 1u)) {
                *out = preference[p];
                return 0;
            }
    list_offered(offered, n, list, sizeof list);
    return sci_error_set(err, -ENOTSUP, "%s: offers no raw monochrome format (it offers %s); measurements need one of "
                         "GREY, Y10, Y12, Y16, Y10P", device, list);
}

static int size_fits(const v4l2_util_framesize *s, uint32_t w, uint32_t h)
{
    if (w < s->min_w || w > s->max_w || h < s->min_h || h > s->max_h)
        return 0;
    if (s->step_w && (w - s->min_w) % s->step_w)
        return 0;
    if (s->step_h && (h - s->min_h) % s->step_h)
        return 0;
    return 1;
}

int v4l2_util_choose_size(const v4l2_util_framesize *sizes, int n, uint32_t w, uint32_t h, const char *device,
                          uint32_t *out_w, uint32_t *out_h, sci_error *err)
{
    if (w == 0 && h == 0) {
        uint64_t best = 0;
        for (int i = 0; i < n; i++)
            if ((uint64_t)sizes[i].max_w * sizes[i].max_h > best) {
                best = (uint64_t)sizes[i].max_w * sizes[i].max_h;
                *out_w = sizes[i].max_w;
                *out_h = sizes[i].max_h;
            }
        if (best == 0)
            return sci_error_set(err, -ENOTSUP, "%s: no frame size given and the device lists none", device);
        return 0;
    }
    if (w == 0 || h == 0)
        return sci_error_set(err, -EINVAL, "%s: frame size %ux%u: give both width and height", device, w, h);
    if (n == 0) {
        *out_w = w;
        *out_h = h;
        return 0;
    }
    for (int i = 0; i < n; i++)
        if (size_fits(&sizes[i], w, h)) {
            *out_w = w;
            *out_h = h;
            return 0;
        }
    char list[256];
    size_t used = 0;
    list[0] = '\0';
    for (int i = 0; i < n && used < sizeof list; i++) {
        int k = (sizes[i].min_w == sizes[i].max_w && sizes[i].min_h == sizes[i].max_h)
                    ? snprintf(list + used, sizeof list - used, "%s%ux%u", i ? ", " : "", sizes[i].max_w, sizes[i].max_h)
                    : snprintf(list + used, sizeof list - used, "%s%ux%u..%ux%u step %u,%u", i ? ", " : "",
                               sizes[i].min_w, sizes[i].min_h, sizes[i].max_w, sizes[i].max_h, sizes[i].step_w,
                               sizes[i].step_h);
        if (k < 0)
            break;
        used += (size_t)k;
    }
    return sci_error_set(err, -ENOTSUP, "%s: frame size %ux%u is not offered; sizes: %s", device, w, h, list);
}

int v4l2_util_ctrl_name_eq(const char *a, const char *b)
{
    for (;; a++, b++) {
        int ca = (*a == ' ' || *a == '-') ? '_' : tolower((unsigned char)*a);
        int cb = (*b == ' ' || *b == '-') ? '_' : tolower((unsigned char)*b);
        if (ca != cb)
            return 0;
        if (ca == '\0')
            return 1;
    }
}
