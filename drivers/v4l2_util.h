/* drivers/v4l2_util.h — raw V4L2 plumbing: the one ioctl wrapper, the system-call seam, and the format and size
 * choice as pure functions (so they are tested without a device).
 *
 * The wrapper: every ioctl goes through v4l2_util_ioctl (or the V4L2_IOCTL macro, which passes the request's
 * name), which retries EINTR, records the name of the last failing ioctl and returns 0 or -errno (v4l-utils
 * style). Arguments are always built as designated-initializer compound literals, so every field the caller
 * does not set (reserved fields included) is zero.
 *
 * The seam: v4l2_util_sys holds open/close/ioctl/mmap/munmap/poll. The V4L2 backend calls the system only
 * through it; v4l2_util_sys_real is the kernel, and a test may pass its own table to fake a device in-process.
 *
 * Thread-safety: a v4l2_util_dev belongs to one thread; the pure functions are thread-safe.
 */
#ifndef SCICAP_DRIVERS_V4L2_UTIL_H
#define SCICAP_DRIVERS_V4L2_UTIL_H

#include <poll.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "base/error.h"
#include "drivers/pixfmt.h"

typedef struct v4l2_util_sys {
    int (*open)(void *ctx, const char *path, int flags);
    int (*close)(void *ctx, int fd);
    int (*ioctl)(void *ctx, int fd, unsigned long req, void *arg);
    void *(*mmap)(void *ctx, size_t len, int prot, int flags, int fd, off_t off);
    int (*munmap)(void *ctx, void *p, size_t len);
    int (*poll)(void *ctx, struct pollfd *fds, nfds_t n, int timeout_ms);
    void *ctx;
} v4l2_util_sys;

/* The real system calls (ctx unused). */
extern const v4l2_util_sys v4l2_util_sys_real;

typedef struct v4l2_util_dev {
    const v4l2_util_sys *sys; /* borrowed */
    int fd;
    const char *last_ioctl;   /* name of the last ioctl that failed, "" if none */
    int last_errno;
} v4l2_util_dev;

/* ioctl with EINTR retry: 0 or -errno; on failure records `name` and errno in dev. */
int v4l2_util_ioctl(v4l2_util_dev *dev, unsigned long req, const char *name, void *arg);
#define V4L2_IOCTL(dev, req, arg) v4l2_util_ioctl((dev), (req), #req, (arg))

/* One entry of VIDIOC_ENUM_FMT, as the choice functions need it. */
typedef struct v4l2_util_fmtdesc {
    uint32_t fourcc;
    uint32_t flags; /* V4L2_FMT_FLAG_* (COMPRESSED matters) */
} v4l2_util_fmtdesc;

/* Pick the wire format. `want` given: it must be offered (-ENOTSUP naming it and listing what the device offers
 * with the reason each is refused). `want` PIXFMT_NONE: the best measurable offer, preferring more bits and
 * unpacked containers: Y16, Y12, Y10, Y10P, GREY. -ENOTSUP when nothing offered is measurable. */
int v4l2_util_choose_format(const v4l2_util_fmtdesc *offered, int n, enum pixfmt want, const char *device,
                            enum pixfmt *out, sci_error *err);

/* One entry of VIDIOC_ENUM_FRAMESIZES: discrete (step_w = step_h = 0, min = max) or stepwise/continuous. */
typedef struct v4l2_util_framesize {
    uint32_t min_w, max_w, step_w;
    uint32_t min_h, max_h, step_h;
} v4l2_util_framesize;

/* Pick the size. w = h = 0: the largest offered. Otherwise the exact size must be offered (-ENOTSUP naming the
 * request and listing the offered sizes). n = 0 (driver does not enumerate): accepts the request as is. */
int v4l2_util_choose_size(const v4l2_util_framesize *sizes, int n, uint32_t w, uint32_t h, const char *device,
                          uint32_t *out_w, uint32_t *out_h, sci_error *err);

/* Control names compare equal ignoring case and treating ' ', '_' and '-' alike ("Trigger Mode" == "trigger_mode"). */
int v4l2_util_ctrl_name_eq(const char *a, const char *b);

#endif
