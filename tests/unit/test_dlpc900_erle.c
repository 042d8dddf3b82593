/* Tests for drivers/dlpc900_erle and dlpc900_image: a golden ERLE byte string, the encoder variants of public
 * drivers (TI, e841018/pycrafter, mcSIM) through the decoder, every rejection rule, RLE and raw, header
 * variants, and full-resolution round trips. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "base/rng.h"
#include "drivers/dlpc900_erle.h"
#include "drivers/dlpc900_image.h"

#define A 0x010203u
#define B 0x0A0B0Cu
#define C 0x111213u
#define D 0x212223u
#define E 0x313233u

static const uint32_t img43[12] = {A, A, A, B, A, A, A, B, C, D, E, E};

static uint64_t seed;

/* The canonical encoding of img43, worked out by hand from the grammar (reference §10). */
static const uint8_t golden43[] = {
    0x03, 0x01, 0x02, 0x03,                         /* row 0: 3 × A */
    0x01, 0x0A, 0x0B, 0x0C,                         /*        lone B = run of 1 */
    0x00, 0x01, 0x04,                               /* row 1: copy 4 from the previous line */
    0x00, 0x02, 0x11, 0x12, 0x13, 0x21, 0x22, 0x23, /* row 2: literal C D */
    0x02, 0x31, 0x32, 0x33,                         /*        2 × E */
    0x00, 0x01, 0x00,                               /* end of image */
};

static void decode_ok(const uint8_t *d, size_t n, int w, int h, const uint32_t *want, int want_warn)
{
    uint32_t *px = malloc((size_t)w * h * sizeof *px);
    sci_error err = {0};
    int warn = -1;
    int rc = dlpc900_erle_decode(d, n, w, h, px, NULL, &warn, &err);
    if (rc)
        fail_msg("decode failed: %s", err.msg);
    assert_memory_equal(px, want, (size_t)w * h * sizeof *px);
    assert_int_equal(warn, want_warn);
    free(px);
}

static void decode_bad(const uint8_t *d, size_t n, int w, int h, const char *why)
{
    uint32_t px[64];
    sci_error err = {0};
    assert_int_equal(dlpc900_erle_decode(d, n, w, h, px, NULL, NULL, &err), SCI_EFORMAT);
    if (!strstr(err.msg, why))
        fail_msg("expected \"%s\" in \"%s\"", why, err.msg);
}

static void test_golden_encode(void **state)
{
    uint8_t out[256];
    long n = dlpc900_erle_encode(img43, 4, 3, out, sizeof out);
    assert_int_equal(n, sizeof golden43);
    assert_memory_equal(out, golden43, sizeof golden43);
    decode_ok(golden43, sizeof golden43, 4, 3, img43, 0);
    assert_int_equal(dlpc900_erle_encode(img43, 4, 3, out, 10), -ENOSPC);
}

/* e841018/ERLE (pycrafter): end of line after every row, end of image, padding to 4 bytes. */
static void test_variant_e841018(void **state)
{
    const uint8_t d[] = {0x03, 0x01, 0x02, 0x03, 0x01, 0x0A, 0x0B, 0x0C, 0x00, 0x00, 0x00, 0x01, 0x04, 0x00, 0x00,
                         0x00, 0x02, 0x11, 0x12, 0x13, 0x21, 0x22, 0x23, 0x02, 0x31, 0x32, 0x33, 0x00, 0x00,
                         0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00};
    decode_ok(d, sizeof d, 4, 3, img43, 0);
}

/* mcSIM encode_erle: whole-row copy when a row repeats, else repeat runs only (runs of 1 included);
 * also 2-byte counts where one byte would do (0x83 0x00 = 3). */
static void test_variant_mcsim(void **state)
{
    const uint8_t d[] = {0x83, 0x00, 0x01, 0x02, 0x03, 0x01, 0x0A, 0x0B, 0x0C, 0x00, 0x01, 0x84, 0x00,
                         0x01, 0x11, 0x12, 0x13, 0x01, 0x21, 0x22, 0x23, 0x02, 0x31, 0x32, 0x33, 0x00, 0x01, 0x00};
    decode_ok(d, sizeof d, 4, 3, img43, 0);
}

static void test_two_byte_counts(void **state)
{
    enum { W = 300 };
    uint32_t want[W * 2];
    for (int i = 0; i < W * 2; i++)
        want[i] = i < W ? A : (i < W + 200 ? A : B);
    /* row 0: repeat 300 (0xAC 0x02); row 1: copy 200 (00 01 0xC8 0x01), repeat 100 B */
    const uint8_t d[] = {0xAC, 0x02, 0x01, 0x02, 0x03, 0x00, 0x01, 0xC8, 0x01, 0x64, 0x0A, 0x0B, 0x0C, 0x00, 0x01, 0x00};
    decode_ok(d, sizeof d, W, 2, want, 0);
    uint8_t enc[4096];
    long n = dlpc900_erle_encode(want, W, 2, enc, sizeof enc);
    assert_int_equal(n, sizeof d);
    assert_memory_equal(enc, d, sizeof d);
    /* a literal run over 127 pixels needs a 2-byte count: 0x00 then 0x80|n, n>>7 */
    uint32_t lit[130];
    for (int i = 0; i < 130; i++)
        lit[i] = (uint32_t)i * 0x010101u;
    n = dlpc900_erle_encode(lit, 130, 1, enc, sizeof enc);
    assert_int_equal(enc[0], 0);
    assert_int_equal(enc[1], 0x82);
    assert_int_equal(enc[2], 0x01);
    assert_int_equal(n, 3 + 130 * 3 + 3);
    decode_ok(enc, (size_t)n, 130, 1, lit, 0);
}

static void test_eol_and_padding(void **state)
{
    /* mid-row end of line: rest of the row stays 0, one warning */
    const uint8_t d[] = {0x02, 0x01, 0x02, 0x03, 0x00, 0x00, 0x04, 0x0A, 0x0B, 0x0C, 0x00, 0x01, 0x00, 0xEE, 0xEE};
    const uint32_t want[8] = {A, A, 0, 0, B, B, B, B};
    decode_ok(d, sizeof d, 4, 2, want, 1);
    /* all rows filled but no end of image: accepted with a warning */
    const uint8_t noend[] = {0x04, 0x01, 0x02, 0x03, 0x04, 0x0A, 0x0B, 0x0C};
    const uint32_t want2[8] = {A, A, A, A, B, B, B, B};
    decode_ok(noend, sizeof noend, 4, 2, want2, 1);
}

static void test_rejections(void **state)
{
    const uint8_t cross[] = {0x05, 0x01, 0x02, 0x03};
    decode_bad(cross, sizeof cross, 4, 1, "crosses the end of row");
    const uint8_t copy0[] = {0x00, 0x01, 0x02};
    decode_bad(copy0, sizeof copy0, 4, 1, "row 0");
    const uint8_t beyond[] = {0x04, 0x01, 0x02, 0x03, 0x01, 0x01, 0x02, 0x03};
    decode_bad(beyond, sizeof beyond, 4, 1, "after the last of 1 rows");
    const uint8_t early[] = {0x04, 0x01, 0x02, 0x03, 0x00, 0x01, 0x00};
    decode_bad(early, sizeof early, 4, 2, "ends after 1 of 2 rows");
    const uint8_t zero[] = {0x80, 0x00, 0x01, 0x02, 0x03};
    decode_bad(zero, sizeof zero, 4, 1, "zero pixels");
    const uint8_t trunc_lit[] = {0x00, 0x03, 0x01, 0x02, 0x03, 0x04};
    decode_bad(trunc_lit, sizeof trunc_lit, 4, 1, "literal");
    const uint8_t trunc_px[] = {0x04, 0x01};
    decode_bad(trunc_px, sizeof trunc_px, 4, 1, "repeat pixel");
    const uint8_t trunc_cnt[] = {0x84};
    decode_bad(trunc_cnt, sizeof trunc_cnt, 4, 1, "repeat count");
    decode_bad(NULL, 0, 4, 1, "ends after 0 of 1 rows");
}

static void test_rle_and_raw(void **state)
{
    /* plain RLE, 4×2: end of line mandatory, next line on a 4-byte boundary, end of image 00 01 */
    const uint8_t d[] = {0x04, 0x01, 0x02, 0x03, 0x00, 0x00, 0xAA, 0xAA, /* row 0 + pad to 8 */
                         0x00, 0x02, 0x11, 0x12, 0x13, 0x21, 0x22, 0x23, 0x02, 0x31, 0x32, 0x33, 0x00, 0x00,
                         0xAA, 0xAA, /* row 1 + pad to 24 */
                         0x00, 0x01, 0x00, 0x00};
    const uint32_t want[8] = {A, A, A, A, C, D, E, E};
    uint32_t px[8];
    sci_error err = {0};
    int warn = -1;
    assert_int_equal(dlpc900_rle_decode(d, sizeof d, 4, 2, px, NULL, &warn, &err), 0);
    assert_memory_equal(px, want, sizeof want);
    assert_int_equal(warn, 0);
    /* raw: rows padded to 16 bytes (5 px = 15 bytes → 16) */
    uint32_t img[10];
    for (int i = 0; i < 10; i++)
        img[i] = 0x10203u * (uint32_t)(i + 1);
    uint8_t raw[64];
    assert_int_equal(dlpc900_raw_size(5, 2), 32);
    assert_int_equal(dlpc900_raw_encode(img, 5, 2, raw, sizeof raw), 32);
    assert_int_equal(raw[15], 0);
    uint32_t back[10];
    assert_int_equal(dlpc900_raw_decode(raw, 32, 5, 2, back, &err), 0);
    assert_memory_equal(back, img, sizeof img);
    assert_int_equal(dlpc900_raw_decode(raw, 31, 5, 2, back, &err), SCI_EFORMAT);
}

static void test_header_variants(void **state)
{
    uint8_t *file;
    size_t len;
    int comp;
    sci_error err = {0};
    assert_int_equal(dlpc900_image_encode(img43, 4, 3, &file, &len, &comp, &err), 0);
    assert_int_equal(comp, DLPC900_COMP_ERLE);
    assert_int_equal(len, 48 + sizeof golden43);
    assert_memory_equal(file, "Spld", 4);
    assert_int_equal(file[4], 4);
    assert_int_equal(file[6], 3);
    assert_int_equal(file[8], sizeof golden43);  /* byte count excludes the header */
    assert_int_equal(file[12], 0xFF);            /* sub-image offset 0xFFFFFFFF */
    assert_int_equal(file[24], 1);
    assert_int_equal(file[25], 2);
    assert_int_equal(file[26], 1);
    assert_int_equal(file[29], 1);
    assert_memory_equal(file + 48, golden43, sizeof golden43);
    uint32_t *px;
    dlpc900_image_info info;
    assert_int_equal(dlpc900_image_decode(file, len, &px, &info, &err), 0);
    assert_memory_equal(px, img43, sizeof img43);
    assert_int_equal(info.warnings, 0);
    free(px);

    /* pycrafter erle.py variant: pixel format 0, isLeftImage 0, byte count = total length incl. padding */
    uint8_t *py = calloc(1, len + 3);
    memcpy(py, file, len);
    py[24] = 0;
    py[29] = 0;
    py[8] = (uint8_t)(len + 3);
    assert_int_equal(dlpc900_image_decode(py, len + 3, &px, &info, &err), 0);
    assert_memory_equal(px, img43, sizeof img43);
    assert_true(info.warnings >= 1);
    free(px);

    py[8] = 7; /* matches neither convention */
    assert_int_equal(dlpc900_image_decode(py, len + 3, &px, &info, &err), SCI_EFORMAT);
    assert_non_null(strstr(err.msg, "byte count"));
    file[25] = 3;
    assert_int_equal(dlpc900_image_decode(file, len, &px, &info, &err), SCI_EFORMAT);
    assert_non_null(strstr(err.msg, "error 9"));
    file[0] = 'X';
    assert_int_equal(dlpc900_image_decode(file, len, &px, &info, &err), SCI_EFORMAT);
    assert_non_null(strstr(err.msg, "Spld"));
    assert_int_equal(dlpc900_image_decode(file, 20, &px, &info, &err), SCI_EFORMAT);
    free(py);
    free(file);
}

/* Full DMD resolution: random, blocky (8×8 super-pixels), all-0, all-1; packing 24 masks and back. */
static void roundtrip_full(const char *what, int kind)
{
    enum { W = 1920, H = 1080 };
    size_t npx = (size_t)W * H;
    uint8_t *masks = malloc(npx * 24);
    sci_rng rng;
    sci_rng_seed(&rng, seed, (uint64_t)kind);
    for (int k = 0; k < 24; k++)
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                uint8_t v;
                if (kind == 0)
                    v = (uint8_t)(sci_rng_u64(&rng) & 1);
                else if (kind == 1)
                    v = (uint8_t)((((uint64_t)(x / 8) * 2654435761u + (uint64_t)(y / 8) * 40503u + (uint64_t)k * 97u) >> 7) & 1);
                else
                    v = kind == 3;
                masks[(size_t)k * npx + (size_t)y * W + x] = v;
            }
    uint32_t *px = malloc(npx * sizeof *px);
    dlpc900_image_pack_bytes(masks, W, H, 24, px);
    uint8_t *file;
    size_t len;
    int comp;
    sci_error err = {0};
    assert_int_equal(dlpc900_image_encode(px, W, H, &file, &len, &comp, &err), 0);
    printf("  %s: %zu bytes, compression %d\n", what, len, comp);
    if (kind == 0)
        assert_int_equal(comp, DLPC900_COMP_NONE); /* random masks do not compress: raw is smaller */
    else
        assert_int_equal(comp, DLPC900_COMP_ERLE);
    uint32_t *back;
    dlpc900_image_info info;
    assert_int_equal(dlpc900_image_decode(file, len, &back, &info, &err), 0);
    assert_memory_equal(back, px, npx * sizeof *px);
    uint8_t *m = malloc(npx);
    for (int k = 0; k < 24; k++) {
        dlpc900_image_unpack_bit(back, W, H, k, m);
        assert_memory_equal(m, masks + (size_t)k * npx, npx);
    }
    /* also force the ERLE path for random data and decode it */
    if (kind == 0) {
        uint8_t *erle = malloc(dlpc900_erle_bound(W, H));
        long n = dlpc900_erle_encode(px, W, H, erle, dlpc900_erle_bound(W, H));
        assert_true(n > 0);
        uint32_t *b2 = malloc(npx * sizeof *b2);
        assert_int_equal(dlpc900_erle_decode(erle, (size_t)n, W, H, b2, NULL, NULL, &err), 0);
        assert_memory_equal(b2, px, npx * sizeof *px);
        free(b2);
        free(erle);
    }
    free(m);
    free(back);
    free(file);
    free(px);
    free(masks);
}

static void test_full_random(void **state) { roundtrip_full("random", 0); }
static void test_full_blocky(void **state) { roundtrip_full("blocky 8x8", 1); }
static void test_full_zero(void **state) { roundtrip_full("all-0", 2); }
static void test_full_one(void **state) { roundtrip_full("all-1", 3); }

/* Small random images of every shape class, many seeds: encode → decode is the identity. */
static void test_random_small(void **state)
{
    sci_rng rng;
    sci_rng_seed(&rng, seed, 99);
    uint8_t *buf = malloc(dlpc900_erle_bound(200, 50));
    uint32_t *img = malloc(200 * 50 * sizeof *img), *back = malloc(200 * 50 * sizeof *back);
    for (int it = 0; it < 300; it++) {
        int w = 1 + (int)sci_rng_below(&rng, 200), h = 1 + (int)sci_rng_below(&rng, 50);
        int colours = 1 + (int)sci_rng_below(&rng, 4);
        for (int i = 0; i < w * h; i++) {
            int copy = i >= w && sci_rng_below(&rng, 3) == 0;
            img[i] = copy ? img[i - w] : (uint32_t)sci_rng_below(&rng, (uint64_t)colours) * 0x050301u;
        }
        long n = dlpc900_erle_encode(img, w, h, buf, dlpc900_erle_bound(w, h));
        assert_true(n > 0);
        sci_error err = {0};
        if (dlpc900_erle_decode(buf, (size_t)n, w, h, back, NULL, NULL, &err))
            fail_msg("seed %llu iteration %d (%d×%d): %s", (unsigned long long)seed, it, w, h, err.msg);
        assert_memory_equal(back, img, (size_t)w * h * sizeof *img);
    }
    free(buf);
    free(img);
    free(back);
}

int main(void)
{
    seed = getenv("SEED") ? strtoull(getenv("SEED"), NULL, 0) : (uint64_t)time(NULL);
    printf("test_dlpc900_erle: seed %llu (set SEED to repeat)\n", (unsigned long long)seed);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_golden_encode),   cmocka_unit_test(test_variant_e841018),
        cmocka_unit_test(test_variant_mcsim),   cmocka_unit_test(test_two_byte_counts),
        cmocka_unit_test(test_eol_and_padding), cmocka_unit_test(test_rejections),
        cmocka_unit_test(test_rle_and_raw),     cmocka_unit_test(test_header_variants),
        cmocka_unit_test(test_full_random),     cmocka_unit_test(test_full_blocky),
        cmocka_unit_test(test_full_zero),       cmocka_unit_test(test_full_one),
        cmocka_unit_test(test_random_small),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
