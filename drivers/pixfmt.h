/* drivers/pixfmt.h — the monochrome pixel formats scicap measures with, and their bit-exact unpacking.
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
 * Colour (YUV, RGB, Bayer) and compressed (MJPEG, H.264) formats are refused: their values are not the sensor
 * counts a reconstruction needs. pixfmt_check_fourcc() says which kind a refused code is.
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
    PIXFMT_COUNT
};

typedef struct pixfmt_info {
    enum pixfmt id;
    const char *name;     /* "GREY", "Y10", "Y12", "Y16", "Y10P": the names used in config files */
    uint32_t fourcc;      /* V4L2_PIX_FMT_* */
    int bits_per_sample;  /* significant bits in each unpacked sample: 8, 10, 12, 16 */
} pixfmt_info;

/* Kind of a V4L2 pixel format code, for messages when a format is refused. */
enum pixfmt_kind {
    PIXFMT_KIND_MONO = 0,   /* one of ours */
    PIXFMT_KIND_MONO_OTHER, /* monochrome but not supported (Y14, Y16_BE, Y10BPACK, ...) */
    PIXFMT_KIND_COLOUR,     /* YUV, RGB, Bayer: refused for measurements */
    PIXFMT_KIND_COMPRESSED, /* MJPEG, JPEG, H.264, ...: refused for measurements */
    PIXFMT_KIND_UNKNOWN
};

/* Static description of `f`; NULL for PIXFMT_NONE or out-of-range values. */
const pixfmt_info *pixfmt_info_get(enum pixfmt f);
/* Name of `f` ("Y10P"), "none" for PIXFMT_NONE or unknown values. Never NULL. */
const char *pixfmt_name(enum pixfmt f);
/* Parse a config name (case-insensitive). -EINVAL naming the value and listing the accepted names. */
int pixfmt_from_name(const char *name, enum pixfmt *out, sci_error *err);
/* Map a V4L2 fourcc to ours; PIXFMT_NONE if it is not one we measure with. */
enum pixfmt pixfmt_from_fourcc(uint32_t fourcc);
/* Classify a V4L2 fourcc; `compressed_flag` is V4L2_FMT_FLAG_COMPRESSED from ENUM_FMT (1 forces COMPRESSED). */
enum pixfmt_kind pixfmt_classify_fourcc(uint32_t fourcc, int compressed_flag);
/* 0 if `fourcc` is measurable; otherwise -ENOTSUP with a message naming `device`, the code and why it is
 * refused ("/dev/video0: format MJPG is compressed; measurements need raw monochrome: GREY, Y10, Y12, Y16, Y10P"). */
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
