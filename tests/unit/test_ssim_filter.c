/* recon/metrics.c: the SSIM's Gaussian filter without clamps inside the frame gives the same SSIM, bit for bit, as
 * the filter that clamps every tap (a copy of it below), on frames from 1x1 to 640x480, narrower and shorter than
 * the window too. Both run through the same SSIM arithmetic (sci_ssim_frame_filtered), so only the filters differ. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "recon/metrics.h"
#include "recon/metrics_ssim.h"

#define SSIM_RADIUS SCI_SSIM_RADIUS

/* The filter as it was: every tap clamped to the frame. */
static void gauss_ref(const double *in, double *out, double *tmp, int w, int h, const double *g)
{
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            double s = 0;
            for (int k = -SSIM_RADIUS; k <= SSIM_RADIUS; k++) {
                int cc = c + k < 0 ? 0 : (c + k >= w ? w - 1 : c + k);
                s += g[k + SSIM_RADIUS] * in[(size_t)r * w + cc];
            }
            tmp[(size_t)r * w + c] = s;
        }
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            double s = 0;
            for (int k = -SSIM_RADIUS; k <= SSIM_RADIUS; k++) {
                int rr = r + k < 0 ? 0 : (r + k >= h ? h - 1 : r + k);
                s += g[k + SSIM_RADIUS] * tmp[(size_t)rr * w + c];
            }
            out[(size_t)r * w + c] = s;
        }
}

static void test_ssim_filter_bitwise(void **state)
{
    const int sizes[][2] = {{256, 256}, {1, 1}, {3, 20}, {11, 11}, {12, 12}, {37, 5}, {640, 480}, {10, 300}};
    for (size_t z = 0; z < sizeof sizes / sizeof sizes[0]; z++) {
        const int w = sizes[z][0], h = sizes[z][1];
        const size_t n = (size_t)w * h;
        float *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y);
        assert_non_null(x);
        assert_non_null(y);
        unsigned s = 1 + (unsigned)z;
        for (size_t i = 0; i < n; i++) {
            s = s * 1103515245u + 12345u;
            x[i] = (float)((s >> 8) & 0xffff) / 65535.f;
            y[i] = x[i] * 0.9f + 0.05f * (float)((s >> 4) & 0xff) / 255.f;
        }
        const double a = sci_ssim_frame(x, y, w, h, 1.0), b = sci_ssim_frame_filtered(x, y, w, h, 1.0, gauss_ref);
        if (memcmp(&a, &b, sizeof a) != 0)
            fail_msg("%dx%d: SSIM %.17g, with clamps everywhere %.17g", w, h, a, b);
        free(x);
        free(y);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_ssim_filter_bitwise)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
