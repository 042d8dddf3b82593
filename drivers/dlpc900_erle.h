/* drivers/dlpc900_erle.h — the DLPC900 image codecs: enhanced RLE (ERLE, compression 2), plain RLE
 * (compression 1) and uncompressed rows (compression 0). Grammar: TI DLPU018, the ERLE compression pages.
 *
 * Pixels are packed 24-bit values (see dlpc900_image.h), w*h of them, top row first.
 *
 * Encoder (one canonical form, TI-like): per row, a copy-from-previous-line when that run is at least as long
 * as the repeat run, else a repeat run (a lone pixel is a run of 1), else a literal run up to the next place
 * worth a run; counts split at 32767; no end-of-line markers; ends with end of image (00 01 00); no padding.
 * Cost: one pass, O(w*h), no allocation.
 *
 * Decoders accept what public encoders produce: 1- or 2-byte counts anywhere, optional end-of-line (no-op at
 * column 0, mid-row skips to the next row leaving zeros and counts a warning), trailing padding after end of
 * image, and no end of image when every row is filled (a warning). They reject runs crossing a row end, copies
 * on row 0, rows beyond the height, zero counts, data running past the buffer, and images that end before all
 * rows are filled. Errors are SCI_EFORMAT with the byte offset. Reentrant.
 */
#ifndef SCICAP_DRIVERS_DLPC900_ERLE_H
#define SCICAP_DRIVERS_DLPC900_ERLE_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

#define DLPC900_ERLE_COUNT_MAX 32767

/* Worst-case ERLE size for w×h (every pixel a run of 1: 4 bytes, plus the end of image). */
size_t dlpc900_erle_bound(int w, int h);
/* Uncompressed size: rows of 3*w bytes padded to 16. */
size_t dlpc900_raw_size(int w, int h);

/* Encode into out (cap bytes, at least dlpc900_erle_bound). Returns the byte count, or -ENOSPC. */
long dlpc900_erle_encode(const uint32_t *px, int w, int h, uint8_t *out, size_t cap);
/* Uncompressed rows into out (cap ≥ dlpc900_raw_size). Returns the byte count, or -ENOSPC. */
long dlpc900_raw_encode(const uint32_t *px, int w, int h, uint8_t *out, size_t cap);

/* Decode n data bytes into px (w*h, zero-filled first). *used receives the bytes consumed through end of image,
 * *warnings (both may be NULL) the count of tolerated oddities. */
int dlpc900_erle_decode(const uint8_t *d, size_t n, int w, int h, uint32_t *px, size_t *used, int *warnings,
                        sci_error *err);
int dlpc900_rle_decode(const uint8_t *d, size_t n, int w, int h, uint32_t *px, size_t *used, int *warnings,
                       sci_error *err);
int dlpc900_raw_decode(const uint8_t *d, size_t n, int w, int h, uint32_t *px, sci_error *err);

#endif
