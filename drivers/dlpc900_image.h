/* drivers/dlpc900_image.h — DLPC900 pattern images: 24 one-bit masks packed per 24-bit image, the 48-byte
 * image header, and whole image files (header + ERLE or uncompressed data) as sent by 0x1A2A/0x1A2B.
 *
 * Packed image: w*h uint32 values, row-major, top row first; bit k (0 … 23) of a pixel is mask k of that image.
 * On the wire each pixel is three bytes, bits 23–16, 15–8, 7–0 (TI DLPU018, image memory format). Mask j of a
 * 1-bit sequence lives in image j / 24 at bit j % 24.
 *
 *     uint32_t *px = malloc(w*h*4);
 *     dlpc900_image_pack_cube(masks, 0, 24, px, &err);      // masks 0..23 → one image
 *     uint8_t *file; size_t len;
 *     dlpc900_image_encode(px, w, h, &file, &len, &err);    // "Spld" header + ERLE (or raw when smaller)
 *     ... send with image init (size = len) and 504-byte chunks ...
 *     free(file);
 *
 * Pure computation: no I/O, reentrant. Encoding and decoding allocate only what they return.
 */
#ifndef SCICAP_DRIVERS_DLPC900_IMAGE_H
#define SCICAP_DRIVERS_DLPC900_IMAGE_H

#include <stddef.h>
#include <stdint.h>

#include "base/cube.h"
#include "base/error.h"

#define DLPC900_IMAGE_HEADER_SIZE 48
#define DLPC900_MASKS_PER_IMAGE 24
/* Decoder guard: no DLPC900 DMD is larger (DLP9000 is 2560×1600); bounds allocation on hostile input. */
#define DLPC900_IMAGE_DIM_MAX 4096

enum dlpc900_compression { DLPC900_COMP_NONE = 0, DLPC900_COMP_RLE = 1, DLPC900_COMP_ERLE = 2 };

typedef struct dlpc900_image_header {
    uint16_t width, height;  /* pixels (half the DMD width per controller on the DLP9000) */
    uint32_t byte_count;     /* data bytes excluding the header (TI); pycrafter writes the total length */
    uint8_t pixel_format;    /* 1 = 24-bit packed (TI); 0 tolerated (pycrafter) */
    uint8_t compression;     /* enum dlpc900_compression */
    uint8_t is_left;         /* 1 (TI); 0 tolerated */
} dlpc900_image_header;

/* Write the canonical TI header (signature "Spld", offsets 0xFFFFFFFF, byte order 1, isLeftImage 1). */
void dlpc900_image_header_write(uint8_t out[DLPC900_IMAGE_HEADER_SIZE], const dlpc900_image_header *h);
/* Parse and check a header: signature, 1 ≤ w,h ≤ DLPC900_IMAGE_DIM_MAX, compression ∈ {0,1,2} (else
 * SCI_EFORMAT naming device error 9), pixel format ∈ {0,1}. */
int dlpc900_image_header_read(const uint8_t *buf, size_t len, dlpc900_image_header *h, sci_error *err);

/* Pack masks first … first+count-1 of `masks` (w×h×n, value ≥ 0.5 = mirror on) into bits 0 … count-1 of `px`
 * (w*h values, other bits cleared). count ≤ 24. SCI_ENONFINITE for NaN/Inf (naming mask and pixel), -EINVAL for a
 * bad range. */
int dlpc900_image_pack_cube(const sci_cube *masks, int first, int count, uint32_t *px, sci_error *err);
/* Same from one byte per pixel (0 = off, else on), masks stored frame after frame (w*h bytes each). */
void dlpc900_image_pack_bytes(const uint8_t *masks, int w, int h, int count, uint32_t *px);
/* Extract bit `bit` of every pixel as 0/1 bytes into out (w*h). */
void dlpc900_image_unpack_bit(const uint32_t *px, int w, int h, int bit, uint8_t *out);

/* Header + data for `px`: ERLE, or uncompressed when ERLE would be larger (TI's GUI does the same).
 * *out is malloc'ed, the caller frees it; *len = 48 + data bytes = the size for image load init.
 * -EINVAL for sizes outside 1 … DLPC900_IMAGE_DIM_MAX, -ENOMEM. *compression (may be NULL) receives the choice. */
int dlpc900_image_encode(const uint32_t *px, int w, int h, uint8_t **out, size_t *len, int *compression,
                         sci_error *err);

typedef struct dlpc900_image_info {
    dlpc900_image_header header;
    int warnings;        /* tolerated oddities: mid-row end-of-line, header variant, missing end of image */
    size_t data_used;    /* data bytes consumed up to and including end of image */
} dlpc900_image_info;

/* Decode an image file of `len` bytes (exactly what image load init declared). Accepts compression 0, 1, 2 and
 * every ERLE variant of reference §10, and both header byte-count conventions (§9). On success *px is a malloc'ed
 * w*h array the caller frees. Errors: SCI_EFORMAT with the offset and reason; nothing allocated on error. */
int dlpc900_image_decode(const uint8_t *buf, size_t len, uint32_t **px, dlpc900_image_info *info, sci_error *err);

#endif
