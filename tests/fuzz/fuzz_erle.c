/* libFuzzer target: the DLPC900 image decoders (ERLE, RLE, raw) and the image-file parser.
 *
 * Input: byte 0 = width - 1 (1…256), byte 1 = height - 1 (1…64), byte 2 = decoder (0 ERLE, 1 RLE, 2 raw,
 * 3 whole file with header), rest = data. Properties checked besides "no crash": whatever ERLE decodes
 * re-encodes with our encoder and decodes back to the same pixels. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/dlpc900_erle.h"
#include "drivers/dlpc900_image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 3)
        return 0;
    int w = data[0] + 1, h = (data[1] & 63) + 1, mode = data[2] & 3;
    const uint8_t *d = data + 3;
    size_t n = size - 3;
    sci_error err = {0};
    if (mode == 3) {
        /* Whole file: bound the header's size so one input cannot ask for 64 MB. */
        if (n >= DLPC900_IMAGE_HEADER_SIZE && (uint32_t)(d[4] | d[5] << 8) * (uint32_t)(d[6] | d[7] << 8) > 65536)
            return 0;
        uint32_t *px = NULL;
        dlpc900_image_info info;
        if (dlpc900_image_decode(d, n, &px, &info, &err) == 0)
            free(px);
        return 0;
    }
    uint32_t *px = malloc((size_t)w * h * sizeof *px);
    int rc;
    if (mode == 0)
        rc = dlpc900_erle_decode(d, n, w, h, px, NULL, NULL, &err);
    else if (mode == 1)
        rc = dlpc900_rle_decode(d, n, w, h, px, NULL, NULL, &err);
    else
        rc = dlpc900_raw_decode(d, n, w, h, px, &err);
    if (rc == 0) {
        for (size_t i = 0; i < (size_t)w * h; i++)
            px[i] &= 0xFFFFFFu;
        size_t cap = dlpc900_erle_bound(w, h);
        uint8_t *enc = malloc(cap);
        uint32_t *back = malloc((size_t)w * h * sizeof *back);
        long m = dlpc900_erle_encode(px, w, h, enc, cap);
        if (m < 0 || dlpc900_erle_decode(enc, (size_t)m, w, h, back, NULL, NULL, &err) != 0 ||
            memcmp(back, px, (size_t)w * h * sizeof *px) != 0)
            abort(); /* the encoder and decoder disagree */
        free(enc);
        free(back);
    }
    free(px);
    return 0;
}
