/* recon/cnn/conv: the Winograd F(4×4, 3×3) layer against the direct definition, on sizes that are and are not
 * multiples of the tile, with and without bias and ReLU, one and two threads (bitwise the same), border kept zero. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "base/rng.h"
#include "recon/cnn/conv.h"

typedef struct layer_case {
    int cin, cout, h, w, relu, bias;
} layer_case;

/* Max |winograd − direct| over the valid values, relative to the largest |direct| (at least 1). */
static double compare(const layer_case *lc, int threads, unsigned seed)
{
    sci_rng rng;
    sci_rng_seed(&rng, seed, 1);
    const size_t nw = (size_t)lc->cout * lc->cin * 9;
    float *wt = malloc(nw * sizeof *wt), *bias = malloc((size_t)lc->cout * sizeof *bias);
    for (size_t i = 0; i < nw; i++)
        wt[i] = (sci_rng_uniformf(&rng) - 0.5f) * 2.0f / sqrtf((float)lc->cin * 9);
    for (int k = 0; k < lc->cout; k++)
        bias[k] = sci_rng_uniformf(&rng) - 0.5f;
    cnn_conv *c = NULL;
    sci_error err = {0};
    assert_int_equal(cnn_conv_new(lc->cin, lc->cout, wt, lc->bias ? bias : NULL, lc->relu ? CNN_RELU : CNN_LINEAR,
                                  &c, &err), 0);
    cnn_act in, out, ref;
    cnn_act_init(&in, lc->cin, lc->h, lc->w, calloc(cnn_act_floats(lc->cin, lc->h, lc->w), sizeof(float)));
    cnn_act_init(&out, lc->cout, lc->h, lc->w, calloc(cnn_act_floats(lc->cout, lc->h, lc->w), sizeof(float)));
    cnn_act_init(&ref, lc->cout, lc->h, lc->w, calloc(cnn_act_floats(lc->cout, lc->h, lc->w), sizeof(float)));
    for (int j = 0; j < lc->cin; j++)
        for (int y = 0; y < lc->h; y++)
            for (int x = 0; x < lc->w; x++)
                *cnn_act_at(&in, j, y, x) = sci_rng_uniformf(&rng);
    cnn_conv_ws *ws = cnn_conv_ws_new(lc->cin > lc->cout ? lc->cin : lc->cout, threads);
    assert_non_null(ws);
    cnn_conv_run(c, &in, &out, ws);
    cnn_conv_reference(c, &in, &ref);
    double worst = 0, scale = 1;
    for (int k = 0; k < lc->cout; k++)
        for (int y = 0; y < lc->h; y++)
            for (int x = 0; x < lc->w; x++) {
                double d = fabs(*cnn_act_at(&out, k, y, x) - *cnn_act_at(&ref, k, y, x));
                worst = d > worst ? d : worst;
                scale = fabs(*cnn_act_at(&ref, k, y, x)) > scale ? fabs(*cnn_act_at(&ref, k, y, x)) : scale;
            }
    /* the border (everything outside the valid values) must still be zero */
    size_t nonzero_border = 0;
    for (int k = 0; k < lc->cout; k++)
        for (int y = 0; y < out.hs; y++)
            for (int x = 0; x < out.ws; x++)
                if ((y < 1 || y > lc->h || x < 1 || x > lc->w) && out.data[(size_t)k * out.plane + (size_t)y * out.ws + x])
                    nonzero_border++;
    assert_int_equal(nonzero_border, 0);
    cnn_conv_ws_free(ws);
    cnn_conv_free(c);
    free(in.data);
    free(out.data);
    free(ref.data);
    free(wt);
    free(bias);
    return worst / scale;
}

static void test_winograd_matches_direct(void **state)
{
    (void)state;
    static const layer_case cases[] = {
        {5, 64, 16, 16, 1, 0}, {64, 64, 13, 17, 1, 1}, {64, 4, 7, 9, 0, 0}, {3, 5, 1, 1, 0, 1},
        {15, 96, 5, 6, 1, 0},  {96, 12, 33, 2, 0, 1},  {2, 3, 40, 37, 1, 1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        double e = compare(&cases[i], 1, 100 + (unsigned)i);
        printf("  conv %d->%d %dx%d relu %d bias %d: max relative difference %.2e\n", cases[i].cin, cases[i].cout,
               cases[i].h, cases[i].w, cases[i].relu, cases[i].bias, e);
        assert_true(e < 2e-5); /* F(4×4, 3×3) in float: ~1e-6 per layer; a wrong transform is O(1) */
    }
}

/* A wrong transform (e.g. a swapped row of Bᵀ) must be caught: the comparison is not vacuous. */
static void test_reference_differs_from_zero(void **state)
{
    (void)state;
    const layer_case lc = {4, 4, 8, 8, 0, 0};
    assert_true(compare(&lc, 1, 7) < 2e-5);
    float wt[4 * 4 * 9] = {0};
    wt[4] = 1; /* the centre tap of output 0 from input 0: an identity on channel 0 */
    cnn_conv *c = NULL;
    assert_int_equal(cnn_conv_new(4, 4, wt, NULL, CNN_LINEAR, &c, NULL), 0);
    cnn_act in, out;
    cnn_act_init(&in, 4, 8, 8, calloc(cnn_act_floats(4, 8, 8), sizeof(float)));
    cnn_act_init(&out, 4, 8, 8, calloc(cnn_act_floats(4, 8, 8), sizeof(float)));
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 8; x++)
            *cnn_act_at(&in, 0, y, x) = (float)(y * 8 + x);
    cnn_conv_ws *ws = cnn_conv_ws_new(4, 1);
    cnn_conv_run(c, &in, &out, ws);
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 8; x++) {
            assert_true(fabsf(*cnn_act_at(&out, 0, y, x) - (float)(y * 8 + x)) < 1e-4f);
            assert_true(fabsf(*cnn_act_at(&out, 1, y, x)) < 1e-6f);
        }
    cnn_conv_ws_free(ws);
    cnn_conv_free(c);
    free(in.data);
    free(out.data);
}

static void test_threads_bitwise_equal(void **state)
{
    (void)state;
    const int cin = 8, cout = 8, h = 70, w = 66; /* 18 × 17 tiles: several blocks */
    float *wt = malloc((size_t)cin * cout * 9 * sizeof *wt);
    sci_rng rng;
    sci_rng_seed(&rng, 5, 1);
    for (int i = 0; i < cin * cout * 9; i++)
        wt[i] = sci_rng_uniformf(&rng) - 0.5f;
    cnn_conv *c = NULL;
    assert_int_equal(cnn_conv_new(cin, cout, wt, NULL, CNN_RELU, &c, NULL), 0);
    cnn_act in, o1, o2;
    cnn_act_init(&in, cin, h, w, calloc(cnn_act_floats(cin, h, w), sizeof(float)));
    cnn_act_init(&o1, cout, h, w, calloc(cnn_act_floats(cout, h, w), sizeof(float)));
    cnn_act_init(&o2, cout, h, w, calloc(cnn_act_floats(cout, h, w), sizeof(float)));
    for (int j = 0; j < cin; j++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                *cnn_act_at(&in, j, y, x) = sci_rng_uniformf(&rng);
    cnn_conv_ws *w1 = cnn_conv_ws_new(8, 1), *w2 = cnn_conv_ws_new(8, 2);
    cnn_conv_run(c, &in, &o1, w1);
    cnn_conv_run(c, &in, &o2, w2);
    assert_memory_equal(o1.data, o2.data, cnn_act_floats(cout, h, w) * sizeof(float));
    cnn_conv_ws_free(w1);
    cnn_conv_ws_free(w2);
    cnn_conv_free(c);
    free(in.data);
    free(o1.data);
    free(o2.data);
    free(wt);
}

static void test_bad_sizes(void **state)
{
    (void)state;
    cnn_conv *c = (cnn_conv *)1;
    sci_error err = {0};
    float wt[9] = {0};
    assert_int_equal(cnn_conv_new(0, 1, wt, NULL, CNN_LINEAR, &c, &err), -22);
    assert_null(c);
    assert_non_null(strstr(err.msg, "bad channel counts"));
}

int main(void)
{
    cnn_blas_single_thread();
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_winograd_matches_direct),
        cmocka_unit_test(test_reference_differs_from_zero),
        cmocka_unit_test(test_threads_bitwise_equal),
        cmocka_unit_test(test_bad_sizes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
