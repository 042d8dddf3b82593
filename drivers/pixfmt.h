/* drivers/pixfmt.h — the raw pixel formats scicap measures with (monochrome and Bayer), and their bit-exact
 * unpacking.
 *
 * A camera delivers rows of bytes in one of a few raw layouts; everything after the camera sees 16-bit samples
 * (uint16, one per pixel, row-major, no padding) holding the sensor's counts *unscaled*: a 10-bit sensor gives
 * 0..1023, never 0..65535. The bit depth travels beside the samples (camera_frame.bits_per_sample) so that
 * nothing downstream has to guess.
 *
 *   GREY  8 bits per pixel, one byte.
 *   Y10   10 bits in a little-endian 16-bit container, upper 6 bits zero.
 *   Y12   12 bits in a little-endian 16-bit container, upper 4 bits zero.
 *   Y16   16 bits little-endian (the sensor's precision may be lower).
 *   Y10P  MIPI RAW10: 4 pixels in 5 bytes; bytes 0..3 hold bits 9:2 of pixels 0..3, byte 4 holds the low two
 *         bits, pixel j at bits 2j+1:2j. A row of w pixels takes ceil(w/4)*5 bytes at least.
 *
 * Bayer (raw colour-filter-array) formats have exactly the layouts above, one sample per photosite; only the
 * colour filter in front of each pixel differs, and it travels as pixfmt_info.cfa (the colours of the 2x2 tile
 * at the top-left corner, read row by row: RGGB = R at (0,0), G at (1,0) and (0,1), B at (1,1)). Unpacking
 * keeps the mosaic: a Bayer frame stays one sample per pixel, never demosaiced here.
 *   SRGGB8  SGRBG8  SGBRG8  SBGGR8    8 bits, as GREY
 *   SRGGB10 SGRBG10 SGBRG10 SBGGR10   as Y10 (16-bit little-endian container, 10 significant bits)
 *   SRGGB12 SGRBG12 SGBRG12 SBGGR12   as Y12
 *   SRGGB16 SGRBG16 SGBRG16 SBGGR16   as Y16
 *   SRGGB10P SGRBG10P SGBRG10P SBGGR10P  as Y10P (MIPI RAW10)
 * The names are V4L2's (V4L2_PIX_FMT_SRGGB8 ...); GenICam's BayerRG8/BayerRG16 ... map onto them
 * (drivers/camera_aravis.c).
 *
 * Colour formats that are not raw sensor counts (YUV, RGB) and compressed ones (MJPEG, H.264) are refused: their
 * values are not the sensor counts a reconstruction needs. pixfmt_check_fourcc() says which kind a refused code
 * is.
 *
 * Rows may be padded by the driver: every function takes the source stride (V4L2 bytesperline) separately.
 * For Y10 and Y12 the unused upper bits are masked off, so a sample never exceeds 2^bits - 1.
 *
 * All functions are pure, allocation-free and thread-safe.
 *
 *     size_t stride = fmt.bytesperline;        // from the driver, >= pixfmt_min_stride(PIXFMT_Y10P, w)
 *     if (pixfmt_unpack(PIXFMT_Y10P, buf, bytesused, stride, w, h, samples, &err) < 0) ...
 */
#ifndef SCICAP_DRIVERS_PIXFMT_H
#define SCICAP_DRIVERS_PIXFMT_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

enum pixfmt {
    PIXFMT_NONE = 0,
    PIXFMT_GREY,
    PIXFMT_Y10,
    PIXFMT_Y12,
    PIXFMT_Y16,
    PIXFMT_Y10P,
    /* Bayer: same layouts as the monochrome formats above, with a colour filter array */
    PIXFMT_SRGGB8,
    PIXFMT_SGRBG8,
    PIXFMT_SGBRG8,
    PIXFMT_SBGGR8,
    PIXFMT_SRGGB10,
    PIXFMT_SGRBG10,
    PIXFMT_SGBRG10,
    PIXFMT_SBGGR10,
    PIXFMT_SRGGB12,
    PIXFMT_SGRBG12,
    PIXFMT_SGBRG12,
    PIXFMT_SBGGR12,
    PIXFMT_SRGGB16,
    PIXFMT_SGRBG16,
    PIXFMT_SGBRG16,
    PIXFMT_SBGGR16,
    PIXFMT_SRGGB10P,
    PIXFMT_SGRBG10P,
    PIXFMT_SGBRG10P,
    PIXFMT_SBGGR10P,
    PIXFMT_COUNT
};

/* The colour filter array of a format: the colours of the top-left 2x2 tile, row by row. */
enum pixfmt_cfa {
    PIXFMT_CFA_NONE = 0, /* monochrome */
    PIXFMT_CFA_RGGB,
    PIXFMT_CFA_GRBG,
    PIXFMT_CFA_GBRG,
    PIXFMT_CFA_BGGR
};

/* How samples sit in a row (the same for a monochrome format and its Bayer twins). */
enum pixfmt_layout {
    PIXFMT_LAYOUT_U8 = 1, /* one byte per sample */
    PIXFMT_LAYOUT_LE16,   /* little-endian 16-bit container, upper bits above bits_per_sample masked off */
    PIXFMT_LAYOUT_RAW10P  /* MIPI RAW10: 4 samples in 5 bytes */
};

typedef struct pixfmt_info {
    enum pixfmt id;
    const char *name;     /* "GREY", "Y10", ..., "SRGGB12": the names used in config files */
    uint32_t fourcc;      /* V4L2_PIX_FMT_* */
    int bits_per_sample;  /* significant bits in each unpacked sample: 8, 10, 12, 16 */
    enum pixfmt_cfa cfa;  /* PIXFMT_CFA_NONE for monochrome */
    enum pixfmt_layout layout;
} pixfmt_info;

/* Kind of a V4L2 pixel format code, for messages when a format is refused. */
enum pixfmt_kind {
    PIXFMT_KIND_MONO = 0,   /* one of ours: raw monochrome or raw Bayer counts (see pixfmt_info.cfa) */
    PIXFMT_KIND_MONO_OTHER, /* monochrome but not supported (Y14, Y16_BE, Y10BPACK, ...) */
    PIXFMT_KIND_COLOUR,     /* YUV, RGB (and Bayer layouts without an unpacker): refused for measurements */
    PIXFMT_KIND_COMPRESSED, /* MJPEG, JPEG, H.264, ...: refused for measurements */
    PIXFMT_KIND_UNKNOWN
};

/* Static description of `f`; NULL for PIXFMT_NONE or out-of-range values. */
const pixfmt_info *pixfmt_info_get(enum pixfmt f);
/* Name of `f` ("Y10P"), "none" for PIXFMT_NONE or unknown values. Never NULL. */
const char *pixfmt_name(enum pixfmt f);
/* "RGGB", "GRBG", "GBRG", "BGGR", or "none" for PIXFMT_CFA_NONE and unknown values. Never NULL. */
const char *pixfmt_cfa_name(enum pixfmt_cfa cfa);
/* The format with `layout`-compatible samples of `bits` and colour filter `cfa`: the Bayer twin of a monochrome
 * format (pixfmt_with_cfa(PIXFMT_Y12, PIXFMT_CFA_RGGB) == PIXFMT_SRGGB12) or the reverse with PIXFMT_CFA_NONE.
 * PIXFMT_NONE when there is none. */
enum pixfmt pixfmt_with_cfa(enum pixfmt f, enum pixfmt_cfa cfa);
/* Parse a config name (case-insensitive). -EINVAL naming the value and listing the accepted names. */
int pixfmt_from_name(const char *name, enum pixfmt *out, sci_error *err);
/* Map a V4L2 fourcc to ours; PIXFMT_NONE if it is not one we measure with. */
enum pixfmt pixfmt_from_fourcc(uint32_t fourcc);
/* Classify a V4L2 fourcc; `compressed_flag` is V4L2_FMT_FLAG_COMPRESSED from ENUM_FMT (1 forces COMPRESSED). */
enum pixfmt_kind pixfmt_classify_fourcc(uint32_t fourcc, int compressed_flag);
/* 0 if `fourcc` is measurable; otherwise -ENOTSUP with a message naming `device`, the code and why it is
 * refused ("/dev/video0: format MJPG is compressed (...); measurements need one of GREY, Y10, ..."). */
int pixfmt_check_fourcc(uint32_t fourcc, int compressed_flag, const char *device, sci_error *err);
/* Printable fourcc ("Y10P", "Y10 "); non-printable bytes become '.'. Writes 5 bytes into buf; returns buf. */
char *pixfmt_fourcc_str(uint32_t fourcc, char buf[5]);

/* Smallest row stride in bytes for `width` pixels of format `f`, 0 for an unknown format. */
size_t pixfmt_min_stride(enum pixfmt f, uint32_t width);

/* Unpack h rows of w pixels from `src` (len bytes, rows `stride` bytes apart) into `dst` (w*h samples).
 * Errors (nothing written): -EINVAL for an unknown format or zero size, SCI_ESHAPE when stride is below
 * pixfmt_min_stride or `len` is shorter than stride*(h-1) + min_stride; the message gives the numbers. */
int pixfmt_unpack(enum pixfmt f, const uint8_t *src, size_t len, size_t stride, uint32_t w, uint32_t h,
                  uint16_t *dst, sci_error *err);

/* The inverse, for simulated cameras and tests: pack w*h samples into rows `stride` bytes apart (padding bytes
 * are set to 0). Samples are masked to the format's bit depth. Same errors as pixfmt_unpack. */
int pixfmt_pack(enum pixfmt f, const uint16_t *src, uint32_t w, uint32_t h, uint8_t *dst, size_t len, size_t stride,
                sci_error *err);

#endif
