/* io/gif.c: animated grey GIF previews with the fixed grey palette, decoded by another implementation
 * (OpenImageIO's GIF reader, on giflib): every frame comes back, every 8-bit value exactly; sizes that exercise the
 * LZW table's resets (more than 4096 codes), odd shapes, a single pixel; and the image.c path (scale, clamp,
 * rounding, NaN as black). */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "io/gif.h"
#include "io/image.h"

static char tmpdir[256];

static int setup(void **state)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/scicap-test-gif-XXXXXX");
    return mkdtemp(tmpdir) ? 0 : -1;
}

static int teardown(void **state)
{
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

/* Frames of one of three kinds: 0 noise (every value, long codes: the table fills and is reset many times),
 * 1 smooth ramps (long runs: long strings), 2 a constant. */
static unsigned char *frames_make(int w, int h, int n, int kind, unsigned seed)
{
    unsigned char *f = malloc((size_t)w * h * n);
    assert_non_null(f);
    unsigned s = seed;
    for (size_t i = 0; i < (size_t)w * h * n; i++) {
        s = s * 1103515245u + 12345u;
        const size_t x = i % (size_t)w, k = i / ((size_t)w * h);
        f[i] = kind == 0 ? (unsigned char)(s >> 16) : kind == 1 ? (unsigned char)((x + 7 * k) & 0xff) : 77;
    }
    return f;
}

static void check_decodes(const char *path, const unsigned char *want, int w, int h, int n)
{
    sci_cube *back = NULL;
    sci_error err = {0};
    if (sci_image_read(path, &back, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(back->w, w);
    assert_int_equal(back->h, h);
    assert_int_equal(back->n, n);
    /* the reader turns the RGB of a GIF into Rec. 709 luminance in float (0.2126 v + 0.7152 v + 0.0722 v, a few
     * ulps off v): the 8-bit value is what must come back */
    for (size_t i = 0; i < (size_t)w * h * n; i++)
        if (fabsf(back->data[i] - (float)want[i]) > 1e-3f)
            fail_msg("%s: %dx%dx%d, sample %zu (frame %zu) decodes as %g, written %d", path, w, h, n, i,
                     i / ((size_t)w * h), (double)back->data[i], want[i]);
    sci_cube_free(back);
}

static void test_gif_lossless_roundtrip(void **state)
{
    const struct { int w, h, n, kind; } cases[] = {
        {256, 256, 8, 0}, {256, 256, 8, 1}, {37, 21, 3, 0}, {1, 1, 1, 0}, {1, 1, 2, 2}, {1000, 3, 2, 0},
        {3, 1000, 1, 1}, {64, 64, 4, 2}, {300, 300, 1, 0},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        const int w = cases[c].w, h = cases[c].h, n = cases[c].n;
        unsigned char *f = frames_make(w, h, n, cases[c].kind, (unsigned)c + 1);
        char path[512];
        snprintf(path, sizeof path, "%s/g%zu.gif", tmpdir, c);
        sci_error err = {0};
        if (sci_gif_write_grey(path, f, w, h, n, 125, &err) < 0)
            fail_msg("%s", err.msg);
        check_decodes(path, f, w, h, n);
        free(f);
    }
}

/* The header: GIF89a, the global table is the grey ramp, the NETSCAPE loop, the delay in 1/100 s. */
static void test_gif_header_palette_delay(void **state)
{
    unsigned char px[4] = {0, 85, 170, 255}, *g = NULL;
    size_t len = 0;
    sci_error err = {0};
    assert_int_equal(sci_gif_encode_grey(px, 2, 2, 1, 125, &g, &len, &err), 0);
    assert_true(len > 13 + 768 + 19);
    assert_memory_equal(g, "GIF89a", 6);
    assert_int_equal(g[6] | g[7] << 8, 2);
    assert_int_equal(g[10], 0xf7);
    for (int v = 0; v < 256; v++)
        if (g[13 + 3 * v] != v || g[14 + 3 * v] != v || g[15 + 3 * v] != v)
            fail_msg("palette entry %d is %d,%d,%d", v, g[13 + 3 * v], g[14 + 3 * v], g[15 + 3 * v]);
    const unsigned char *ext = g + 13 + 768;
    assert_memory_equal(ext, "\x21\xff\x0bNETSCAPE2.0", 14);
    const unsigned char *gce = ext + 19;
    assert_memory_equal(gce, "\x21\xf9\x04", 3);
    assert_int_equal(gce[4] | gce[5] << 8, 13); /* 125 ms: 13 hundredths */
    assert_int_equal(g[len - 1], 0x3b);
    free(g);
    assert_int_equal(sci_gif_encode_grey(px, 0, 2, 1, 125, &g, &len, &err), -EINVAL);
    assert_int_equal(sci_gif_encode_grey(px, 70000, 1, 1, 125, &g, &len, &err), -EINVAL);
    assert_null(g);
}

/* The preview path: value × scale, rounded, clamped to 0..255, NaN as black; written atomically (no temporary
 * left beside). */
static void test_image_write_gif_values(void **state)
{
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, 40, 30, 3, NULL), 0);
    unsigned char *want = malloc(sci_cube_count(c));
    assert_non_null(want);
    for (size_t i = 0; i < sci_cube_count(c); i++) {
        const float v = (float)((int)(i % 301) - 20) / 255.0f * 1.1f;
        c->data[i] = i % 97 == 0 ? NAN : v;
        double s = i % 97 == 0 ? 0 : nearbyint((double)v * 255.0);
        want[i] = (unsigned char)(s < 0 ? 0 : s > 255 ? 255 : s);
    }
    char path[512];
    snprintf(path, sizeof path, "%s/preview.gif", tmpdir);
    sci_error err = {0};
    int factor = 0;
    if (sci_image_write_gif_opt(path, c, 255.0, 125, &factor, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(factor, 1);
    check_decodes(path, want, 40, 30, 3);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "ls '%s' | grep -c tmp", tmpdir);
    FILE *p = popen(cmd, "r");
    int n = -1;
    assert_int_equal(fscanf(p, "%d", &n), 1);
    pclose(p);
    assert_int_equal(n, 0);
    free(want);
    sci_cube_free(c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_gif_lossless_roundtrip),
        cmocka_unit_test(test_gif_header_palette_delay),
        cmocka_unit_test(test_image_write_gif_values),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
