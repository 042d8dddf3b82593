/* io/gif.c — animated grey GIF with a fixed palette, encoded by giflib (see the header). */
#include "io/gif.h"

#include <errno.h>
#include <gif_lib.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* giflib writes through a callback: the bytes go to a growing buffer. */
typedef struct gif_buf {
    unsigned char *p;
    size_t len, cap;
    int oom;
} gif_buf;

static int buf_write(GifFileType *gif, const GifByteType *src, int n)
{
    gif_buf *b = gif->UserData;
    if (b->oom || n < 0)
        return 0;
    if (b->len + (size_t)n > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->len + (size_t)n)
            cap *= 2;
        unsigned char *q = realloc(b->p, cap);
        if (!q) {
            b->oom = 1;
            return 0; /* giflib then fails the call with E_GIF_ERR_WRITE_FAILED */
        }
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->len, src, (size_t)n);
    b->len += (size_t)n;
    return n;
}

/* The file's body after EGifOpen; GIF_ERROR with gif->Error set on failure. */
static int encode(GifFileType *gif, const unsigned char *frames, int w, int h, int n, int delay_ms)
{
    GifColorType grey[256];
    for (int v = 0; v < 256; v++)
        grey[v] = (GifColorType){(GifByteType)v, (GifByteType)v, (GifByteType)v};
    ColorMapObject *map = GifMakeMapObject(256, grey);
    if (!map) {
        gif->Error = E_GIF_ERR_NOT_ENOUGH_MEM;
        return GIF_ERROR;
    }
    EGifSetGifVersion(gif, true); /* GIF89a: the extensions below */
    int rc = EGifPutScreenDesc(gif, w, h, 8, 0, map);
    GifFreeMapObject(map); /* giflib keeps its own copy */
    if (rc == GIF_ERROR)
        return GIF_ERROR;
    static const GifByteType loop[3] = {1, 0, 0}; /* NETSCAPE2.0 sub-block 1: loop forever */
    if (EGifPutExtensionLeader(gif, APPLICATION_EXT_FUNC_CODE) == GIF_ERROR ||
        EGifPutExtensionBlock(gif, 11, "NETSCAPE2.0") == GIF_ERROR || EGifPutExtensionBlock(gif, 3, loop) == GIF_ERROR ||
        EGifPutExtensionTrailer(gif) == GIF_ERROR)
        return GIF_ERROR;
    const int cs = delay_ms > 5 ? (delay_ms + 5) / 10 : 1; /* GIF's 1/100 s, at least 1 */
    GraphicsControlBlock gcb = {.DisposalMode = DISPOSE_DO_NOT,
                                .UserInputFlag = false,
                                .DelayTime = cs > 65535 ? 65535 : cs,
                                .TransparentColor = NO_TRANSPARENT_COLOR};
    GifByteType ext[4];
    const size_t ext_len = EGifGCBToExtension(&gcb, ext);
    const size_t fs = (size_t)w * (size_t)h;
    for (int k = 0; k < n; k++) {
        if (EGifPutExtension(gif, GRAPHICS_EXT_FUNC_CODE, (int)ext_len, ext) == GIF_ERROR ||
            EGifPutImageDesc(gif, 0, 0, w, h, false, NULL) == GIF_ERROR)
            return GIF_ERROR;
        /* EGifPutLine takes a non-const pointer but only reads the row */
        GifPixelType *rows = (GifPixelType *)(uintptr_t)(frames + (size_t)k * fs);
        for (int y = 0; y < h; y++)
            if (EGifPutLine(gif, rows + (size_t)y * (size_t)w, w) == GIF_ERROR)
                return GIF_ERROR;
    }
    return GIF_OK;
}

int sci_gif_encode_grey(const unsigned char *frames, int w, int h, int n, int delay_ms, unsigned char **out,
                        size_t *len, sci_error *err)
{
    *out = NULL;
    *len = 0;
    if (w < 1 || h < 1 || w > 65535 || h > 65535 || n < 1)
        return sci_error_set(err, -EINVAL, "GIF: %dx%d, %d frames: not a GIF size", w, h, n);
    gif_buf b = {0};
    int gerr = 0;
    GifFileType *gif = EGifOpen(&b, buf_write, &gerr);
    if (!gif)
        return sci_error_set(err, -ENOMEM, "GIF: %s", GifErrorString(gerr));
    int rc = encode(gif, frames, w, h, n, delay_ms);
    if (rc == GIF_ERROR)
        gerr = gif->Error;
    if (EGifCloseFile(gif, rc == GIF_ERROR ? NULL : &gerr) == GIF_ERROR) /* writes the trailer, frees gif */
        rc = GIF_ERROR;
    if (rc == GIF_ERROR || b.oom) {
        free(b.p);
        if (b.oom || gerr == E_GIF_ERR_NOT_ENOUGH_MEM || gerr == E_GIF_ERR_WRITE_FAILED)
            return sci_error_set(err, -ENOMEM, "GIF: out of memory");
        return sci_error_set(err, -EIO, "GIF: %s", GifErrorString(gerr));
    }
    *out = b.p;
    *len = b.len;
    return 0;
}

int sci_gif_write_grey(const char *path, const unsigned char *frames, int w, int h, int n, int delay_ms,
                       sci_error *err)
{
    unsigned char *data;
    size_t len;
    int rc = sci_gif_encode_grey(frames, w, h, n, delay_ms, &data, &len, err);
    if (rc < 0) {
        sci_error_prefix(err, "%s: ", path);
        return rc;
    }
    FILE *f = fopen(path, "wb");
    if (!f) {
        rc = -errno;
        free(data);
        return sci_error_set(err, rc, "%s: %s", path, strerror(-rc));
    }
    int bad = fwrite(data, 1, len, f) != len;
    bad |= fflush(f) != 0;
    int e = errno;
    bad |= fclose(f) != 0;
    free(data);
    if (bad)
        return sci_error_set(err, -(e ? e : EIO), "%s: cannot write: %s", path, strerror(e ? e : EIO));
    return 0;
}
