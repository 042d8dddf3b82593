#include "drivers/dlpc900_image.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/dlpc900_erle.h"
#include "drivers/dlpc900_proto.h"

void dlpc900_image_header_write(uint8_t out[DLPC900_IMAGE_HEADER_SIZE], const dlpc900_image_header *h)
{
    memset(out, 0, DLPC900_IMAGE_HEADER_SIZE);
    memcpy(out, "Spld", 4);
    dlpc900_put16(out + 4, h->width);
    dlpc900_put16(out + 6, h->height);
    dlpc900_put32(out + 8, h->byte_count);
    dlpc900_put32(out + 12, 0xFFFFFFFFu); /* sub-image offset */
    dlpc900_put32(out + 16, 0xFFFFFFFFu); /* sub-image end */
    dlpc900_put32(out + 20, 0);           /* background colour */
    out[24] = h->pixel_format;
    out[25] = h->compression;
    out[26] = 1; /* byte order */
    out[27] = 0; /* chroma order */
    out[28] = 0; /* is3D */
    out[29] = h->is_left;
}

int dlpc900_image_header_read(const uint8_t *buf, size_t len, dlpc900_image_header *h, sci_error *err)
{
    if (len < DLPC900_IMAGE_HEADER_SIZE)
        return sci_error_set(err, SCI_EFORMAT, "image of %zu bytes is shorter than its 48-byte header", len);
    if (memcmp(buf, "Spld", 4) != 0)
        return sci_error_set(err, SCI_EFORMAT, "image header signature is %02X %02X %02X %02X, not \"Spld\"", buf[0],
                             buf[1], buf[2], buf[3]);
    h->width = dlpc900_get16(buf + 4);
    h->height = dlpc900_get16(buf + 6);
    h->byte_count = dlpc900_get32(buf + 8);
    h->pixel_format = buf[24];
    h->compression = buf[25];
    h->is_left = buf[29];
    if (h->width < 1 || h->height < 1 || h->width > DLPC900_IMAGE_DIM_MAX || h->height > DLPC900_IMAGE_DIM_MAX)
        return sci_error_set(err, SCI_EFORMAT, "image header size %u×%u out of range 1…%d", h->width, h->height,
                             DLPC900_IMAGE_DIM_MAX);
    if (h->compression > DLPC900_COMP_ERLE)
        return sci_error_set(err, SCI_EFORMAT, "image header compression %u is not 0, 1 or 2 (device error 9: %s)",
                             h->compression, dlpc900_errcode_text(DLPC900_ERR_BMP_COMPRESSION));
    if (h->pixel_format > 1)
        return sci_error_set(err, SCI_EFORMAT, "image header pixel format %u is not 24-bit packed (1)", h->pixel_format);
    return 0;
}

int dlpc900_image_pack_cube(const sci_cube *masks, int first, int count, uint32_t *px, sci_error *err)
{
    if (first < 0 || count < 1 || count > DLPC900_MASKS_PER_IMAGE || first + count > masks->n)
        return sci_error_set(err, -EINVAL, "masks %d…%d: outside the %d masks given, or more than 24", first,
                             first + count - 1, masks->n);
    size_t npx = sci_cube_frame_size(masks);
    memset(px, 0, npx * sizeof *px);
    for (int k = 0; k < count; k++) {
        const float *f = sci_cube_frame(masks, first + k);
        uint32_t bit = 1u << k;
        for (size_t i = 0; i < npx; i++) {
            if (!isfinite(f[i]))
                return sci_error_set(err, SCI_ENONFINITE, "mask %d pixel (%zu, %zu) is %g", first + k,
                                     i % (size_t)masks->w, i / (size_t)masks->w, (double)f[i]);
            if (f[i] >= 0.5f)
                px[i] |= bit;
        }
    }
    return 0;
}

void dlpc900_image_pack_bytes(const uint8_t *masks, int w, int h, int count, uint32_t *px)
{
    size_t npx = (size_t)w * (size_t)h;
    memset(px, 0, npx * sizeof *px);
    for (int k = 0; k < count && k < DLPC900_MASKS_PER_IMAGE; k++) {
        const uint8_t *m = masks + (size_t)k * npx;
        for (size_t i = 0; i < npx; i++)
            px[i] |= (uint32_t)(m[i] != 0) << k;
    }
}

void dlpc900_image_unpack_bit(const uint32_t *px, int w, int h, int bit, uint8_t *out)
{
    size_t npx = (size_t)w * (size_t)h;
    for (size_t i = 0; i < npx; i++)
        out[i] = (uint8_t)((px[i] >> bit) & 1);
}

int dlpc900_image_encode(const uint32_t *px, int w, int h, uint8_t **out, size_t *len, int *compression,
                         sci_error *err)
{
    if (w < 1 || h < 1 || w > DLPC900_IMAGE_DIM_MAX || h > DLPC900_IMAGE_DIM_MAX)
        return sci_error_set(err, -EINVAL, "image size %d×%d out of range 1…%d", w, h, DLPC900_IMAGE_DIM_MAX);
    size_t raw = dlpc900_raw_size(w, h);
    size_t cap = dlpc900_erle_bound(w, h);
    uint8_t *buf = malloc(DLPC900_IMAGE_HEADER_SIZE + (cap > raw ? cap : raw));
    if (!buf)
        return sci_error_set(err, -ENOMEM, "image %d×%d: out of memory for the encoded image", w, h);
    dlpc900_image_header hd = {.width = (uint16_t)w, .height = (uint16_t)h, .pixel_format = 1, .is_left = 1};
    long n = dlpc900_erle_encode(px, w, h, buf + DLPC900_IMAGE_HEADER_SIZE, cap);
    hd.compression = DLPC900_COMP_ERLE;
    if (n < 0 || (size_t)n > raw) {
        n = dlpc900_raw_encode(px, w, h, buf + DLPC900_IMAGE_HEADER_SIZE, raw);
        hd.compression = DLPC900_COMP_NONE;
    }
    hd.byte_count = (uint32_t)n;
    dlpc900_image_header_write(buf, &hd);
    *out = buf;
    *len = DLPC900_IMAGE_HEADER_SIZE + (size_t)n;
    if (compression)
        *compression = hd.compression;
    return 0;
}

int dlpc900_image_decode(const uint8_t *buf, size_t len, uint32_t **px, dlpc900_image_info *info, sci_error *err)
{
    dlpc900_image_info inf = {0};
    int rc = dlpc900_image_header_read(buf, len, &inf.header, err);
    if (rc < 0)
        return rc;
    const dlpc900_image_header *h = &inf.header;
    size_t data = len - DLPC900_IMAGE_HEADER_SIZE;
    /* Two byte-count conventions (reference §9): TI counts data only, pycrafter the whole file. */
    if ((size_t)h->byte_count == data) {
    } else if ((size_t)h->byte_count == len) {
        inf.warnings++;
    } else {
        return sci_error_set(err, SCI_EFORMAT, "image header byte count %u disagrees with the %zu bytes received",
                             h->byte_count, len);
    }
    if (h->pixel_format != 1 || h->is_left != 1)
        inf.warnings++;
    uint32_t *p = malloc((size_t)h->width * h->height * sizeof *p);
    if (!p)
        return sci_error_set(err, -ENOMEM, "image %u×%u: out of memory", h->width, h->height);
    const uint8_t *d = buf + DLPC900_IMAGE_HEADER_SIZE;
    int warn = 0;
    size_t used = data;
    if (h->compression == DLPC900_COMP_ERLE)
        rc = dlpc900_erle_decode(d, data, h->width, h->height, p, &used, &warn, err);
    else if (h->compression == DLPC900_COMP_RLE)
        rc = dlpc900_rle_decode(d, data, h->width, h->height, p, &used, &warn, err);
    else
        rc = dlpc900_raw_decode(d, data, h->width, h->height, p, err);
    if (rc < 0) {
        free(p);
        return rc;
    }
    inf.warnings += warn;
    inf.data_used = used;
    if (info)
        *info = inf;
    *px = p;
    return 0;
}
