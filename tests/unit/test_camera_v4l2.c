/* The V4L2 backend's bad-input errors on this machine's real nodes: a node that is not a capture device, a node
 * that does not exist, a card that no device has. (Streaming needs a device: vivid, tests/vm.)
 * And the Bayer path end to end through the backend against a fake kernel (the v4l2_util_sys seam): a colour
 * sensor offering only Bayer gets its best raw format, and frames arrive as the raw mosaic, bit for bit, with the
 * driver's row padding removed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>
#include <errno.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>

#include "drivers/camera_v4l2.h"
#include "drivers/v4l2_util.h"

static void not_a_capture_device(void **state)
{
    (void)state;
    camera_config cfg = camera_config_default();
    cfg.device = "/dev/null";
    camera *cam = NULL;
    sci_error err = {0};
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -ENOTTY);
    assert_null(cam);
    assert_string_equal(err.msg, "/dev/null: not a V4L2 device (VIDIOC_QUERYCAP refused)");
}

static void missing_node(void **state)
{
    (void)state;
    camera_config cfg = camera_config_default();
    cfg.device = "/dev/v4l/by-id/usb-none-video-index0";
    camera *cam = NULL;
    sci_error err = {0};
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -ENOENT);
    assert_non_null(strstr(err.msg, "/dev/v4l/by-id/usb-none-video-index0: no such device node"));
}

static void card_not_found(void **state)
{
    (void)state;
    camera_config cfg = camera_config_default();
    cfg.card = "No Such Camera 9000";
    camera *cam = NULL;
    sci_error err = {0};
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -ENOENT);
    assert_non_null(strstr(err.msg, "card \"No Such Camera 9000\""));
    cfg = camera_config_default();
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "no device, card or bus_info"));
}

/* ---- a fake kernel: one capture node offering a list of formats at one size, two mmap buffers ---- */

#define FAKE_W 6
#define FAKE_H 4
#define FAKE_PAD 3 /* bytes of driver padding per row */

typedef struct fake_node {
    const uint32_t *formats;
    int nformats;
    uint32_t fourcc;        /* the format set */
    uint32_t bpl, sizeimage;
    uint8_t mem[2][256];
    int queued[2];
    uint32_t sequence;
    uint16_t samples[FAKE_W * FAKE_H]; /* what the sensor "saw" for the next frame */
} fake_node;

static int fake_err(int e)
{
    errno = e;
    return -1;
}

static int fake_open(void *ctx, const char *path, int flags) { return 42; }
static int fake_close(void *ctx, int fd) { return 0; }
static int fake_munmap(void *ctx, void *p, size_t len) { return 0; }
static int fake_poll(void *ctx, struct pollfd *fds, nfds_t n, int timeout_ms)
{
    fds[0].revents = POLLIN;
    return 1;
}
static void *fake_mmap(void *ctx, size_t len, int prot, int flags, int fd, off_t off)
{
    fake_node *f = ctx;
    return off / 4096 < 2 && len <= sizeof f->mem[0] ? f->mem[off / 4096] : MAP_FAILED;
}

static int fake_ioctl(void *ctx, int fd, unsigned long req, void *arg)
{
    fake_node *f = ctx;
    switch (req) {
    case VIDIOC_QUERYCAP: {
        struct v4l2_capability *c = arg;
        snprintf((char *)c->driver, sizeof c->driver, "fake");
        snprintf((char *)c->card, sizeof c->card, "fake bayer sensor");
        c->capabilities = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING | V4L2_CAP_DEVICE_CAPS;
        c->device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
        return 0;
    }
    case VIDIOC_ENUM_FMT: {
        struct v4l2_fmtdesc *d = arg;
        if (d->index >= (uint32_t)f->nformats)
            return fake_err(EINVAL);
        d->pixelformat = f->formats[d->index];
        d->flags = d->pixelformat == V4L2_PIX_FMT_MJPEG ? V4L2_FMT_FLAG_COMPRESSED : 0;
        return 0;
    }
    case VIDIOC_ENUM_FRAMESIZES: {
        struct v4l2_frmsizeenum *s = arg;
        if (s->index > 0)
            return fake_err(EINVAL);
        s->type = V4L2_FRMSIZE_TYPE_DISCRETE;
        s->discrete.width = FAKE_W;
        s->discrete.height = FAKE_H;
        return 0;
    }
    case VIDIOC_G_FMT:
    case VIDIOC_S_FMT: {
        struct v4l2_format *fm = arg;
        if (req == VIDIOC_S_FMT) {
            enum pixfmt pf = pixfmt_from_fourcc(fm->fmt.pix.pixelformat);
            f->fourcc = fm->fmt.pix.pixelformat;
            f->bpl = (uint32_t)pixfmt_min_stride(pf, FAKE_W) + FAKE_PAD;
            f->sizeimage = f->bpl * FAKE_H;
        }
        fm->fmt.pix.width = FAKE_W;
        fm->fmt.pix.height = FAKE_H;
        fm->fmt.pix.pixelformat = f->fourcc;
        fm->fmt.pix.bytesperline = f->bpl;
        fm->fmt.pix.sizeimage = f->sizeimage;
        return 0;
    }
    case VIDIOC_G_PARM: return 0;
    case VIDIOC_REQBUFS: {
        struct v4l2_requestbuffers *rb = arg;
        rb->count = rb->count ? 2 : 0;
        return 0;
    }
    case VIDIOC_QUERYBUF: {
        struct v4l2_buffer *b = arg;
        b->length = f->sizeimage;
        b->m.offset = b->index * 4096;
        return 0;
    }
    case VIDIOC_QBUF: f->queued[((struct v4l2_buffer *)arg)->index] = 1; return 0;
    case VIDIOC_STREAMON:
    case VIDIOC_STREAMOFF: return 0;
    case VIDIOC_DQBUF: {
        struct v4l2_buffer *b = arg;
        int i = f->queued[0] ? 0 : f->queued[1] ? 1 : -1;
        if (i < 0)
            return fake_err(EAGAIN);
        f->queued[i] = 0;
        memset(f->mem[i], 0xA5, sizeof f->mem[i]); /* padding bytes must not leak into the samples */
        sci_error err = {0};
        enum pixfmt pf = pixfmt_from_fourcc(f->fourcc);
        if (pixfmt_pack(pf, f->samples, FAKE_W, FAKE_H, f->mem[i], f->sizeimage, f->bpl, &err) < 0)
            fail_msg("fake kernel: pack: %s", err.msg);
        for (uint32_t y = 0; y < FAKE_H; y++) /* pack zeroes the padding: put garbage back */
            memset(f->mem[i] + y * f->bpl + pixfmt_min_stride(pf, FAKE_W), 0xA5, FAKE_PAD);
        b->index = (uint32_t)i;
        b->bytesused = f->sizeimage;
        b->sequence = f->sequence++;
        b->flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
        b->timestamp.tv_sec = 100 + b->sequence;
        return 0;
    }
    default: return fake_err(EINVAL); /* no controls */
    }
}

static const camera_format *open_fake_node(fake_node *f, const uint32_t *formats, int n, enum pixfmt want,
                                           camera **cam, camera_format *fmt, sci_error *err)
{
    memset(f, 0, sizeof *f);
    f->formats = formats;
    f->nformats = n;
    static v4l2_util_sys sys;
    sys = (v4l2_util_sys){.open = fake_open, .close = fake_close, .ioctl = fake_ioctl, .mmap = fake_mmap,
                          .munmap = fake_munmap, .poll = fake_poll, .ctx = f};
    camera_config cfg = camera_config_default();
    cfg.device = "/dev/fake-bayer";
    cfg.pixfmt = want;
    cfg.backend_options = &sys;
    *cam = NULL;
    if (camera_open(cam, &camera_v4l2_ops, &cfg, err) < 0)
        return NULL;
    camera_format_get(*cam, fmt);
    return fmt;
}

static void bayer_through_the_backend(void **state)
{
    (void)state;
    static const struct {
        uint32_t offered[3];
        int n;
        enum pixfmt want, got;
    } cases[] = {
        {{V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_SRGGB12}, 2, PIXFMT_NONE, PIXFMT_SRGGB12},   /* no mono: Bayer taken */
        {{V4L2_PIX_FMT_SBGGR8, V4L2_PIX_FMT_SGRBG16, V4L2_PIX_FMT_MJPEG}, 3, PIXFMT_NONE, PIXFMT_SGRBG16}, /* most bits */
        {{V4L2_PIX_FMT_SBGGR8, V4L2_PIX_FMT_SGRBG16}, 2, PIXFMT_SBGGR8, PIXFMT_SBGGR8}, /* asked: taken */
        {{V4L2_PIX_FMT_SGBRG10P, V4L2_PIX_FMT_SGBRG8}, 2, PIXFMT_NONE, PIXFMT_SGBRG10P},
        {{V4L2_PIX_FMT_Y10, V4L2_PIX_FMT_SRGGB16}, 2, PIXFMT_NONE, PIXFMT_Y10},          /* mono still first */
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        fake_node f;
        camera *cam;
        camera_format fmt;
        sci_error err = {0};
        if (!open_fake_node(&f, cases[k].offered, cases[k].n, cases[k].want, &cam, &fmt, &err))
            fail_msg("case %zu: camera_open: %s", k, err.msg);
        assert_int_equal(fmt.pixfmt, cases[k].got);
        assert_int_equal(fmt.bytesperline, pixfmt_min_stride(cases[k].got, FAKE_W) + FAKE_PAD);
        int bits = pixfmt_info_get(cases[k].got)->bits_per_sample;
        assert_int_equal(camera_start(cam, &err), 0);
        camera_frame fr = {0};
        for (int n = 0; n < 3; n++) {
            for (int i = 0; i < FAKE_W * FAKE_H; i++) /* a mosaic with every sample distinct and the top bit used */
                f.samples[i] = (uint16_t)(((unsigned)i * 2654435761u + (unsigned)n * 97u) % (1u << bits));
            f.samples[0] = (uint16_t)((1u << bits) - 1);
            assert_int_equal(camera_wait_frame(cam, 1000000000LL, &fr, &err), 0);
            assert_int_equal(fr.pixfmt, cases[k].got);
            assert_int_equal(fr.bits_per_sample, bits);
            assert_int_equal(fr.width, FAKE_W);
            assert_memory_equal(fr.data, f.samples, sizeof f.samples);
            assert_int_equal(fr.lost_before, 0);
        }
        camera_frame_release(&fr);
        camera_close(cam);
    }
    /* a webcam: YUYV and MJPG only, still refused */
    static const uint32_t webcam[] = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
    fake_node f;
    camera *cam;
    camera_format fmt;
    sci_error err = {0};
    assert_null(open_fake_node(&f, webcam, 2, PIXFMT_NONE, &cam, &fmt, &err));
    assert_null(cam);
    assert_non_null(strstr(err.msg, "YUYV (colour)"));
    /* Bayer asked for and not offered: refused, naming it */
    static const uint32_t rggb8[] = {V4L2_PIX_FMT_SRGGB8};
    assert_null(open_fake_node(&f, rggb8, 1, PIXFMT_SBGGR12, &cam, &fmt, &err));
    assert_non_null(strstr(err.msg, "does not offer format SBGGR12"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(not_a_capture_device),
        cmocka_unit_test(missing_node),
        cmocka_unit_test(card_not_found),
        cmocka_unit_test(bayer_through_the_backend),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
