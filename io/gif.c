/* io/gif.c — animated grey GIF with a fixed palette (see the header). */
#include "io/gif.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct gif_buf {
    unsigned char *p;
    size_t len, cap;
    int oom;
} gif_buf;

static void put(gif_buf *b, const void *src, size_t n)
{
    if (b->oom)
        return;
    if (b->len + n > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->len + n)
            cap *= 2;
        unsigned char *q = realloc(b->p, cap);
        if (!q) {
            b->oom = 1;
            return;
        }
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->len, src, n);
    b->len += n;
}

static void put_byte(gif_buf *b, unsigned v)
{
    unsigned char c = (unsigned char)v;
    put(b, &c, 1);
}

static void put_u16(gif_buf *b, unsigned v)
{
    put_byte(b, v & 0xff);
    put_byte(b, (v >> 8) & 0xff);
}

/* LZW codes packed LSB first into bytes, the bytes into sub-blocks of at most 255. */
typedef struct lzw_out {
    gif_buf *b;
    uint32_t acc;
    int nbits;
    unsigned char block[255];
    int blen;
} lzw_out;

static void block_byte(lzw_out *o, unsigned char v)
{
    o->block[o->blen++] = v;
    if (o->blen == 255) {
        put_byte(o->b, 255);
        put(o->b, o->block, 255);
        o->blen = 0;
    }
}

static void emit(lzw_out *o, unsigned code, int size)
{
    o->acc |= (uint32_t)code << o->nbits;
    o->nbits += size;
    while (o->nbits >= 8) {
        block_byte(o, (unsigned char)(o->acc & 0xff));
        o->acc >>= 8;
        o->nbits -= 8;
    }
}

static void emit_end(lzw_out *o)
{
    if (o->nbits > 0)
        block_byte(o, (unsigned char)(o->acc & 0xff));
    if (o->blen > 0) {
        put_byte(o->b, (unsigned)o->blen);
        put(o->b, o->block, (size_t)o->blen);
    }
    put_byte(o->b, 0); /* block terminator */
}

/* The string table as a hash of (prefix code, next byte) -> code: at most 4096 entries in 8192 slots. */
#define LZW_SLOTS 8192
enum { LZW_MIN = 8, LZW_CLEAR = 256, LZW_EOI = 257, LZW_MAXCODE = 4095 };

/* One frame's image data: minimum code size 8, a clear code first, the table reset when full. The code size
 * grows when the code just assigned reaches 1 << size, the rule every decoder follows (one code behind). */
static void lzw_frame(gif_buf *b, const unsigned char *px, size_t count, int32_t *keys, uint16_t *vals)
{
    lzw_out o = {.b = b};
    put_byte(b, LZW_MIN);
    int size = LZW_MIN + 1;
    unsigned next = LZW_EOI + 1;
    memset(keys, 0xff, LZW_SLOTS * sizeof *keys);
    emit(&o, LZW_CLEAR, size);
    unsigned prefix = px[0];
    for (size_t i = 1; i < count; i++) {
        const unsigned c = px[i];
        const int32_t key = (int32_t)(prefix << 8 | c);
        uint32_t h = ((uint32_t)key * 2654435761u) >> (32 - 13);
        while (keys[h] >= 0 && keys[h] != key)
            h = (h + 1) & (LZW_SLOTS - 1);
        if (keys[h] == key) {
            prefix = vals[h];
            continue;
        }
        emit(&o, prefix, size);
        keys[h] = key;
        vals[h] = (uint16_t)next;
        if (next >= (1u << size))
            size++;
        if (next == LZW_MAXCODE) {
            emit(&o, LZW_CLEAR, size);
            memset(keys, 0xff, LZW_SLOTS * sizeof *keys);
            size = LZW_MIN + 1;
            next = LZW_EOI;
        }
        next++;
        prefix = c;
    }
    emit(&o, prefix, size);
    emit(&o, LZW_EOI, size);
    emit_end(&o);
}

int sci_gif_encode_grey(const unsigned char *frames, int w, int h, int n, int delay_ms, unsigned char **out,
                        size_t *len, sci_error *err)
{
    *out = NULL;
    *len = 0;
    if (w < 1 || h < 1 || w > 65535 || h > 65535 || n < 1)
        return sci_error_set(err, -EINVAL, "GIF: %dx%d, %d frames: not a GIF size", w, h, n);
    int32_t *keys = malloc(LZW_SLOTS * sizeof *keys);
    uint16_t *vals = malloc(LZW_SLOTS * sizeof *vals);
    gif_buf b = {0};
    if (!keys || !vals) {
        free(keys);
        free(vals);
        return sci_error_set(err, -ENOMEM, "GIF: out of memory");
    }
    put(&b, "GIF89a", 6);
    put_u16(&b, (unsigned)w);
    put_u16(&b, (unsigned)h);
    put_byte(&b, 0xf7); /* global table, 8 bits of colour resolution, 2^(7+1) entries */
    put_byte(&b, 0);    /* background: entry 0 */
    put_byte(&b, 0);    /* square pixels */
    for (unsigned v = 0; v < 256; v++) {
        const unsigned char rgb[3] = {(unsigned char)v, (unsigned char)v, (unsigned char)v};
        put(&b, rgb, 3);
    }
    put(&b, "\x21\xff\x0bNETSCAPE2.0\x03\x01", 16);
    put_u16(&b, 0); /* loop forever */
    put_byte(&b, 0);
    const unsigned delay = delay_ms > 5 ? (unsigned)(delay_ms + 5) / 10 : 1;
    const size_t fs = (size_t)w * (size_t)h;
    for (int k = 0; k < n; k++) {
        put(&b, "\x21\xf9\x04\x04", 4); /* graphic control: disposal 1 (leave in place), no transparency */
        put_u16(&b, delay > 65535 ? 65535 : delay);
        put_byte(&b, 0);
        put_byte(&b, 0);
        put_byte(&b, 0x2c);
        put_u16(&b, 0);
        put_u16(&b, 0);
        put_u16(&b, (unsigned)w);
        put_u16(&b, (unsigned)h);
        put_byte(&b, 0); /* no local table, not interlaced */
        lzw_frame(&b, frames + (size_t)k * fs, fs, keys, vals);
    }
    put_byte(&b, 0x3b);
    free(keys);
    free(vals);
    if (b.oom) {
        free(b.p);
        return sci_error_set(err, -ENOMEM, "GIF: out of memory");
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
