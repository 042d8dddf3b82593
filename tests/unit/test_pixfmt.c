/* Bit-exact unpacking of GREY, Y10, Y12, Y16, Y10P and the Bayer formats (8/10/12/16 bit and MIPI 10P, four filter
 * orders), against hand-computed bytes and an independent bit-reader reference, with padded strides and widths
 * that are not multiples of 4. Bayer frames must come out as the raw mosaic, sample for sample. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include <errno.h>
#include <linux/videodev2.h>

#include "base/rng.h"
#include "drivers/pixfmt.h"

static uint64_t test_seed(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    uint64_t seed = s ? strtoull(s, NULL, 0) : 20240611u;
    printf("test_pixfmt: seed %llu (set SCICAP_TEST_SEED to change)\n", (unsigned long long)seed);
    return seed;
}

static uint64_t g_seed;

/* The four samples unpacked into px are a, b, c, d. */
static void expect_px4(const uint16_t *px, uint16_t a, uint16_t b, uint16_t c, uint16_t d)
{
    const uint16_t want[4] = {a, b, c, d};
    for (int i = 0; i < 4; i++)
        if (px[i] != want[i])
            fail_msg("sample %d: 0x%X, want 0x%X", i, px[i], want[i]);
}

static void y10p_known_bytes(void **state)
{
    (void)state;
    /* pixels 0x3FF, 0x000, 0x155, 0x2AA: high bytes FF 00 55 AA; low bits 3,0,1,2 at 2j -> 0b10010011 */
    const uint8_t raw[5] = {0xFF, 0x00, 0x55, 0xAA, 0x93};
    uint16_t px[4] = {0};
    assert_int_equal(pixfmt_unpack(PIXFMT_Y10P, raw, sizeof raw, 5, 4, 1, px, NULL), 0);
    expect_px4(px, 0x3FF, 0x000, 0x155, 0x2AA);
    uint8_t back[5];
    assert_int_equal(pixfmt_pack(PIXFMT_Y10P, px, 4, 1, back, sizeof back, 5, NULL), 0);
    assert_memory_equal(back, raw, 5);
}

static void y16_y10_y12_grey_known_bytes(void **state)
{
    (void)state;
    const uint8_t le[4] = {0x34, 0x12, 0xFF, 0xFF};
    uint16_t px[2];
    assert_int_equal(pixfmt_unpack(PIXFMT_Y16, le, 4, 4, 2, 1, px, NULL), 0);
    assert_int_equal(px[0], 0x1234);
    assert_int_equal(px[1], 0xFFFF);
    /* Garbage in the unused upper bits is masked: a 10-bit sample never exceeds 1023. */
    assert_int_equal(pixfmt_unpack(PIXFMT_Y10, le, 4, 4, 2, 1, px, NULL), 0);
    assert_int_equal(px[0], 0x234);
    assert_int_equal(px[1], 0x3FF);
    assert_int_equal(pixfmt_unpack(PIXFMT_Y12, le, 4, 4, 2, 1, px, NULL), 0);
    assert_int_equal(px[0], 0x234);
    assert_int_equal(px[1], 0xFFF);
    const uint8_t g[2] = {0, 255};
    assert_int_equal(pixfmt_unpack(PIXFMT_GREY, g, 2, 2, 2, 1, px, NULL), 0);
    assert_int_equal(px[0], 0);
    assert_int_equal(px[1], 255);
}

/* The reference's own idea of each format, from its name alone (not from the library's table): "GREY" and names
 * ending in 8 are one byte; names ending in 10P are MIPI RAW10; the rest are 16-bit little-endian containers with
 * the number in the name as their significant bits. */
enum ref_layout { REF_U8, REF_LE16, REF_RAW10P };
static enum ref_layout ref_layout_of(const char *name, unsigned *bits)
{
    size_t n = strlen(name);
    if (strcmp(name, "GREY") == 0 || name[n - 1] == '8') {
        *bits = 8;
        return REF_U8;
    }
    if (name[n - 1] == 'P') {
        *bits = 10;
        return REF_RAW10P;
    }
    const char *d = name + n;
    while (d > name && d[-1] >= '0' && d[-1] <= '9')
        d--;
    *bits = (unsigned)atoi(d);
    return REF_LE16;
}

/* Reference: read pixel x of a row by its definition, written differently from the library (bit positions
 * computed per pixel, no grouping loop). */
static uint16_t ref_pixel(enum pixfmt f, const uint8_t *row, uint32_t x)
{
    unsigned bits;
    switch (ref_layout_of(pixfmt_name(f), &bits)) {
    case REF_U8: return row[x];
    case REF_LE16: return (uint16_t)(((unsigned)row[2 * x + 1] * 256u + row[2 * x]) % (1u << bits));
    case REF_RAW10P: {
        size_t group = x / 4, j = x % 4;
        unsigned hi = row[group * 5 + j], lo = (row[group * 5 + 4] / (1u << (2 * j))) % 4u;
        return (uint16_t)(hi * 4u + lo);
    }
    }
    return 0;
}

static void random_buffers_match_reference(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, g_seed, 1);
    for (int f = PIXFMT_GREY; f < PIXFMT_COUNT; f++) {
        for (int trial = 0; trial < 40; trial++) {
            uint32_t w = 1 + (uint32_t)sci_rng_below(&rng, 67), h = 1 + (uint32_t)sci_rng_below(&rng, 9);
            size_t stride = pixfmt_min_stride((enum pixfmt)f, w) + sci_rng_below(&rng, 3) * 8;
            size_t len = stride * h;
            uint8_t *raw = malloc(len);
            uint16_t *px = malloc(sizeof *px * w * h);
            for (size_t i = 0; i < len; i++)
                raw[i] = (uint8_t)sci_rng_below(&rng, 256);
            assert_int_equal(pixfmt_unpack((enum pixfmt)f, raw, len, stride, w, h, px, NULL), 0);
            for (uint32_t y = 0; y < h; y++)
                for (uint32_t x = 0; x < w; x++)
                    if (px[y * w + x] != ref_pixel((enum pixfmt)f, raw + y * stride, x))
                        fail_msg("%s %ux%u stride %zu: pixel (%u,%u) = %u, reference %u", pixfmt_name((enum pixfmt)f),
                                 w, h, stride, x, y, px[y * w + x], ref_pixel((enum pixfmt)f, raw + y * stride, x));
            free(raw);
            free(px);
        }
    }
}

static void pack_unpack_round_trip(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, g_seed, 2);
    for (int f = PIXFMT_GREY; f < PIXFMT_COUNT; f++) {
        int bits = pixfmt_info_get((enum pixfmt)f)->bits_per_sample;
        for (int trial = 0; trial < 20; trial++) {
            uint32_t w = 1 + (uint32_t)sci_rng_below(&rng, 41), h = 1 + (uint32_t)sci_rng_below(&rng, 7);
            size_t stride = pixfmt_min_stride((enum pixfmt)f, w) + sci_rng_below(&rng, 5);
            size_t len = stride * (h - 1) + pixfmt_min_stride((enum pixfmt)f, w); /* tight: no tail padding */
            uint16_t *in = malloc(sizeof *in * w * h), *out = malloc(sizeof *out * w * h);
            uint8_t *raw = malloc(len);
            for (size_t i = 0; i < (size_t)w * h; i++)
                in[i] = (uint16_t)sci_rng_below(&rng, 1u << bits);
            in[0] = (uint16_t)((1u << bits) - 1); /* the extremes are always present */
            in[w * h - 1] = 0;
            assert_int_equal(pixfmt_pack((enum pixfmt)f, in, w, h, raw, len, stride, NULL), 0);
            assert_int_equal(pixfmt_unpack((enum pixfmt)f, raw, len, stride, w, h, out, NULL), 0);
            assert_memory_equal(in, out, sizeof *in * w * h);
            free(in);
            free(out);
            free(raw);
        }
    }
}

static void bad_geometry_is_refused(void **state)
{
    (void)state;
    uint8_t raw[64] = {0};
    uint16_t px[64];
    sci_error err = {0};
    assert_int_equal(pixfmt_unpack(PIXFMT_Y16, raw, 64, 10, 8, 1, px, &err), SCI_ESHAPE);
    assert_non_null(strstr(err.msg, "stride 10"));
    assert_int_equal(pixfmt_unpack(PIXFMT_Y16, raw, 31, 16, 8, 2, px, &err), SCI_ESHAPE);
    assert_non_null(strstr(err.msg, "31 bytes"));
    assert_int_equal(pixfmt_unpack(PIXFMT_Y10P, raw, 64, 5, 5, 1, px, &err), SCI_ESHAPE); /* 5 px need 10 bytes */
    assert_int_equal(pixfmt_unpack(PIXFMT_NONE, raw, 64, 8, 4, 1, px, &err), -EINVAL);
    assert_int_equal(pixfmt_min_stride(PIXFMT_Y10P, 1920), 2400);
    assert_int_equal(pixfmt_min_stride(PIXFMT_Y10P, 5), 10);
}

static void names_and_fourccs(void **state)
{
    (void)state;
    enum pixfmt f;
    sci_error err = {0};
    assert_int_equal(pixfmt_from_name("y10p", &f, &err), 0);
    assert_int_equal(f, PIXFMT_Y10P);
    assert_int_equal(pixfmt_from_name("YUYV", &f, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "\"YUYV\""));
    assert_int_equal(pixfmt_from_fourcc(V4L2_PIX_FMT_Y12), PIXFMT_Y12);
    assert_int_equal(pixfmt_from_fourcc(V4L2_PIX_FMT_YUYV), PIXFMT_NONE);
    assert_int_equal(pixfmt_check_fourcc(V4L2_PIX_FMT_Y16, 0, "/dev/video0", &err), 0);
    assert_int_equal(pixfmt_check_fourcc(V4L2_PIX_FMT_MJPEG, 1, "/dev/video0", &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, "/dev/video0: format MJPG is compressed"));
    assert_int_equal(pixfmt_check_fourcc(V4L2_PIX_FMT_YUYV, 0, "cam", &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, "YUYV is a colour format"));
    assert_int_equal(pixfmt_check_fourcc(V4L2_PIX_FMT_SRGGB12P, 0, "cam", &err), -ENOTSUP); /* no unpacker */
    assert_non_null(strstr(err.msg, "colour"));
    assert_int_equal(pixfmt_classify_fourcc(V4L2_PIX_FMT_Y14, 0), PIXFMT_KIND_MONO_OTHER);
    char s[5];
    assert_string_equal(pixfmt_fourcc_str(V4L2_PIX_FMT_Y10, s), "Y10 ");
}

/* The Bayer formats through hand-computed bytes: each unpacks exactly like its monochrome twin (the mosaic is
 * kept sample for sample), upper container bits are masked, and the filter order travels in pixfmt_info.cfa. */
static void bayer_known_bytes(void **state)
{
    (void)state;
    /* a 2x2 RGGB tile in 12-bit containers, garbage in the top nibbles: R=0x123 G=0xABC / G=0x000 B=0xFFF */
    const uint8_t rg12[8] = {0x23, 0xF1, 0xBC, 0x7A, 0x00, 0x00, 0xFF, 0xFF};
    uint16_t px[4] = {0};
    assert_int_equal(pixfmt_unpack(PIXFMT_SRGGB12, rg12, sizeof rg12, 4, 2, 2, px, NULL), 0);
    expect_px4(px, 0x123, 0xABC, 0x000, 0xFFF);
    /* 10-bit containers keep 10 bits; 16-bit keep all */
    assert_int_equal(pixfmt_unpack(PIXFMT_SGRBG10, rg12, sizeof rg12, 4, 2, 2, px, NULL), 0);
    assert_int_equal(px[0], 0x123);
    assert_int_equal(px[1], 0x2BC);
    assert_int_equal(px[3], 0x3FF);
    assert_int_equal(pixfmt_unpack(PIXFMT_SBGGR16, rg12, sizeof rg12, 4, 2, 2, px, NULL), 0);
    assert_int_equal(px[0], 0xF123);
    assert_int_equal(px[1], 0x7ABC);
    /* 8-bit: bytes as they are, rows `stride` apart (2 pixels, stride 3: one padding byte per row) */
    const uint8_t g8[6] = {10, 200, 0xEE, 0, 255, 0xEE};
    assert_int_equal(pixfmt_unpack(PIXFMT_SGBRG8, g8, sizeof g8, 3, 2, 2, px, NULL), 0);
    expect_px4(px, 10, 200, 0, 255);
    /* MIPI RAW10 Bayer: the Y10P example bytes give the same samples */
    const uint8_t raw[5] = {0xFF, 0x00, 0x55, 0xAA, 0x93};
    assert_int_equal(pixfmt_unpack(PIXFMT_SBGGR10P, raw, sizeof raw, 5, 4, 1, px, NULL), 0);
    expect_px4(px, 0x3FF, 0x000, 0x155, 0x2AA);
    assert_int_equal(pixfmt_min_stride(PIXFMT_SRGGB10P, 1920), 2400);
    assert_int_equal(pixfmt_min_stride(PIXFMT_SRGGB16, 7), 14);
    assert_int_equal(pixfmt_min_stride(PIXFMT_SBGGR8, 7), 7);
}

static void bayer_names_fourccs_and_cfa(void **state)
{
    (void)state;
    static const struct {
        const char *name;
        uint32_t fourcc;
        int bits;
        const char *cfa;
    } want[] = {
        {"SRGGB8", V4L2_PIX_FMT_SRGGB8, 8, "RGGB"},     {"SGRBG8", V4L2_PIX_FMT_SGRBG8, 8, "GRBG"},
        {"SGBRG8", V4L2_PIX_FMT_SGBRG8, 8, "GBRG"},     {"SBGGR8", V4L2_PIX_FMT_SBGGR8, 8, "BGGR"},
        {"SRGGB10", V4L2_PIX_FMT_SRGGB10, 10, "RGGB"},  {"SGRBG10", V4L2_PIX_FMT_SGRBG10, 10, "GRBG"},
        {"SGBRG10", V4L2_PIX_FMT_SGBRG10, 10, "GBRG"},  {"SBGGR10", V4L2_PIX_FMT_SBGGR10, 10, "BGGR"},
        {"SRGGB12", V4L2_PIX_FMT_SRGGB12, 12, "RGGB"},  {"SGRBG12", V4L2_PIX_FMT_SGRBG12, 12, "GRBG"},
        {"SGBRG12", V4L2_PIX_FMT_SGBRG12, 12, "GBRG"},  {"SBGGR12", V4L2_PIX_FMT_SBGGR12, 12, "BGGR"},
        {"SRGGB16", V4L2_PIX_FMT_SRGGB16, 16, "RGGB"},  {"SGRBG16", V4L2_PIX_FMT_SGRBG16, 16, "GRBG"},
        {"SGBRG16", V4L2_PIX_FMT_SGBRG16, 16, "GBRG"},  {"SBGGR16", V4L2_PIX_FMT_SBGGR16, 16, "BGGR"},
        {"SRGGB10P", V4L2_PIX_FMT_SRGGB10P, 10, "RGGB"}, {"SGRBG10P", V4L2_PIX_FMT_SGRBG10P, 10, "GRBG"},
        {"SGBRG10P", V4L2_PIX_FMT_SGBRG10P, 10, "GBRG"}, {"SBGGR10P", V4L2_PIX_FMT_SBGGR10P, 10, "BGGR"},
    };
    sci_error err = {0};
    int bayer = 0;
    for (int f = PIXFMT_NONE + 1; f < PIXFMT_COUNT; f++)
        bayer += pixfmt_info_get((enum pixfmt)f)->cfa != PIXFMT_CFA_NONE;
    assert_int_equal(bayer, (int)(sizeof want / sizeof want[0])); /* every Bayer format is in the table below */
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++) {
        enum pixfmt f = PIXFMT_NONE;
        assert_int_equal(pixfmt_from_name(want[i].name, &f, &err), 0);
        const pixfmt_info *in = pixfmt_info_get(f);
        assert_non_null(in);
        assert_string_equal(in->name, want[i].name);
        assert_int_equal(in->fourcc, want[i].fourcc);
        assert_int_equal(in->bits_per_sample, want[i].bits);
        assert_string_equal(pixfmt_cfa_name(in->cfa), want[i].cfa);
        assert_int_equal(pixfmt_from_fourcc(want[i].fourcc), f);
        assert_int_equal(pixfmt_check_fourcc(want[i].fourcc, 0, "cam", &err), 0);
        /* the monochrome twin has the same layout and depth, and maps back */
        enum pixfmt mono = pixfmt_with_cfa(f, PIXFMT_CFA_NONE);
        assert_int_not_equal(mono, PIXFMT_NONE);
        assert_int_equal(pixfmt_info_get(mono)->bits_per_sample, want[i].bits);
        assert_int_equal(pixfmt_min_stride(mono, 13), pixfmt_min_stride(f, 13));
        assert_int_equal(pixfmt_with_cfa(mono, in->cfa), f);
    }
    assert_int_equal(pixfmt_with_cfa(PIXFMT_Y12, PIXFMT_CFA_GBRG), PIXFMT_SGBRG12);
    assert_int_equal(pixfmt_with_cfa(PIXFMT_Y10P, PIXFMT_CFA_RGGB), PIXFMT_SRGGB10P);
    assert_int_equal(pixfmt_with_cfa(PIXFMT_Y10, PIXFMT_CFA_RGGB), PIXFMT_SRGGB10); /* not the packed one */
    assert_int_equal(pixfmt_with_cfa(PIXFMT_NONE, PIXFMT_CFA_RGGB), PIXFMT_NONE);
    assert_int_equal(pixfmt_info_get(PIXFMT_Y16)->cfa, PIXFMT_CFA_NONE);
    assert_string_equal(pixfmt_cfa_name(PIXFMT_CFA_NONE), "none");
    enum pixfmt g;
    assert_int_equal(pixfmt_from_name("BayerRG8", &g, &err), -EINVAL); /* GenICam names are the backend's */
    assert_non_null(strstr(err.msg, "Bayer S{RGGB,GRBG,GBRG,BGGR}"));
}

int main(void)
{
    g_seed = test_seed();
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(y10p_known_bytes),
        cmocka_unit_test(y16_y10_y12_grey_known_bytes),
        cmocka_unit_test(random_buffers_match_reference),
        cmocka_unit_test(pack_unpack_round_trip),
        cmocka_unit_test(bad_geometry_is_refused),
        cmocka_unit_test(names_and_fourccs),
        cmocka_unit_test(bayer_known_bytes),
        cmocka_unit_test(bayer_names_fourccs_and_cfa),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
