#include "io/mat_verify.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <zlib.h>

enum { MI_INT8 = 1, MI_UINT8, MI_INT16, MI_UINT16, MI_INT32, MI_UINT32, MI_SINGLE, MI_DOUBLE = 9, MI_INT64 = 12,
       MI_UINT64, MI_MATRIX, MI_COMPRESSED, MI_UTF8, MI_UTF16, MI_UTF32 };
enum { MX_SPARSE = 5, MX_DOUBLE = 6, MX_UINT64 = 15 };

/* The head of a variable kept for the structure check: flags, dims (≤ 32), name (≤ 63 in MATLAB, ≤ 4096 here) and
 * the data tags fit well inside. */
#define HEAD_MAX 8192

typedef struct reader {
    FILE *f;
    const char *path;
    int swap; /* file is big-endian ("MI") */
} reader;

static uint32_t u32(const reader *r, const unsigned char *p)
{
    return r->swap ? (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]
                   : (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 | (uint32_t)p[1] << 8 | p[0];
}

static int type_size(uint32_t t)
{
    switch (t) {
    case MI_INT8: case MI_UINT8: case MI_UTF8: return 1;
    case MI_INT16: case MI_UINT16: case MI_UTF16: return 2;
    case MI_INT32: case MI_UINT32: case MI_SINGLE: case MI_UTF32: return 4;
    case MI_DOUBLE: case MI_INT64: case MI_UINT64: return 8;
    default: return 0;
    }
}

/* One subelement at head[*pos] (total bytes available: have; the matrix's content ends at `end`): its type and
 * byte count, with *pos moved past it and its padding. Small-element format: 4 data bytes inside the tag. */
static int sub_next(const reader *r, const unsigned char *head, size_t have, size_t end, size_t *pos,
                    uint32_t *type, uint32_t *nbytes, const unsigned char **data, long long at, const char *what,
                    sci_error *err)
{
    if (*pos + 8 > end || *pos + 8 > have)
        return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: %s missing (matrix too short)", r->path,
                             at, what);
    uint32_t t = u32(r, head + *pos);
    if (t >> 16) { /* small element */
        *nbytes = t >> 16;
        *type = t & 0xffff;
        if (*nbytes > 4)
            return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: %s: small element of %u bytes",
                                 r->path, at, what, (unsigned)*nbytes);
        *data = head + *pos + 4;
        *pos += 8;
        return 0;
    }
    *type = t;
    *nbytes = u32(r, head + *pos + 4);
    *data = head + *pos + 8;
    const size_t padded = ((size_t)*nbytes + 7) & ~(size_t)7;
    if (padded > end - *pos - 8)
        return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: %s of %u bytes overruns its matrix",
                             r->path, at, what, (unsigned)*nbytes);
    *pos += 8 + padded;
    return 0;
}

/* The structure of one miMATRIX element whose content (after its 8-byte tag) is `total` bytes, of which the first
 * `have` are in head. `at` is the element's file offset, for messages. */
static int check_matrix(const reader *r, const unsigned char *head, size_t have, size_t total, long long at,
                        sci_error *err)
{
    if (total == 0)
        return 0; /* an empty element: MATLAB writes these for empty variables */
    size_t pos = 0;
    uint32_t t, nb;
    const unsigned char *d;
    int rc;
    if ((rc = sub_next(r, head, have, total, &pos, &t, &nb, &d, at, "array flags", err)) < 0)
        return rc;
    if (t != MI_UINT32 || nb != 8)
        return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: array flags are type %u, %u bytes "
                             "(expected miUINT32, 8)", r->path, at, (unsigned)t, (unsigned)nb);
    const uint32_t flags = u32(r, d);
    const unsigned cls = flags & 0xff;
    const int complex = (flags >> 11) & 1;
    if (cls < 1 || cls > 18)
        return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: unknown array class %u", r->path, at,
                             cls);
    if ((rc = sub_next(r, head, have, total, &pos, &t, &nb, &d, at, "dimensions", err)) < 0)
        return rc;
    if (t != MI_INT32 || nb < 8 || nb % 4 || nb > 4 * 32)
        return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: dimensions are type %u, %u bytes "
                             "(expected miINT32, 2 to 32 of them)", r->path, at, (unsigned)t, (unsigned)nb);
    double count = 1;
    for (uint32_t i = 0; i < nb / 4; i++) {
        const int32_t dim = (int32_t)u32(r, d + 4 * i);
        if (dim < 0)
            return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: negative dimension %d", r->path, at,
                                 (int)dim);
        count *= dim;
    }
    if ((rc = sub_next(r, head, have, total, &pos, &t, &nb, &d, at, "array name", err)) < 0)
        return rc;
    if (t != MI_INT8 && t != MI_UTF8)
        return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: array name is type %u (expected miINT8)",
                             r->path, at, (unsigned)t);
    if (cls == MX_SPARSE || cls < MX_DOUBLE || cls > MX_UINT64)
        return 0; /* cell, struct, object, char, sparse: only their head is checked (the readers refuse them) */
    for (int part = 0; part <= complex; part++) {
        const char *what = part ? "imaginary part" : "real part";
        if (part && pos + 8 > have && pos + 8 <= total)
            return 0; /* the imaginary tag lies past the head kept; complex arrays are refused by the readers */
        if ((rc = sub_next(r, head, have, total, &pos, &t, &nb, &d, at, what, err)) < 0)
            return rc;
        const int es = type_size(t);
        if (!es || t == MI_UTF8 || t == MI_UTF16 || t == MI_UTF32)
            return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: %s has data type %u", r->path, at,
                                 what, (unsigned)t);
        if ((double)nb != count * es)
            return sci_error_set(err, SCI_EFORMAT,
                                 "%s: variable at byte %lld: %s holds %u bytes, its dimensions need %.0f × %d",
                                 r->path, at, what, (unsigned)nb, count, es);
    }
    if (pos != total)
        return sci_error_set(err, SCI_EFORMAT, "%s: variable at byte %lld: %zu bytes of matrix, its parts fill %zu",
                             r->path, at, total, pos);
    return 0;
}

/* Inflate the zlib stream of `nbytes` at the current file position: it must end exactly there, with zlib's
 * adler32 verified. The first HEAD_MAX inflated bytes go to head (*have of them), the total to *total. */
static int inflate_element(const reader *r, uint32_t nbytes, long long at, unsigned char *head, size_t *have,
                           unsigned long long *total, sci_error *err)
{
    enum { IN = 65536, OUT = 65536 };
    unsigned char *in = malloc(IN), *out = malloc(OUT);
    z_stream z = {0};
    int rc = 0, zr = Z_OK;
    if (!in || !out || inflateInit(&z) != Z_OK) {
        rc = sci_error_set(err, -ENOMEM, "%s: out of memory", r->path);
        goto done;
    }
    uint32_t left = nbytes;
    *have = 0;
    *total = 0;
    while (zr != Z_STREAM_END) {
        if (z.avail_in == 0) {
            if (left == 0)
                break;
            const size_t want = left < IN ? left : IN;
            if (fread(in, 1, want, r->f) != want) {
                rc = sci_error_set(err, SCI_EFORMAT, "%s: compressed variable at byte %lld: file ends inside it",
                                   r->path, at);
                goto done;
            }
            left -= (uint32_t)want;
            z.next_in = in;
            z.avail_in = (uInt)want;
        }
        z.next_out = out;
        z.avail_out = OUT;
        zr = inflate(&z, Z_NO_FLUSH);
        if (zr != Z_OK && zr != Z_STREAM_END) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s: compressed variable at byte %lld is corrupt (zlib: %s)",
                               r->path, at, zr == Z_DATA_ERROR && z.msg ? z.msg : zError(zr));
            goto done;
        }
        const size_t got = OUT - z.avail_out;
        if (*have < HEAD_MAX) {
            const size_t take = got < HEAD_MAX - *have ? got : HEAD_MAX - *have;
            memcpy(head + *have, out, take);
            *have += take;
        }
        *total += got;
    }
    if (zr != Z_STREAM_END)
        rc = sci_error_set(err, SCI_EFORMAT,
                           "%s: compressed variable at byte %lld: the zlib stream does not end with the element "
                           "(%u bytes): truncated or corrupt",
                           r->path, at, (unsigned)nbytes);
    else if (z.avail_in != 0 || left != 0)
        rc = sci_error_set(err, SCI_EFORMAT,
                           "%s: compressed variable at byte %lld: the zlib stream ends %llu bytes before the element",
                           r->path, at, (unsigned long long)z.avail_in + left);
done:
    inflateEnd(&z);
    free(in);
    free(out);
    return rc;
}

int sci_mat_verify(const char *path, sci_error *err)
{
    reader r = {.path = path};
    if (!(r.f = fopen(path, "rb")))
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    unsigned char hdr[128];
    unsigned char *head = malloc(HEAD_MAX);
    int rc = 0;
    if (!head) {
        rc = sci_error_set(err, -ENOMEM, "%s: out of memory", path);
        goto out;
    }
    if (fread(hdr, 1, sizeof hdr, r.f) != sizeof hdr) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: shorter than a MAT-file header (truncated?)", path);
        goto out;
    }
    if (hdr[126] == 'M' && hdr[127] == 'I')
        r.swap = 1;
    else if (!(hdr[126] == 'I' && hdr[127] == 'M')) {
        if (memcmp(hdr, "\x89HDF", 4) == 0)
            goto out; /* a bare HDF5 file: the HDF5 library judges it */
        rc = sci_error_set(err, SCI_EFORMAT, "%s: no MAT-file byte-order mark at byte 126 (found 0x%02x%02x, "
                           "expected \"IM\" or \"MI\"): not a .mat file, or corrupt", path, hdr[126], hdr[127]);
        goto out;
    }
    const unsigned version = r.swap ? (unsigned)(hdr[124] << 8 | hdr[125]) : (unsigned)(hdr[125] << 8 | hdr[124]);
    if (version == 0x0200)
        goto out; /* v7.3: HDF5 behind a 512-byte header, with HDF5's own checks */
    if (version != 0x0100) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: MAT-file version 0x%04x at byte 124 (expected 0x0100 for v5 or "
                           "0x0200 for v7.3): corrupt header", path, version);
        goto out;
    }
    if (fseeko(r.f, 0, SEEK_END) != 0) {
        rc = sci_error_set(err, -EIO, "%s: cannot seek", path);
        goto out;
    }
    const off_t size = ftello(r.f);
    off_t pos = 128;
    while (pos < size) {
        unsigned char tag[8];
        if (size - pos < 8 || fseeko(r.f, pos, SEEK_SET) != 0 || fread(tag, 1, 8, r.f) != 8) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s: %lld stray bytes at byte %lld after the last variable "
                               "(truncated or corrupt)", path, (long long)(size - pos), (long long)pos);
            goto out;
        }
        const uint32_t type = u32(&r, tag), nbytes = u32(&r, tag + 4);
        if (type != MI_MATRIX && type != MI_COMPRESSED) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s: element at byte %lld has type %u (a MAT-file holds only "
                               "miMATRIX 14 and miCOMPRESSED 15): corrupt", path, (long long)pos, (unsigned)type);
            goto out;
        }
        /* miMATRIX is padded to 8 bytes; miCOMPRESSED is not */
        const off_t len = type == MI_MATRIX ? (8 + (off_t)nbytes + 7) & ~(off_t)7 : 8 + (off_t)nbytes;
        if (8 + (off_t)nbytes > size - pos) {
            rc = sci_error_set(err, SCI_EFORMAT,
                               "%s: truncated: an element at byte %lld needs %u bytes, the file ends %lld bytes later",
                               path, (long long)pos, (unsigned)nbytes, (long long)(size - pos - 8));
            goto out;
        }
        size_t have = 0;
        if (type == MI_COMPRESSED) {
            unsigned long long total = 0;
            if ((rc = inflate_element(&r, nbytes, (long long)pos, head, &have, &total, err)) < 0)
                goto out;
            if (have < 8 || u32(&r, head) != MI_MATRIX || 8 + (unsigned long long)u32(&r, head + 4) != total) {
                rc = sci_error_set(err, SCI_EFORMAT, "%s: compressed variable at byte %lld does not hold one "
                                   "matrix of the inflated size (%llu bytes)", path, (long long)pos, total);
                goto out;
            }
            if ((rc = check_matrix(&r, head + 8, have - 8, (size_t)(total - 8), (long long)pos, err)) < 0)
                goto out;
        } else {
            have = fread(head, 1, nbytes < HEAD_MAX ? nbytes : HEAD_MAX, r.f);
            if ((rc = check_matrix(&r, head, have, nbytes, (long long)pos, err)) < 0)
                goto out;
        }
        pos += len;
    }
    if (pos != size) /* an unpadded last miMATRIX */
        rc = sci_error_set(err, SCI_EFORMAT, "%s: the last variable's padding runs past the end of the file", path);
out:
    free(head);
    fclose(r.f);
    return rc;
}
