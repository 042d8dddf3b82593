#include "drivers/camera_v4l2.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "drivers/v4l2_util.h"

#define V4L2_MAX_FORMATS 64
#define V4L2_MAX_SIZES 64

typedef struct v4l2_buf {
    void *ptr;
    size_t len;
} v4l2_buf;

typedef struct v4l2_cam {
    v4l2_util_dev dev;
    char path[256];
    char want_card[64], want_bus[64];
    struct v4l2_capability cap;
    uint32_t caps;
    camera_config want;  /* the last format request, kept for recover (strings are not kept) */
    camera_format fmt;
    int have_fmt;
    uint32_t exposure_us;
    int32_t gain;
    char ctrl_names[CAMERA_MAX_CONTROLS][32];
    int64_t ctrl_values[CAMERA_MAX_CONTROLS];
    int nctrl;
    char profile_name[32];
    int buffer_count;
    v4l2_buf bufs[CAMERA_MAX_BUFFERS];
    int nbufs;
    int streaming;
} v4l2_cam;

static int v4l2_fail(v4l2_cam *c, int rc, sci_error *err, const char *what)
{
    return sci_error_set(err, rc, "%s: %s failed: %s", c->path, c->dev.last_ioctl ? c->dev.last_ioctl : what,
                         sci_strerror(rc));
}

/* Open `path` and check it is a streaming capture device. */
static int v4l2_probe(v4l2_cam *c, const char *path, sci_error *err)
{
    snprintf(c->path, sizeof c->path, "%s", path);
    int fd = c->dev.sys->open(c->dev.sys->ctx, path, O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        int e = errno;
        if (e == ENOENT)
            return sci_error_set(err, -ENOENT, "%s: no such device node", path);
        if (e == EACCES)
            return sci_error_set(err, -EACCES, "%s: permission denied (is the user in group video?)", path);
        if (e == EBUSY)
            return sci_error_set(err, -EBUSY, "%s: device busy", path);
        return sci_error_set(err, -e, "%s: open failed: %s", path, sci_strerror(-e));
    }
    c->dev.fd = fd;
    memset(&c->cap, 0, sizeof c->cap);
    int rc = V4L2_IOCTL(&c->dev, VIDIOC_QUERYCAP, &c->cap);
    if (rc == -ENOTTY || rc == -EINVAL) {
        rc = sci_error_set(err, -ENOTTY, "%s: not a V4L2 device (VIDIOC_QUERYCAP refused)", path);
        goto fail;
    }
    if (rc < 0) {
        rc = v4l2_fail(c, rc, err, "VIDIOC_QUERYCAP");
        goto fail;
    }
    c->caps = (c->cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? c->cap.device_caps : c->cap.capabilities;
    if (!(c->caps & V4L2_CAP_VIDEO_CAPTURE)) {
        rc = sci_error_set(err, -ENOTTY, "%s (%s): not a video capture device (capabilities 0x%08x%s)", path,
                           (const char *)c->cap.card, c->caps,
                           (c->caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) ? "; multi-planar capture is not supported" : "");
        goto fail;
    }
    if (!(c->caps & V4L2_CAP_STREAMING)) {
        rc = sci_error_set(err, -ENOTSUP, "%s (%s): no streaming I/O (read() only is not supported)", path,
                           (const char *)c->cap.card);
        goto fail;
    }
    return 0;
fail:
    c->dev.sys->close(c->dev.sys->ctx, fd);
    c->dev.fd = -1;
    return rc;
}

static int v4l2_matches(const v4l2_cam *c)
{
    return (!c->want_card[0] || strcmp((const char *)c->cap.card, c->want_card) == 0) &&
           (!c->want_bus[0] || strcmp((const char *)c->cap.bus_info, c->want_bus) == 0);
}

static int v4l2_find(v4l2_cam *c, sci_error *err)
{
    for (int i = 0; i < 64; i++) {
        char p[32];
        snprintf(p, sizeof p, "/dev/video%d", i);
        if (v4l2_probe(c, p, NULL) < 0)
            continue;
        if (v4l2_matches(c))
            return 0;
        c->dev.sys->close(c->dev.sys->ctx, c->dev.fd);
        c->dev.fd = -1;
    }
    return sci_error_set(err, -ENOENT, "no V4L2 capture device with card \"%s\" bus_info \"%s\"", c->want_card,
                         c->want_bus);
}

static int v4l2_find_ctrl(v4l2_cam *c, const char *name, uint32_t *id, uint32_t *type)
{
    struct v4l2_query_ext_ctrl q = {.id = V4L2_CTRL_FLAG_NEXT_CTRL | V4L2_CTRL_FLAG_NEXT_COMPOUND};
    while (V4L2_IOCTL(&c->dev, VIDIOC_QUERY_EXT_CTRL, &q) == 0) {
        if (!(q.flags & V4L2_CTRL_FLAG_DISABLED) && v4l2_util_ctrl_name_eq(q.name, name)) {
            *id = q.id;
            *type = q.type;
            return 0;
        }
        q = (struct v4l2_query_ext_ctrl){.id = q.id | V4L2_CTRL_FLAG_NEXT_CTRL | V4L2_CTRL_FLAG_NEXT_COMPOUND};
    }
    return -ENOENT;
}

static int v4l2_set_ctrl(v4l2_cam *c, uint32_t id, uint32_t type, int64_t value)
{
    struct v4l2_ext_control ctl = {.id = id};
    if (type == V4L2_CTRL_TYPE_INTEGER64)
        ctl.value64 = value;
    else
        ctl.value = (int32_t)value;
    struct v4l2_ext_controls cs = {.which = V4L2_CTRL_WHICH_CUR_VAL, .count = 1, .controls = &ctl};
    return V4L2_IOCTL(&c->dev, VIDIOC_S_EXT_CTRLS, &cs);
}

static int v4l2_get_ctrl(v4l2_cam *c, uint32_t id, int32_t *value)
{
    struct v4l2_control ctl = {.id = id};
    int rc = V4L2_IOCTL(&c->dev, VIDIOC_G_CTRL, &ctl);
    if (rc == 0)
        *value = ctl.value;
    return rc;
}

static int v4l2_apply_profile(v4l2_cam *c, sci_error *err)
{
    for (int i = 0; i < c->nctrl; i++) {
        uint32_t id, type;
        if (v4l2_find_ctrl(c, c->ctrl_names[i], &id, &type) < 0)
            return sci_error_set(err, -ENOTSUP, "%s (%s): no control \"%s\" (trigger profile \"%s\")", c->path,
                                 (const char *)c->cap.card, c->ctrl_names[i], c->profile_name);
        int rc = v4l2_set_ctrl(c, id, type, c->ctrl_values[i]);
        if (rc < 0)
            return sci_error_set(err, rc, "%s: control \"%s\" = %lld refused (trigger profile \"%s\"): %s", c->path,
                                 c->ctrl_names[i], (long long)c->ctrl_values[i], c->profile_name, sci_strerror(rc));
    }
    return 0;
}

static int v4l2_open(void **state, const camera_config *cfg, sci_error *err)
{
    v4l2_cam *c = calloc(1, sizeof *c);
    if (!c)
        return sci_error_set(err, -ENOMEM, "v4l2: out of memory");
    c->dev.sys = cfg->backend_options ? cfg->backend_options : &v4l2_util_sys_real;
    c->dev.fd = -1;
    c->gain = -1;
    c->buffer_count = cfg->buffer_count ? cfg->buffer_count : 4;
    int rc;
    if (c->buffer_count < 2 || c->buffer_count > CAMERA_MAX_BUFFERS) {
        rc = sci_error_set(err, -EINVAL, "%s: buffer count %d is outside 2..%d", cfg->device ? cfg->device : "v4l2",
                           c->buffer_count, CAMERA_MAX_BUFFERS);
        goto fail;
    }
    snprintf(c->want_card, sizeof c->want_card, "%s", cfg->card ? cfg->card : "");
    snprintf(c->want_bus, sizeof c->want_bus, "%s", cfg->bus_info ? cfg->bus_info : "");
    if (cfg->trigger_profile_count > CAMERA_MAX_CONTROLS) {
        rc = sci_error_set(err, -EINVAL, "v4l2: more than %d trigger profile controls", CAMERA_MAX_CONTROLS);
        goto fail;
    }
    snprintf(c->profile_name, sizeof c->profile_name, "%s",
             cfg->trigger_profile_name ? cfg->trigger_profile_name : "unnamed");
    for (int i = 0; i < cfg->trigger_profile_count; i++) {
        snprintf(c->ctrl_names[i], sizeof c->ctrl_names[i], "%s", cfg->trigger_profile[i].name);
        c->ctrl_values[i] = cfg->trigger_profile[i].value;
    }
    c->nctrl = cfg->trigger_profile_count;
    if (cfg->device)
        rc = v4l2_probe(c, cfg->device, err);
    else if (c->want_card[0] || c->want_bus[0])
        rc = v4l2_find(c, err);
    else
        rc = sci_error_set(err, -EINVAL, "v4l2: no device, card or bus_info given");
    if (rc < 0)
        goto fail;
    if ((rc = v4l2_apply_profile(c, err)) < 0)
        goto fail_close;
    *state = c;
    return 0;
fail_close:
    c->dev.sys->close(c->dev.sys->ctx, c->dev.fd);
fail:
    free(c);
    return rc;
}

static void v4l2_unmap(v4l2_cam *c)
{
    for (int i = 0; i < c->nbufs; i++)
        if (c->bufs[i].ptr)
            c->dev.sys->munmap(c->dev.sys->ctx, c->bufs[i].ptr, c->bufs[i].len);
    c->nbufs = 0;
}

static void v4l2_release_stream(v4l2_cam *c)
{
    enum v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (c->streaming)
        V4L2_IOCTL(&c->dev, VIDIOC_STREAMOFF, &type);
    v4l2_unmap(c);
    struct v4l2_requestbuffers rb = {.count = 0, .type = V4L2_BUF_TYPE_VIDEO_CAPTURE, .memory = V4L2_MEMORY_MMAP};
    V4L2_IOCTL(&c->dev, VIDIOC_REQBUFS, &rb);
    c->streaming = 0;
}

static void v4l2_close(void *state)
{
    v4l2_cam *c = state;
    if (!c)
        return;
    if (c->dev.fd >= 0) {
        v4l2_release_stream(c);
        c->dev.sys->close(c->dev.sys->ctx, c->dev.fd);
    }
    free(c);
}

static void v4l2_identity(void *state, camera_identity *out)
{
    v4l2_cam *c = state;
    memset(out, 0, sizeof *out);
    snprintf(out->backend, sizeof out->backend, "v4l2");
    snprintf(out->driver, sizeof out->driver, "%s", (const char *)c->cap.driver);
    snprintf(out->card, sizeof out->card, "%s", (const char *)c->cap.card);
    snprintf(out->bus_info, sizeof out->bus_info, "%s", (const char *)c->cap.bus_info);
    snprintf(out->path, sizeof out->path, "%s", c->path);
    out->version = c->cap.version;
}

/* Nothing asked and no monochrome format offered: a colour sensor's raw Bayer mosaic, most bits first, unpacked
 * containers before MIPI-packed (as for mono), whatever the filter order. -ENOTSUP when none is offered. */
static int v4l2_choose_bayer(const v4l2_util_fmtdesc *offered, int n, enum pixfmt *out)
{
    static const enum pixfmt by_depth[] = {PIXFMT_Y16, PIXFMT_Y12, PIXFMT_Y10, PIXFMT_Y10P, PIXFMT_GREY};
    static const enum pixfmt_cfa cfas[] = {PIXFMT_CFA_RGGB, PIXFMT_CFA_GRBG, PIXFMT_CFA_GBRG, PIXFMT_CFA_BGGR};
    for (size_t d = 0; d < sizeof by_depth / sizeof by_depth[0]; d++)
        for (size_t k = 0; k < sizeof cfas / sizeof cfas[0]; k++) {
            enum pixfmt pf = pixfmt_with_cfa(by_depth[d], cfas[k]);
            for (int i = 0; i < n; i++)
                if (offered[i].fourcc == pixfmt_info_get(pf)->fourcc && !(offered[i].flags & V4L2_FMT_FLAG_COMPRESSED)) {
                    *out = pf;
                    return 0;
                }
        }
    return -ENOTSUP;
}

static int v4l2_set_format(void *state, const camera_config *want, camera_format *out, sci_error *err)
{
    v4l2_cam *c = state;
    if (c->streaming)
        return sci_error_set(err, -EBUSY, "%s: cannot change the format while streaming", c->path);
    v4l2_util_fmtdesc offered[V4L2_MAX_FORMATS];
    int n = 0, rc;
    for (; n < V4L2_MAX_FORMATS; n++) {
        struct v4l2_fmtdesc d = {.index = (uint32_t)n, .type = V4L2_BUF_TYPE_VIDEO_CAPTURE};
        if (V4L2_IOCTL(&c->dev, VIDIOC_ENUM_FMT, &d) < 0)
            break;
        offered[n] = (v4l2_util_fmtdesc){.fourcc = d.pixelformat, .flags = d.flags};
    }
    enum pixfmt pf;
    if ((rc = v4l2_util_choose_format(offered, n, want->pixfmt, c->path, &pf, err)) < 0 &&
        (want->pixfmt != PIXFMT_NONE || v4l2_choose_bayer(offered, n, &pf) < 0))
        return rc;
    uint32_t fourcc = pixfmt_info_get(pf)->fourcc;
    v4l2_util_framesize sizes[V4L2_MAX_SIZES];
    int ns = 0;
    for (; ns < V4L2_MAX_SIZES; ns++) {
        struct v4l2_frmsizeenum fs = {.index = (uint32_t)ns, .pixel_format = fourcc};
        if (V4L2_IOCTL(&c->dev, VIDIOC_ENUM_FRAMESIZES, &fs) < 0)
            break;
        if (fs.type == V4L2_FRMSIZE_TYPE_DISCRETE)
            sizes[ns] = (v4l2_util_framesize){fs.discrete.width, fs.discrete.width, 0,
                                              fs.discrete.height, fs.discrete.height, 0};
        else {
            sizes[ns] = (v4l2_util_framesize){fs.stepwise.min_width, fs.stepwise.max_width, fs.stepwise.step_width,
                                              fs.stepwise.min_height, fs.stepwise.max_height, fs.stepwise.step_height};
            ns++;
            break; /* stepwise and continuous have a single entry */
        }
    }
    struct v4l2_format f = {.type = V4L2_BUF_TYPE_VIDEO_CAPTURE};
    if ((rc = V4L2_IOCTL(&c->dev, VIDIOC_G_FMT, &f)) < 0)
        return v4l2_fail(c, rc, err, "VIDIOC_G_FMT");
    uint32_t w = f.fmt.pix.width, h = f.fmt.pix.height;
    if ((want->width || want->height) &&
        (rc = v4l2_util_choose_size(sizes, ns, want->width, want->height, c->path, &w, &h, err)) < 0)
        return rc;
    f = (struct v4l2_format){.type = V4L2_BUF_TYPE_VIDEO_CAPTURE};
    f.fmt.pix = (struct v4l2_pix_format){.width = w, .height = h, .pixelformat = fourcc, .field = V4L2_FIELD_NONE};
    if ((rc = V4L2_IOCTL(&c->dev, VIDIOC_S_FMT, &f)) < 0)
        return rc == -EBUSY ? sci_error_set(err, -EBUSY, "%s: format locked (another process is streaming)", c->path)
                            : v4l2_fail(c, rc, err, "VIDIOC_S_FMT");
    if (f.fmt.pix.pixelformat != fourcc || f.fmt.pix.width != w || f.fmt.pix.height != h) {
        char a[5], b[5];
        return sci_error_set(err, -ENOTSUP, "%s: asked for %ux%u %s, the driver set %ux%u %s", c->path, w, h,
                             pixfmt_fourcc_str(fourcc, a), f.fmt.pix.width, f.fmt.pix.height,
                             pixfmt_fourcc_str(f.fmt.pix.pixelformat, b));
    }
    size_t min = pixfmt_min_stride(pf, w);
    uint32_t bpl = f.fmt.pix.bytesperline ? f.fmt.pix.bytesperline : (uint32_t)min;
    if (bpl < min || (size_t)f.fmt.pix.sizeimage < (size_t)bpl * (h - 1) + min)
        return sci_error_set(err, SCI_EDEVICE, "%s: driver reports bytesperline %u / sizeimage %u, too small for "
                             "%ux%u %s", c->path, f.fmt.pix.bytesperline, f.fmt.pix.sizeimage, w, h, pixfmt_name(pf));
    c->fmt = (camera_format){.width = w, .height = h, .pixfmt = pf, .bits_per_sample = pixfmt_info_get(pf)->bits_per_sample,
                             .bytesperline = bpl, .sizeimage = f.fmt.pix.sizeimage};
    struct v4l2_streamparm parm = {.type = V4L2_BUF_TYPE_VIDEO_CAPTURE};
    if (want->interval_num && want->interval_den) {
        parm.parm.capture.timeperframe = (struct v4l2_fract){want->interval_num, want->interval_den};
        rc = V4L2_IOCTL(&c->dev, VIDIOC_S_PARM, &parm);
        if (rc < 0 || !(parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME))
            return sci_error_set(err, -ENOTSUP, "%s: frame interval %u/%u s not settable (%s)", c->path,
                                 want->interval_num, want->interval_den, rc < 0 ? sci_strerror(rc) : "no TIMEPERFRAME");
    } else {
        parm = (struct v4l2_streamparm){.type = V4L2_BUF_TYPE_VIDEO_CAPTURE};
        V4L2_IOCTL(&c->dev, VIDIOC_G_PARM, &parm);
    }
    c->fmt.interval_num = parm.parm.capture.timeperframe.numerator;
    c->fmt.interval_den = parm.parm.capture.timeperframe.denominator;
    c->want = camera_config_format_request(w, h, pf, want);
    c->have_fmt = 1;
    *out = c->fmt;
    return 0;
}

static int v4l2_set_exposure(void *state, uint32_t *exposure_us, sci_error *err)
{
    v4l2_cam *c = state;
    /* auto off first: manual values are ignored while auto exposure is on (ext-ctrls-camera.rst) */
    int rc = v4l2_set_ctrl(c, V4L2_CID_EXPOSURE_AUTO, V4L2_CTRL_TYPE_MENU, V4L2_EXPOSURE_MANUAL);
    if (rc < 0 && rc != -EINVAL)
        return v4l2_fail(c, rc, err, "VIDIOC_S_EXT_CTRLS(EXPOSURE_AUTO)");
    int32_t units = (int32_t)((*exposure_us + 50) / 100);
    if (units < 1)
        units = 1;
    rc = v4l2_set_ctrl(c, V4L2_CID_EXPOSURE_ABSOLUTE, V4L2_CTRL_TYPE_INTEGER, units);
    if (rc == -EINVAL)
        return sci_error_set(err, -ENOTSUP, "%s (%s): no V4L2_CID_EXPOSURE_ABSOLUTE control", c->path,
                             (const char *)c->cap.card);
    if (rc == -ERANGE)
        return sci_error_set(err, -ERANGE, "%s: exposure %u us is out of the device's range", c->path, *exposure_us);
    if (rc < 0)
        return v4l2_fail(c, rc, err, "VIDIOC_S_EXT_CTRLS(EXPOSURE_ABSOLUTE)");
    int32_t got = units;
    v4l2_get_ctrl(c, V4L2_CID_EXPOSURE_ABSOLUTE, &got); /* the driver may clamp to the frame interval */
    *exposure_us = (uint32_t)got * 100;
    c->exposure_us = *exposure_us;
    return 0;
}

static int v4l2_set_gain(void *state, int32_t *gain, sci_error *err)
{
    v4l2_cam *c = state;
    /* auto gain off first, as for exposure: while it is on, the gain is the device's own (read back volatile) */
    int rc = v4l2_set_ctrl(c, V4L2_CID_AUTOGAIN, V4L2_CTRL_TYPE_BOOLEAN, 0);
    if (rc < 0 && rc != -EINVAL)
        return v4l2_fail(c, rc, err, "VIDIOC_S_EXT_CTRLS(AUTOGAIN)");
    uint32_t id = V4L2_CID_GAIN;
    rc = v4l2_set_ctrl(c, id, V4L2_CTRL_TYPE_INTEGER, *gain);
    if (rc == -EINVAL) {
        id = V4L2_CID_ANALOGUE_GAIN;
        rc = v4l2_set_ctrl(c, id, V4L2_CTRL_TYPE_INTEGER, *gain);
    }
    if (rc == -EINVAL)
        return sci_error_set(err, -ENOTSUP, "%s (%s): no gain control (V4L2_CID_GAIN or ANALOGUE_GAIN)", c->path,
                             (const char *)c->cap.card);
    if (rc < 0)
        return sci_error_set(err, rc, "%s: gain %d refused: %s", c->path, (int)*gain, sci_strerror(rc));
    v4l2_get_ctrl(c, id, gain);
    c->gain = *gain;
    return 0;
}

static int v4l2_start(void *state, sci_error *err)
{
    v4l2_cam *c = state;
    struct v4l2_requestbuffers rb = {.count = (uint32_t)c->buffer_count, .type = V4L2_BUF_TYPE_VIDEO_CAPTURE,
                                     .memory = V4L2_MEMORY_MMAP};
    int rc = V4L2_IOCTL(&c->dev, VIDIOC_REQBUFS, &rb);
    if (rc < 0)
        return rc == -EBUSY ? sci_error_set(err, -EBUSY, "%s: buffers held by another process", c->path)
                            : v4l2_fail(c, rc, err, "VIDIOC_REQBUFS");
    if (rb.count < 2 || rb.count > CAMERA_MAX_BUFFERS) {
        rc = sci_error_set(err, SCI_EDEVICE, "%s: driver granted %u buffers (need 2..%d)", c->path, rb.count,
                           CAMERA_MAX_BUFFERS);
        goto fail;
    }
    for (uint32_t i = 0; i < rb.count; i++) {
        struct v4l2_buffer b = {.index = i, .type = V4L2_BUF_TYPE_VIDEO_CAPTURE, .memory = V4L2_MEMORY_MMAP};
        if ((rc = V4L2_IOCTL(&c->dev, VIDIOC_QUERYBUF, &b)) < 0) {
            rc = v4l2_fail(c, rc, err, "VIDIOC_QUERYBUF");
            goto fail;
        }
        void *p = c->dev.sys->mmap(c->dev.sys->ctx, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, c->dev.fd,
                                   (off_t)b.m.offset);
        if (p == MAP_FAILED) {
            rc = sci_error_set(err, -errno, "%s: mmap of buffer %u failed: %s", c->path, i, sci_strerror(-errno));
            goto fail;
        }
        c->bufs[c->nbufs++] = (v4l2_buf){.ptr = p, .len = b.length};
        if ((rc = V4L2_IOCTL(&c->dev, VIDIOC_QBUF, &b)) < 0) {
            rc = v4l2_fail(c, rc, err, "VIDIOC_QBUF");
            goto fail;
        }
    }
    enum v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if ((rc = V4L2_IOCTL(&c->dev, VIDIOC_STREAMON, &type)) < 0) {
        rc = v4l2_fail(c, rc, err, "VIDIOC_STREAMON");
        goto fail;
    }
    c->streaming = 1;
    return 0;
fail:
    v4l2_release_stream(c);
    return rc;
}

static int v4l2_stop(void *state, sci_error *err)
{
    v4l2_cam *c = state;
    v4l2_release_stream(c);
    return 0;
}

static int v4l2_wait_frame(void *state, int64_t timeout_ns, camera_frame *out, sci_error *err)
{
    v4l2_cam *c = state;
    int timeout_ms = (int)((timeout_ns + 999999) / 1000000);
    for (;;) {
        struct pollfd pfd = {.fd = c->dev.fd, .events = POLLIN | POLLPRI};
        int r = c->dev.sys->poll(c->dev.sys->ctx, &pfd, 1, timeout_ms);
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return sci_error_set(err, -errno, "%s: poll failed: %s", c->path, sci_strerror(-errno));
        if (r == 0)
            return sci_error_set(err, -ETIMEDOUT, "%s: no frame within %d ms", c->path, timeout_ms);
        struct v4l2_buffer b = {.type = V4L2_BUF_TYPE_VIDEO_CAPTURE, .memory = V4L2_MEMORY_MMAP};
        int rc = V4L2_IOCTL(&c->dev, VIDIOC_DQBUF, &b);
        if (rc == -EAGAIN) {
            if (pfd.revents & POLLERR)
                return sci_error_set(err, -EIO, "%s: device error (POLLERR, no buffer)", c->path);
            continue; /* spurious wake-up, or only an event (POLLPRI) */
        }
        if (rc == -ENODEV)
            return sci_error_set(err, -ENODEV, "%s (%s): device disconnected", c->path, (const char *)c->cap.card);
        if (rc < 0)
            return v4l2_fail(c, rc, err, "VIDIOC_DQBUF");
        if (b.index >= (uint32_t)c->nbufs)
            return sci_error_set(err, SCI_EDEVICE, "%s: driver returned buffer %u of %d", c->path, b.index, c->nbufs);
        size_t used = b.bytesused ? b.bytesused : c->bufs[b.index].len;
        if (used > c->bufs[b.index].len)
            used = c->bufs[b.index].len;
        rc = camera_frame_unpack(out, &c->fmt, c->bufs[b.index].ptr, used, c->fmt.bytesperline, err);
        /* Back to the driver at once, whatever happened. QBUF is _IOWR: the kernel rewrites the struct with the
         * queued state (sequence 0, no timestamp, no ERROR flag), so it gets a copy and `b` keeps the frame's. */
        struct v4l2_buffer q = b;
        int qrc = V4L2_IOCTL(&c->dev, VIDIOC_QBUF, &q);
        if (rc < 0)
            return sci_error_prefix(err, "%s: buffer %u: ", c->path, b.index), rc;
        if (qrc < 0)
            return qrc == -ENODEV ? sci_error_set(err, -ENODEV, "%s: device disconnected", c->path)
                                  : v4l2_fail(c, qrc, err, "VIDIOC_QBUF");
        out->sequence = b.sequence;
        out->timestamp_ns = (int64_t)b.timestamp.tv_sec * 1000000000LL + (int64_t)b.timestamp.tv_usec * 1000;
        uint32_t src = b.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK;
        out->ts_source = (b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC ? CAMERA_TS_UNKNOWN
                         : src == V4L2_BUF_FLAG_TSTAMP_SRC_SOE                                      ? CAMERA_TS_SOE
                                                                                                   : CAMERA_TS_EOF;
        out->corrupt = (b.flags & V4L2_BUF_FLAG_ERROR) != 0;
        out->exposure_us = c->exposure_us;
        out->gain = c->gain;
        return 0;
    }
}

static int v4l2_recover(void *state, sci_error *err)
{
    v4l2_cam *c = state;
    int was_streaming = c->streaming;
    if (c->dev.fd >= 0) {
        v4l2_unmap(c); /* the old buffers die with the fd; no ioctl on a dead device */
        c->dev.sys->close(c->dev.sys->ctx, c->dev.fd);
        c->dev.fd = -1;
    }
    c->streaming = 0;
    char path[256];
    snprintf(path, sizeof path, "%s", c->path);
    int rc = (c->want_card[0] || c->want_bus[0]) && strncmp(path, "/dev/video", 10) == 0 ? v4l2_find(c, err)
                                                                                           : v4l2_probe(c, path, err);
    if (rc < 0)
        return rc;
    camera_format f;
    if ((rc = v4l2_apply_profile(c, err)) < 0 || (c->have_fmt && (rc = v4l2_set_format(c, &c->want, &f, err)) < 0))
        return rc;
    return camera_recover_controls(&camera_v4l2_ops, c, c->exposure_us, c->gain, was_streaming, err);
}

const camera_ops camera_v4l2_ops = {
    .name = "v4l2",
    .open = v4l2_open,
    .close = v4l2_close,
    .identity = v4l2_identity,
    .set_format = v4l2_set_format,
    .set_exposure_us = v4l2_set_exposure,
    .set_gain = v4l2_set_gain,
    .start = v4l2_start,
    .stop = v4l2_stop,
    .wait_frame = v4l2_wait_frame,
    .recover = v4l2_recover,
};
