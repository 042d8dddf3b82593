#include "drivers/dlpc900_erle.h"

#include <errno.h>
#include <string.h>

size_t dlpc900_erle_bound(int w, int h) { return (size_t)w * (size_t)h * 4 + 16; }

size_t dlpc900_raw_size(int w, int h) { return (((size_t)w * 3 + 15) & ~(size_t)15) * (size_t)h; }

/* ---- encoder ---- */

typedef struct outbuf {
    uint8_t *p;
    size_t n, cap;
    int full;
} outbuf;

static inline void put_byte(outbuf *o, uint8_t b)
{
    if (o->n < o->cap)
        o->p[o->n++] = b;
    else
        o->full = 1;
}

static inline void put_count(outbuf *o, uint32_t n)
{
    if (n < 128) {
        put_byte(o, (uint8_t)n);
    } else {
        put_byte(o, (uint8_t)((n & 0x7F) | 0x80));
        put_byte(o, (uint8_t)(n >> 7));
    }
}

static inline void put_pixel(outbuf *o, uint32_t v)
{
    put_byte(o, (uint8_t)(v >> 16));
    put_byte(o, (uint8_t)(v >> 8));
    put_byte(o, (uint8_t)v);
}

static int run_len(const uint32_t *row, int x, int w)
{
    int e = x + 1, lim = w - x > DLPC900_ERLE_COUNT_MAX ? x + DLPC900_ERLE_COUNT_MAX : w;
    while (e < lim && row[e] == row[x])
        e++;
    return e - x;
}

static int copy_len(const uint32_t *row, const uint32_t *prev, int x, int w)
{
    if (!prev)
        return 0;
    int e = x, lim = w - x > DLPC900_ERLE_COUNT_MAX ? x + DLPC900_ERLE_COUNT_MAX : w;
    while (e < lim && row[e] == prev[e])
        e++;
    return e - x;
}

long dlpc900_erle_encode(const uint32_t *px, int w, int h, uint8_t *out, size_t cap)
{
    outbuf o = {out, 0, cap, 0};
    for (int y = 0; y < h; y++) {
        const uint32_t *row = px + (size_t)y * w;
        const uint32_t *prev = y ? row - w : NULL;
        int x = 0;
        while (x < w) {
            int r = run_len(row, x, w);
            int c = copy_len(row, prev, x, w);
            if (c > 0 && c >= r) {
                put_byte(&o, 0);
                put_byte(&o, 1);
                put_count(&o, (uint32_t)c);
                x += c;
            } else if (r >= 2) {
                put_count(&o, (uint32_t)r);
                put_pixel(&o, row[x]);
                x += r;
            } else {
                /* Literal up to the next pixel that starts a repeat or a copy of two or more. */
                int e = x + 1;
                while (e < w && e - x < DLPC900_ERLE_COUNT_MAX) {
                    if (e + 1 < w && row[e] == row[e + 1])
                        break;
                    if (prev && e + 1 < w && row[e] == prev[e] && row[e + 1] == prev[e + 1])
                        break;
                    e++;
                }
                int n = e - x;
                if (n == 1) {
                    put_count(&o, 1);
                    put_pixel(&o, row[x]);
                } else {
                    put_byte(&o, 0);
                    put_count(&o, (uint32_t)n);
                    for (int i = x; i < e; i++)
                        put_pixel(&o, row[i]);
                }
                x = e;
            }
        }
        if (o.full)
            return -ENOSPC;
    }
    put_byte(&o, 0);
    put_byte(&o, 1);
    put_byte(&o, 0);
    return o.full ? -ENOSPC : (long)o.n;
}

long dlpc900_raw_encode(const uint32_t *px, int w, int h, uint8_t *out, size_t cap)
{
    size_t stride = ((size_t)w * 3 + 15) & ~(size_t)15;
    if (cap < stride * (size_t)h)
        return -ENOSPC;
    for (int y = 0; y < h; y++) {
        uint8_t *o = out + stride * (size_t)y;
        const uint32_t *row = px + (size_t)y * w;
        for (int x = 0; x < w; x++) {
            o[3 * x] = (uint8_t)(row[x] >> 16);
            o[3 * x + 1] = (uint8_t)(row[x] >> 8);
            o[3 * x + 2] = (uint8_t)row[x];
        }
        memset(o + 3 * (size_t)w, 0, stride - 3 * (size_t)w);
    }
    return (long)(stride * (size_t)h);
}

/* ---- decoders ---- */

typedef struct reader {
    const uint8_t *d;
    size_t n, pos;
    sci_error *err;
} reader;

static int truncated(reader *r, const char *what)
{
    return sci_error_set(r->err, SCI_EFORMAT, "image data ends at byte %zu inside %s", r->n, what);
}

static int get_u8(reader *r, uint8_t *b, const char *what)
{
    if (r->pos >= r->n)
        return truncated(r, what);
    *b = r->d[r->pos++];
    return 0;
}

static int get_count(reader *r, uint32_t *n, const char *what)
{
    uint8_t b0 = 0, b1 = 0;
    int rc = get_u8(r, &b0, what);
    if (rc < 0)
        return rc;
    if (!(b0 & 0x80)) {
        *n = b0;
        return 0;
    }
    if ((rc = get_u8(r, &b1, what)) < 0)
        return rc;
    *n = (uint32_t)(b0 & 0x7F) | (uint32_t)b1 << 7;
    return 0;
}

static int get_pixel(reader *r, uint32_t *v, const char *what)
{
    if (r->n - r->pos < 3)
        return truncated(r, what);
    const uint8_t *p = r->d + r->pos;
    *v = (uint32_t)p[0] << 16 | (uint32_t)p[1] << 8 | p[2];
    r->pos += 3;
    return 0;
}

/* Checks shared by every run: a row left to write into, and the run fits in it. */
static int check_run(reader *r, size_t at, int x, int y, int w, int h, uint32_t n, const char *what)
{
    if (n == 0)
        return sci_error_set(r->err, SCI_EFORMAT, "byte %zu: %s of zero pixels", at, what);
    if (y >= h)
        return sci_error_set(r->err, SCI_EFORMAT, "byte %zu: %s after the last of %d rows", at, what, h);
    if ((uint32_t)(w - x) < n)
        return sci_error_set(r->err, SCI_EFORMAT, "byte %zu: %s of %u pixels at column %d crosses the end of row %d (width %d)",
                             at, what, n, x, y, w);
    return 0;
}

/* cnt literal pixels into o, all there or SCI_EFORMAT before any is read. */
static int get_literal(reader *r, uint32_t *o, uint32_t cnt)
{
    if ((r->n - r->pos) / 3 < cnt)
        return truncated(r, "literal pixels");
    for (uint32_t i = 0; i < cnt; i++)
        get_pixel(r, &o[i], "literal pixels");
    return 0;
}

/* The close of a decode at row y: every row written (else SCI_EFORMAT), a missing end of image one more warning. */
static int decode_end(reader *r, int y, int h, int done, int warn, size_t *used, int *warnings)
{
    if (y < h)
        return sci_error_set(r->err, SCI_EFORMAT, "image data ends after %d of %d rows", y, h);
    if (!done)
        warn++; /* every row filled but no end of image */
    if (used)
        *used = r->pos;
    if (warnings)
        *warnings = warn;
    return 0;
}

int dlpc900_erle_decode(const uint8_t *d, size_t n, int w, int h, uint32_t *px, size_t *used, int *warnings,
                        sci_error *err)
{
    reader r = {d, n, 0, err};
    int x = 0, y = 0, warn = 0, done = 0, rc;
    memset(px, 0, (size_t)w * (size_t)h * sizeof *px);
    while (!done && r.pos < r.n) {
        size_t at = r.pos;
        uint32_t cnt = 0, v = 0;
        if (d[r.pos] != 0) {
            if ((rc = get_count(&r, &cnt, "a repeat count")) < 0 || (rc = get_pixel(&r, &v, "a repeat pixel")) < 0 ||
                (rc = check_run(&r, at, x, y, w, h, cnt, "repeat run")) < 0)
                return rc;
            uint32_t *o = px + (size_t)y * w + x;
            for (uint32_t i = 0; i < cnt; i++)
                o[i] = v;
            x += (int)cnt;
        } else {
            uint8_t c = 0;
            r.pos++;
            if ((rc = get_u8(&r, &c, "an escape")) < 0)
                return rc;
            if (c == 0) { /* end of line */
                if (x != 0) {
                    warn++;
                    x = 0;
                    y++;
                }
                continue;
            }
            if (c == 1) {
                if ((rc = get_count(&r, &cnt, "a copy count")) < 0)
                    return rc;
                if (cnt == 0) {
                    done = 1;
                    break;
                }
                if (y == 0)
                    return sci_error_set(err, SCI_EFORMAT, "byte %zu: copy from the previous line on row 0", at);
                if ((rc = check_run(&r, at, x, y, w, h, cnt, "copy")) < 0)
                    return rc;
                uint32_t *o = px + (size_t)y * w + x;
                memcpy(o, o - w, cnt * sizeof *o);
                x += (int)cnt;
            } else {
                r.pos--;
                if ((rc = get_count(&r, &cnt, "a literal count")) < 0 ||
                    (rc = check_run(&r, at, x, y, w, h, cnt, "literal run")) < 0)
                    return rc;
                if ((rc = get_literal(&r, px + (size_t)y * w + x, cnt)) < 0)
                    return rc;
                x += (int)cnt;
            }
        }
        if (x == w) {
            x = 0;
            y++;
        }
    }
    return decode_end(&r, y, h, done, warn, used, warnings);
}

int dlpc900_rle_decode(const uint8_t *d, size_t n, int w, int h, uint32_t *px, size_t *used, int *warnings,
                       sci_error *err)
{
    reader r = {d, n, 0, err};
    int x = 0, y = 0, warn = 0, done = 0, rc;
    memset(px, 0, (size_t)w * (size_t)h * sizeof *px);
    while (!done && r.pos < r.n) {
        size_t at = r.pos;
        uint8_t b = 0, c = 0;
        uint32_t v = 0;
        get_u8(&r, &b, "");
        if (b != 0) {
            if ((rc = get_pixel(&r, &v, "a repeat pixel")) < 0 || (rc = check_run(&r, at, x, y, w, h, b, "repeat run")) < 0)
                return rc;
            uint32_t *o = px + (size_t)y * w + x;
            for (int i = 0; i < b; i++)
                o[i] = v;
            x += b;
            continue;
        }
        if ((rc = get_u8(&r, &c, "an escape")) < 0)
            return rc;
        if (c == 0) { /* end of line, mandatory in RLE; the next line starts on a 4-byte boundary */
            if (y >= h)
                return sci_error_set(err, SCI_EFORMAT, "byte %zu: end of line after the last of %d rows", at, h);
            if (x != w)
                warn++;
            x = 0;
            y++;
            r.pos = (r.pos + 3) & ~(size_t)3;
            if (r.pos > r.n)
                r.pos = r.n;
        } else if (c == 1) {
            done = 1;
        } else {
            if ((rc = check_run(&r, at, x, y, w, h, c, "literal run")) < 0)
                return rc;
            if ((rc = get_literal(&r, px + (size_t)y * w + x, c)) < 0)
                return rc;
            x += c;
        }
    }
    if (y == h - 1 && x == w) { /* last end of line omitted before end of image: tolerated */
        y = h;
        warn++;
    }
    return decode_end(&r, y, h, done, warn, used, warnings);
}

int dlpc900_raw_decode(const uint8_t *d, size_t n, int w, int h, uint32_t *px, sci_error *err)
{
    size_t stride = ((size_t)w * 3 + 15) & ~(size_t)15;
    if (n < stride * (size_t)h)
        return sci_error_set(err, SCI_EFORMAT, "uncompressed image of %d×%d needs %zu bytes, got %zu", w, h,
                             stride * (size_t)h, n);
    for (int y = 0; y < h; y++) {
        const uint8_t *p = d + stride * (size_t)y;
        uint32_t *o = px + (size_t)y * w;
        for (int x = 0; x < w; x++)
            o[x] = (uint32_t)p[3 * x] << 16 | (uint32_t)p[3 * x + 1] << 8 | p[3 * x + 2];
    }
    return 0;
}
