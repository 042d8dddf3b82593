/* Bit-exact unpacking of GREY, Y10, Y12, Y16 and Y10P, against hand-computed bytes and an independent
 * bit-reader reference, with padded strides and widths that are not multiples of 4. */
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

static void y10p_known_bytes(void **state)
{
    (void)state;
    /* pixels 0x3FF, 0x000, 0x155, 0x2AA: high bytes FF 00 55 AA; low bits 3,0,1,2 at 2j -> 0b10010011 */
    const uint8_t raw[5] = {0xFF, 0x00, 0x55, 0xAA, 0x93};
    uint16_t px[4] = {0};
    assert_int_equal(pixfmt_unpack(PIXFMT_Y10P, raw, sizeof raw, 5, 4, 1, px, NULL), 0);
    assert_int_equal(px[0], 0x3FF);
    assert_int_equal(px[1], 0x000);
    assert_int_equal(px[2], 0x155);
    assert_int_equal(px[3], 0x2AA);
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

/* Reference: read pixel x of a row by its definition, written differently from the library (bit positions
 * computed per pixel, no grouping loop). */
static uint16_t ref_pixel(enum pixfmt f, const uint8_t *row, uint32_t x)
{
    switch (f) {
    case PIXFMT_GREY: return row[x];
    case PIXFMT_Y10: return (uint16_t)(((unsigned)row[2 * x + 1] * 256u + row[2 * x]) % 1024u);
    case PIXFMT_Y12: return (uint16_t)(((unsigned)row[2 * x + 1] * 256u + row[2 * x]) % 4096u);
    case PIXFMT_Y16: return (uint16_t)((unsigned)row[2 * x + 1] * 256u + row[2 * x]);
    case PIXFMT_Y10P: {
        size_t group = x / 4, j = x % 4;
        unsigned hi = row[group * 5 + j], lo = (row[group * 5 + 4] / (1u << (2 * j))) % 4u;
        return (uint16_t)(hi * 4u + lo);
    }
    default: return 0;
    }
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
    assert_int_equal(pixfmt_check_fourcc(V4L2_PIX_FMT_SRGGB10P, 0, "cam", &err), -ENOTSUP);
    assert_non_null(strstr(err.msg, "colour"));
    assert_int_equal(pixfmt_classify_fourcc(V4L2_PIX_FMT_Y14, 0), PIXFMT_KIND_MONO_OTHER);
    char s[5];
    assert_string_equal(pixfmt_fourcc_str(V4L2_PIX_FMT_Y10, s), "Y10 ");
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
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
