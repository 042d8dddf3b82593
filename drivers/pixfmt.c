#include "drivers/pixfmt.h"

#include <errno.h>
#include <linux/videodev2.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

static const pixfmt_info pixfmt_table[PIXFMT_COUNT] = {
    [PIXFMT_GREY] = {.id = PIXFMT_GREY, .name = "GREY", .fourcc = V4L2_PIX_FMT_GREY, .bits_per_sample = 8},
    [PIXFMT_Y10] = {.id = PIXFMT_Y10, .name = "Y10", .fourcc = V4L2_PIX_FMT_Y10, .bits_per_sample = 10},
    [PIXFMT_Y12] = {.id = PIXFMT_Y12, .name = "Y12", .fourcc = V4L2_PIX_FMT_Y12, .bits_per_sample = 12},
    [PIXFMT_Y16] = {.id = PIXFMT_Y16, .name = "Y16", .fourcc = V4L2_PIX_FMT_Y16, .bits_per_sample = 16},
    [PIXFMT_Y10P] = {.id = PIXFMT_Y10P, .name = "Y10P", .fourcc = V4L2_PIX_FMT_Y10P, .bits_per_sample = 10},
};

#define PIXFMT_ACCEPTED "GREY, Y10, Y12, Y16, Y10P"

const pixfmt_info *pixfmt_info_get(enum pixfmt f)
{
    if ((int)f <= PIXFMT_NONE || f >= PIXFMT_COUNT)
        return NULL;
    return &pixfmt_table[f];
}

const char *pixfmt_name(enum pixfmt f)
{
    const pixfmt_info *in = pixfmt_info_get(f);
    return in ? in->name : "none";
}

int pixfmt_from_name(const char *name, enum pixfmt *out, sci_error *err)
{
    for (int f = PIXFMT_NONE + 1; f < PIXFMT_COUNT; f++)
        if (name && strcasecmp(name, pixfmt_table[f].name) == 0) {
            *out = (enum pixfmt)f;
            return 0;
        }
    return sci_error_set(err, -EINVAL, "pixel format \"%s\" is not supported (use one of " PIXFMT_ACCEPTED ")",
                         name ? name : "(null)");
}

enum pixfmt pixfmt_from_fourcc(uint32_t fourcc)
{
    for (int f = PIXFMT_NONE + 1; f < PIXFMT_COUNT; f++)
        if (pixfmt_table[f].fourcc == fourcc)
            return (enum pixfmt)f;
    return PIXFMT_NONE;
}

char *pixfmt_fourcc_str(uint32_t fourcc, char buf[5])
{
    for (int i = 0; i < 4; i++) {
        unsigned char c = (unsigned char)((fourcc >> (8 * i)) & 0xff);
        buf[i] = (c >= 0x20 && c < 0x7f) ? (char)c : '.';
    }
    buf[4] = '\0';
    return buf;
}

static int fourcc_in(uint32_t fourcc, const uint32_t *list, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (list[i] == fourcc)
            return 1;
    return 0;
}

enum pixfmt_kind pixfmt_classify_fourcc(uint32_t fourcc, int compressed_flag)
{
    static const uint32_t compressed[] = {
        V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_JPEG, V4L2_PIX_FMT_H264, V4L2_PIX_FMT_H264_NO_SC, V4L2_PIX_FMT_HEVC,
        V4L2_PIX_FMT_VP8,   V4L2_PIX_FMT_VP9,  V4L2_PIX_FMT_MPEG, V4L2_PIX_FMT_MPEG2,       V4L2_PIX_FMT_MPEG4,
    };
    static const uint32_t mono_other[] = {
        V4L2_PIX_FMT_Y4, V4L2_PIX_FMT_Y6, V4L2_PIX_FMT_Y14, V4L2_PIX_FMT_Y10BPACK, V4L2_PIX_FMT_Y16_BE,
    };
    static const uint32_t colour[] = {
        V4L2_PIX_FMT_YUYV,   V4L2_PIX_FMT_UYVY,   V4L2_PIX_FMT_YVYU,   V4L2_PIX_FMT_VYUY,   V4L2_PIX_FMT_NV12,
        V4L2_PIX_FMT_NV21,   V4L2_PIX_FMT_NV16,   V4L2_PIX_FMT_NV61,   V4L2_PIX_FMT_YUV420, V4L2_PIX_FMT_YVU420,
        V4L2_PIX_FMT_YUV422P, V4L2_PIX_FMT_RGB24, V4L2_PIX_FMT_BGR24,  V4L2_PIX_FMT_RGB565, V4L2_PIX_FMT_RGB32,
        V4L2_PIX_FMT_BGR32,  V4L2_PIX_FMT_ABGR32, V4L2_PIX_FMT_XBGR32, V4L2_PIX_FMT_ARGB32, V4L2_PIX_FMT_XRGB32,
        V4L2_PIX_FMT_SBGGR8, V4L2_PIX_FMT_SGBRG8, V4L2_PIX_FMT_SGRBG8, V4L2_PIX_FMT_SRGGB8, V4L2_PIX_FMT_SBGGR10,
        V4L2_PIX_FMT_SGBRG10, V4L2_PIX_FMT_SGRBG10, V4L2_PIX_FMT_SRGGB10, V4L2_PIX_FMT_SBGGR10P,
        V4L2_PIX_FMT_SGBRG10P, V4L2_PIX_FMT_SGRBG10P, V4L2_PIX_FMT_SRGGB10P, V4L2_PIX_FMT_SBGGR12,
        V4L2_PIX_FMT_SGBRG12, V4L2_PIX_FMT_SGRBG12, V4L2_PIX_FMT_SRGGB12, V4L2_PIX_FMT_SBGGR16,
        V4L2_PIX_FMT_SGBRG16, V4L2_PIX_FMT_SGRBG16, V4L2_PIX_FMT_SRGGB16,
    };
    if (compressed_flag || fourcc_in(fourcc, compressed, sizeof compressed / sizeof compressed[0]))
        return PIXFMT_KIND_COMPRESSED;
    if (pixfmt_from_fourcc(fourcc) != PIXFMT_NONE)
        return PIXFMT_KIND_MONO;
    if (fourcc_in(fourcc, mono_other, sizeof mono_other / sizeof mono_other[0]))
        return PIXFMT_KIND_MONO_OTHER;
    if (fourcc_in(fourcc, colour, sizeof colour / sizeof colour[0]))
        return PIXFMT_KIND_COLOUR;
    return PIXFMT_KIND_UNKNOWN;
}

int pixfmt_check_fourcc(uint32_t fourcc, int compressed_flag, const char *device, sci_error *err)
{
    char s[5];
    const char *why;
    switch (pixfmt_classify_fourcc(fourcc, compressed_flag)) {
    case PIXFMT_KIND_MONO: return 0;
    case PIXFMT_KIND_COMPRESSED: why = "is compressed (lossy or not sensor counts)"; break;
    case PIXFMT_KIND_COLOUR: why = "is a colour format (YUV/RGB/Bayer), not raw monochrome counts"; break;
    case PIXFMT_KIND_MONO_OTHER: why = "is monochrome but has no unpacker in scicap"; break;
    default: why = "is unknown to scicap"; break;
    }
    return sci_error_set(err, -ENOTSUP, "%s: format %s %s; measurements need one of " PIXFMT_ACCEPTED,
                         device ? device : "camera", pixfmt_fourcc_str(fourcc, s), why);
}

size_t pixfmt_min_stride(enum pixfmt f, uint32_t width)
{
    switch (f) {
    case PIXFMT_GREY: return width;
    case PIXFMT_Y10:
    case PIXFMT_Y12:
    case PIXFMT_Y16: return (size_t)width * 2;
    case PIXFMT_Y10P: return ((size_t)width + 3) / 4 * 5;
    default: return 0;
    }
}

static int check_geometry(enum pixfmt f, size_t len, size_t stride, uint32_t w, uint32_t h, sci_error *err)
{
    size_t min = pixfmt_min_stride(f, w);
    if (min == 0 || w == 0 || h == 0)
        return sci_error_set(err, -EINVAL, "pixel data: format %s, size %ux%u is not valid", pixfmt_name(f), w, h);
    if (stride < min)
        return sci_error_set(err, SCI_ESHAPE, "pixel data: stride %zu bytes is below the %zu that %u pixels of %s need",
                             stride, min, w, pixfmt_name(f));
    size_t need = stride * (size_t)(h - 1) + min;
    if (len < need)
        return sci_error_set(err, SCI_ESHAPE, "pixel data: buffer of %zu bytes is short of the %zu that %ux%u %s "
                             "with stride %zu need", len, need, w, h, pixfmt_name(f), stride);
    return 0;
}

/* Little-endian 16-bit containers. On little-endian hosts a plain 16-bit load (through memcpy, so alignment does
 * not matter) vectorises; assembling bytes does not, and costs 10x on a 1920x1080 frame (bench_camera). */
static void unpack_le16(const uint8_t *s, uint32_t w, uint16_t mask, uint16_t *d)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    for (uint32_t x = 0; x < w; x++) {
        uint16_t v;
        memcpy(&v, s + 2 * (size_t)x, 2);
        d[x] = v & mask;
    }
#else
    for (uint32_t x = 0; x < w; x++)
        d[x] = (uint16_t)((s[2 * x] | (s[2 * x + 1] << 8)) & mask);
#endif
}

static void unpack_y10p_row(const uint8_t *s, uint32_t w, uint16_t *d)
{
    uint32_t full = w / 4;
    for (uint32_t g = 0; g < full; g++) {
        const uint8_t *b = s + 5 * (size_t)g;
        uint8_t lo = b[4];
        d[4 * g + 0] = (uint16_t)((b[0] << 2) | (lo & 3));
        d[4 * g + 1] = (uint16_t)((b[1] << 2) | ((lo >> 2) & 3));
        d[4 * g + 2] = (uint16_t)((b[2] << 2) | ((lo >> 4) & 3));
        d[4 * g + 3] = (uint16_t)((b[3] << 2) | ((lo >> 6) & 3));
    }
    if (w % 4) { /* a partial last group still occupies 5 bytes */
        const uint8_t *b = s + 5 * (size_t)full;
        for (uint32_t j = 0; j < w % 4; j++)
            d[4 * full + j] = (uint16_t)((b[j] << 2) | ((b[4] >> (2 * j)) & 3));
    }
}

int pixfmt_unpack(enum pixfmt f, const uint8_t *src, size_t len, size_t stride, uint32_t w, uint32_t h,
                  uint16_t *dst, sci_error *err)
{
    int rc = check_geometry(f, len, stride, w, h, err);
    if (rc < 0)
        return rc;
    for (uint32_t y = 0; y < h; y++) {
        const uint8_t *s = src + (size_t)y * stride;
        uint16_t *d = dst + (size_t)y * w;
        switch (f) {
        case PIXFMT_GREY:
            for (uint32_t x = 0; x < w; x++)
                d[x] = s[x];
            break;
        case PIXFMT_Y10: unpack_le16(s, w, 0x03ff, d); break;
        case PIXFMT_Y12: unpack_le16(s, w, 0x0fff, d); break;
        case PIXFMT_Y16:
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
            memcpy(d, s, (size_t)w * 2); /* already the host's layout */
#else
            unpack_le16(s, w, 0xffff, d);
#endif
            break;
        case PIXFMT_Y10P: unpack_y10p_row(s, w, d); break;
        default: break; /* excluded by check_geometry */
        }
    }
    return 0;
}

int pixfmt_pack(enum pixfmt f, const uint16_t *src, uint32_t w, uint32_t h, uint8_t *dst, size_t len, size_t stride,
                sci_error *err)
{
    int rc = check_geometry(f, len, stride, w, h, err);
    if (rc < 0)
        return rc;
    uint16_t mask = (uint16_t)((1u << pixfmt_info_get(f)->bits_per_sample) - 1u);
    for (uint32_t y = 0; y < h; y++) {
        const uint16_t *s = src + (size_t)y * w;
        uint8_t *d = dst + (size_t)y * stride;
        size_t row = (y + 1 < h) ? stride : pixfmt_min_stride(f, w);
        memset(d, 0, row);
        switch (f) {
        case PIXFMT_GREY:
            for (uint32_t x = 0; x < w; x++)
                d[x] = (uint8_t)(s[x] & mask);
            break;
        case PIXFMT_Y10:
        case PIXFMT_Y12:
        case PIXFMT_Y16:
            for (uint32_t x = 0; x < w; x++) {
                uint16_t v = s[x] & mask;
                d[2 * x] = (uint8_t)(v & 0xff);
                d[2 * x + 1] = (uint8_t)(v >> 8);
            }
            break;
        case PIXFMT_Y10P:
            for (uint32_t x = 0; x < w; x++) {
                uint16_t v = s[x] & mask;
                uint8_t *b = d + 5 * (size_t)(x / 4);
                b[x % 4] = (uint8_t)(v >> 2);
                b[4] |= (uint8_t)((v & 3) << (2 * (x % 4)));
            }
            break;
        default: break;
        }
    }
    return 0;
}
