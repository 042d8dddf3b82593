/* io/oiio_shim.h — the extern "C" face of OpenImageIO (C++), used only by io/image.c.
 *
 * Every function catches all C++ exceptions; none reaches C. Errors: a negative code (-EIO for I/O failures,
 * -ENOMEM, SCI_EFORMAT for unreadable or unsupported files) and a message in errbuf naming the file.
 */
#ifndef SCICAP_IO_OIIO_SHIM_H
#define SCICAP_IO_OIIO_SHIM_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Read every subimage (TIFF page) of `path` as grey float values as stored (no normalisation: 8-bit 0..255,
 * 16-bit 0..65535). *data is malloc'd, frame-major w×h×nframes; the caller frees it. Colour is converted to
 * Rec. 709 luminance. *bits: stored bits per sample. */
int sci_oiio_read(const char *path, float **data, int *w, int *h, int *nframes, int *bits, char *errbuf,
                  size_t errlen);

/* The size of the first subimage of `path`, from its header alone (no pixels read, nothing allocated for them). */
int sci_oiio_probe(const char *path, int *w, int *h, char *errbuf, size_t errlen);

/* Write one w×h image of `channels` interleaved samples per pixel (1 grey, 3 RGB; others -EINVAL). `pixel_type`
 * 0 = uint8, 1 = uint16, 2 = half, 3 = float; values must already be in the type's range (integer types: rounded
 * by the caller). Lossless compression at its cheapest level (deflate level 1: EXR "zip:1", TIFF zip quality 1,
 * PNG level 1): ~3 times less CPU than the libraries' defaults for 5-15 % more bytes on our frames (measured on
 * 256×256 frames); uncompressed = 1 stores the pixels without compression (EXR and TIFF; PNG is always deflated).
 * description may be NULL. Not atomic: io/image.c writes to a temporary name and renames. */
int sci_oiio_write(const char *path, const float *data, int w, int h, int channels, int pixel_type,
                   const char *description, int uncompressed, char *errbuf, size_t errlen);

/* OpenEXR's process-wide compression pool: threads > 0 sets its size, 0 lets it use every core, -1 turns it off
 * (each file compressed on the thread that writes it). Affects every EXR read and write in the process. */
void sci_oiio_exr_threads(int threads);

#ifdef __cplusplus
}
#endif

#endif
