#include "drivers/pixfmt.h"

#include <errno.h>
#include <linux/videodev2.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#define MONO(id_, name_, fcc, bits, lay) [id_] = {.id = id_, .name = name_, .fourcc = fcc, .bits_per_sample = bits, \
                                              .cfa = PIXFMT_CFA_NONE, .layout = PIXFMT_LAYOUT_##lay}
#define BAYER(cfa_, bits, lay, suffix)                                                                               \
    [PIXFMT_S##cfa_##suffix] = {.id = PIXFMT_S##cfa_##suffix, .name = "S" #cfa_ #suffix,                           \
                                .fourcc = V4L2_PIX_FMT_S##cfa_##suffix, .bits_per_sample = bits,                   \
                                .cfa = PIXFMT_CFA_##cfa_, .layout = PIXFMT_LAYOUT_##lay}
#define BAYER4(bits, lay, suffix) BAYER(RGGB, bits, lay, suffix), BAYER(GRBG, bits, lay, suffix), \
                                  BAYER(GBRG, bits, lay, suffix), BAYER(BGGR, bits, lay, suffix)

static const pixfmt_info pixfmt_table[PIXFMT_COUNT] = {
    MONO(PIXFMT_GREY, "GREY", V4L2_PIX_FMT_GREY, 8, U8),
    MONO(PIXFMT_Y10, "Y10", V4L2_PIX_FMT_Y10, 10, LE16),
    MONO(PIXFMT_Y12, "Y12", V4L2_PIX_FMT_Y12, 12, LE16),
    MONO(PIXFMT_Y16, "Y16", V4L2_PIX_FMT_Y16, 16, LE16),
    MONO(PIXFMT_Y10P, "Y10P", V4L2_PIX_FMT_Y10P, 10, RAW10P),
    BAYER4(8, U8, 8),
    BAYER4(10, LE16, 10),
    BAYER4(12, LE16, 12),
    BAYER4(16, LE16, 16),
    BAYER4(10, RAW10P, 10P),
};

#define PIXFMT_ACCEPTED "GREY, Y10, Y12, Y16, Y10P or Bayer S{RGGB,GRBG,GBRG,BGGR}{8,10,12,16,10P}"

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

const char *pixfmt_cfa_name(enum pixfmt_cfa cfa)
{
    switch (cfa) {
    case PIXFMT_CFA_RGGB: return "RGGB";
    case PIXFMT_CFA_GRBG: return "GRBG";
    case PIXFMT_CFA_GBRG: return "GBRG";
    case PIXFMT_CFA_BGGR: return "BGGR";
    default: return "none";
    }
}

enum pixfmt pixfmt_with_cfa(enum pixfmt f, enum pixfmt_cfa cfa)
{
    const pixfmt_info *in = pixfmt_info_get(f);
    if (!in || (int)cfa < PIXFMT_CFA_NONE || cfa > PIXFMT_CFA_BGGR)
        return PIXFMT_NONE;
    for (int g = PIXFMT_NONE + 1; g < PIXFMT_COUNT; g++)
        if (pixfmt_table[g].layout == in->layout && pixfmt_table[g].bits_per_sample == in->bits_per_sample &&
            pixfmt_table[g].cfa == cfa)
            return (enum pixfmt)g;
    return PIXFMT_NONE;
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
        /* Bayer layouts without an unpacker here (12-bit packed, 14-bit, compressed A-law/DPCM) */
        V4L2_PIX_FMT_SBGGR12P, V4L2_PIX_FMT_SGBRG12P, V4L2_PIX_FMT_SGRBG12P, V4L2_PIX_FMT_SRGGB12P,
        V4L2_PIX_FMT_SBGGR14, V4L2_PIX_FMT_SGBRG14, V4L2_PIX_FMT_SGRBG14, V4L2_PIX_FMT_SRGGB14,
        V4L2_PIX_FMT_SBGGR10ALAW8, V4L2_PIX_FMT_SGBRG10ALAW8, V4L2_PIX_FMT_SGRBG10ALAW8, V4L2_PIX_FMT_SRGGB10ALAW8,
        V4L2_PIX_FMT_SBGGR10DPCM8, V4L2_PIX_FMT_SGBRG10DPCM8, V4L2_PIX_FMT_SGRBG10DPCM8, V4L2_PIX_FMT_SRGGB10DPCM8,
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
    case PIXFMT_KIND_COLOUR: why = "is a colour format (YUV/RGB, or a Bayer layout without an unpacker), not raw counts"; break;
    case PIXFMT_KIND_MONO_OTHER: why = "is monochrome but has no unpacker in scicap"; break;
    default: why = "is unknown to scicap"; break;
    }
    return sci_error_set(err, -ENOTSUP, "%s: format %s %s; measurements need one of " PIXFMT_ACCEPTED,
                         device ? device : "camera", pixfmt_fourcc_str(fourcc, s), why);
}

size_t pixfmt_min_stride(enum pixfmt f, uint32_t width)
{
    const pixfmt_info *in = pixfmt_info_get(f);
    switch (in ? in->layout : 0) {
    case PIXFMT_LAYOUT_U8: return width;
    case PIXFMT_LAYOUT_LE16: return (size_t)width * 2;
    case PIXFMT_LAYOUT_RAW10P: return ((size_t)width + 3) / 4 * 5;
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
    const pixfmt_info *in = pixfmt_info_get(f); /* not NULL: check_geometry passed */
    uint16_t mask = (uint16_t)((1u << in->bits_per_sample) - 1u);
    for (uint32_t y = 0; y < h; y++) {
        const uint8_t *s = src + (size_t)y * stride;
        uint16_t *d = dst + (size_t)y * w;
        switch (in->layout) {
        case PIXFMT_LAYOUT_U8:
            for (uint32_t x = 0; x < w; x++)
                d[x] = s[x];
            break;
        case PIXFMT_LAYOUT_LE16:
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
            if (mask == 0xffff) {
                memcpy(d, s, (size_t)w * 2); /* already the host's layout */
                break;
            }
#endif
            unpack_le16(s, w, mask, d);
            break;
        case PIXFMT_LAYOUT_RAW10P: unpack_y10p_row(s, w, d); break;
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
    const pixfmt_info *in = pixfmt_info_get(f);
    uint16_t mask = (uint16_t)((1u << in->bits_per_sample) - 1u);
    for (uint32_t y = 0; y < h; y++) {
        const uint16_t *s = src + (size_t)y * w;
        uint8_t *d = dst + (size_t)y * stride;
        size_t row = (y + 1 < h) ? stride : pixfmt_min_stride(f, w);
        memset(d, 0, row);
        switch (in->layout) {
        case PIXFMT_LAYOUT_U8:
            for (uint32_t x = 0; x < w; x++)
                d[x] = (uint8_t)(s[x] & mask);
            break;
        case PIXFMT_LAYOUT_LE16:
            for (uint32_t x = 0; x < w; x++) {
                uint16_t v = s[x] & mask;
                d[2 * x] = (uint8_t)(v & 0xff);
                d[2 * x + 1] = (uint8_t)(v >> 8);
            }
            break;
        case PIXFMT_LAYOUT_RAW10P:
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
