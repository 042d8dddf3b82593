/* io/gif.h — animated grey GIF previews with one fixed 256-level grey palette, encoded by giflib.
 *
 * Why not OpenImageIO's GIF writer: it builds a fresh palette for every frame (a k-d tree over the frame's
 * colours, then a search per pixel), ≈ 57 ms for 8 frames of 256×256, and is lossy — for frames that are grey,
 * whose 256 levels fit GIF's 256 palette entries exactly. With the grey palette every 8-bit value is stored as
 * itself (the preview is lossless) and encoding is giflib's LZW alone.
 *
 * Format: GIF89a, one global colour table (entry v = (v, v, v)), a NETSCAPE2.0 loop-forever extension, and per
 * frame a graphic control extension (delay in 1/100 s, no transparency, disposal "do not dispose") and a full-size
 * image (tests/unit/test_gif.c decodes it with OpenImageIO's reader).
 */
#ifndef SCICAP_IO_GIF_H
#define SCICAP_IO_GIF_H

#include <stddef.h>

#include "base/error.h"

/* Encode n frames of w×h 8-bit grey values (frame-major, row-major) as an animated GIF into a malloc'd buffer
 * (*out, *len; the caller frees *out). delay_ms per frame, rounded to GIF's 10 ms units (at least 10 ms).
 * 1 <= w, h <= 65535, n >= 1, else -EINVAL; -ENOMEM. */
int sci_gif_encode_grey(const unsigned char *frames, int w, int h, int n, int delay_ms, unsigned char **out,
                        size_t *len, sci_error *err);

/* sci_gif_encode_grey, then written to `path` (not atomic: io/image.c writes a temporary and renames). -errno
 * naming the file on an I/O error. */
int sci_gif_write_grey(const char *path, const unsigned char *frames, int w, int h, int n, int delay_ms,
                       sci_error *err);

#endif
