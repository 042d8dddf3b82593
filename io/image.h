/* io/image.h — image files and image stacks through OpenImageIO.
 *
 * OpenImageIO has no C API; io/oiio_shim.cpp wraps the few calls we need in extern "C" functions that catch
 * every C++ exception, so none ever reaches C. This header is the C face of it.
 *
 * Single images hold one frame of a cube. A *stack* is N frames in one folder — <stem>_000.<ext>,
 * <stem>_001.<ext>, ... — plus a JSON sidecar <stem>.json that records the shape, the pixel type, the scale
 * applied before storing, and free-form provenance:
 *     {"format": "scicap-stack", "version": 1, "w": 256, "h": 256, "n": 8, "type": "f32", "scale": 1.0,
 *      "files": ["mask_000.exr", ...], "provenance": {...}}
 * Stored value = cube value × scale (integer types rounded and clamped); reading divides by scale again, so a
 * float stack round-trips bit for bit and a 16-bit stack round-trips to within half a count.
 *
 * Pixel types by use (docs/formats.md; docs/architecture.md, Contracts: Storage writes): raw snapshots 16-bit
 * TIFF (counts, never rescaled), reconstructions float EXR, previews 8- or 16-bit PNG.
 *
 * Writes are atomic per file: written to "<path>.tmp-<pid>" and renamed, so a reader never sees half a file.
 * Errors: -errno for I/O, SCI_EFORMAT for files OpenImageIO cannot read or that have the wrong channel count;
 * the message names the file. Thread-safe (each call opens its own file handles).
 */
#ifndef SCICAP_IO_IMAGE_H
#define SCICAP_IO_IMAGE_H

#include <jansson.h>

#include "base/cube.h"
#include "base/error.h"
#include "io/limits.h"

typedef enum sci_pixel_type {
    SCI_PIXEL_U8,   /* 8-bit unsigned */
    SCI_PIXEL_U16,  /* 16-bit unsigned */
    SCI_PIXEL_HALF, /* 16-bit float (EXR) */
    SCI_PIXEL_F32,  /* 32-bit float */
} sci_pixel_type;

/* Name used in sidecars ("u8", "u16", "half", "f32"); NULL for an invalid type. */
const char *sci_pixel_type_name(sci_pixel_type t);

/* Read one image file as a 1-frame cube of its stored values (8-bit 0..255, 16-bit 0..65535, float as is).
 * Colour images are converted to luminance (Rec. 709 weights). *bits (may be NULL) receives the stored bit
 * depth (8, 16, 32; 16 for half). A multi-page TIFF gives one frame per page. */
int sci_image_read(const char *path, sci_cube **out, int *bits, sci_error *err);

/* Write frame `k` of `c` as a 1-channel image; the format follows the extension (.tif/.tiff, .exr, .png, ...).
 * Stored value = value × scale, rounded and clamped to the type's range for integer types. `description` (may be
 * NULL) goes into the file's ImageDescription (TIFF) or a string attribute (EXR). Atomic (see above). */
int sci_image_write(const char *path, const sci_cube *c, int k, sci_pixel_type type, double scale,
                    const char *description, sci_error *err);

/* Write frames 3f, 3f + 1, 3f + 2 of `rgb` (an RGB cube, recon/bayer.h) as one 3-channel image: colour EXR
 * (float) or PNG/TIFF (8/16-bit, value × scale rounded and clamped). Atomic. Errors as sci_image_write. */
int sci_image_write_rgb(const char *path, const sci_cube *rgb, int f, sci_pixel_type type, double scale,
                        sci_error *err);

/* OpenEXR's process-wide compression pool (every EXR read and write in the process): threads > 0 sets its size,
 * 0 one thread per core (OpenImageIO's default), -1 no pool: each file is compressed by the thread that writes it.
 * A program that already writes several files in parallel (scicapd's writers and workers) gains nothing from
 * the pool on few cores and pays its hand-offs: 256×256 float frames cost 4-7 ms of CPU each with it, 2.5 without. */
void sci_image_exr_threads(int threads);

/* Write an animated GIF preview of all frames (8-bit, value × scale clamped), `delay_ms` per frame, with one
 * fixed 256-level grey palette (io/gif.h): every 8-bit value is kept exactly, and no palette is searched.
 * Frames above SCI_GIF_MAX_PIXELS (or wider or taller than GIF's 65535) are shrunk by the smallest integer factor
 * that fits, averaging factor×factor blocks: a preview needs no more (and OpenImageIO 2.4's GIF writer, used before
 * io/gif.c, crashed with SIGSEGV on frames over 2^24 pixels). *factor (may be NULL) receives the
 * factor used (1: full size). */
#define SCI_GIF_MAX_PIXELS (2048 * 2048)
int sci_image_write_gif(const char *path, const sci_cube *c, double scale, int delay_ms, sci_error *err);
int sci_image_write_gif_opt(const char *path, const sci_cube *c, double scale, int delay_ms, int *factor,
                            sci_error *err);

/* Write cube `c` as a stack in folder `dir` (created if missing) with sidecar <dir>/<stem>.json. `ext` is the
 * file extension without dot ("exr", "tif", "png"). `provenance` (may be NULL, borrowed) is copied into the
 * sidecar. */
int sci_stack_write(const char *dir, const char *stem, const char *ext, const sci_cube *c, sci_pixel_type type,
                    double scale, const json_t *provenance, sci_error *err);
/* Same; uncompressed = 1 stores EXR/TIFF frames without compression. For float frames whose low mantissa bits
 * are noise (a solver's output), deflate saves ~2 % of the bytes for 5-6 ms of CPU per 256×256 frame (measured on
 * GAP-TV frames: 261 KB zip against 267 KB raw); compressible frames (masks, rendered truth) keep the default. */
int sci_stack_write_ex(const char *dir, const char *stem, const char *ext, const sci_cube *c, sci_pixel_type type,
                       double scale, const json_t *provenance, int uncompressed, sci_error *err);

/* Read a stack from its sidecar path (<dir>/<stem>.json): checks every frame's size against the sidecar and
 * returns values divided by the sidecar's scale. *provenance (may be NULL) receives a new reference the caller
 * must json_decref, or NULL if the sidecar has none. */
int sci_stack_read(const char *sidecar_path, sci_cube **out, json_t **provenance, sci_error *err);
/* Same, with the sidecar's claim checked before anything is allocated: against `lim` (io/limits.h; NULL: no
 * limit, as sci_stack_read), and against the first frame file's header (its size must be the sidecar's w×h), so a
 * sidecar that lies costs a file open, not w·h·n floats. -EFBIG over a limit, SCI_ESHAPE on a mismatch. */
int sci_stack_read_opts(const char *sidecar_path, const sci_io_limits *lim, sci_cube **out, json_t **provenance,
                        sci_error *err);

#endif
