/* recon/cnn/ffdnet: the C denoiser against PyTorch's FFDNet on the same inputs. The reference outputs are fixtures
 * (tests/fixtures/ffdnet/, made by bench/ffdnet_torch.py fixtures with Debian's python3-torch), so no PyTorch is
 * needed here: grey and colour, a 256×256 and an odd-sized image, σ = 6, 25, 50 (/255). Both product paths (AVX-512
 * where the CPU has it, OpenBLAS) are checked. Weights and shapes that are wrong are refused with a message. */
#include <jansson.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "recon/cnn/conv.h"
#include "recon/cnn/ffdnet.h"
#include "tests/helpers/testdata.h"

#define FIXTURES "tests/fixtures/ffdnet"
#define TOLERANCE 1e-4 /* max |C − PyTorch| on [0, 1] images */

static float *read_f32(const char *name, size_t count)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", FIXTURES, name);
    FILE *f = fopen(path, "rb");
    if (!f)
        fail_msg("fixture %s missing", path);
    float *v = malloc(count * sizeof *v);
    size_t got = fread(v, sizeof *v, count, f);
    fclose(f);
    if (got != count)
        fail_msg("fixture %s: %zu of %zu floats", path, got, count);
    return v;
}

static void test_matches_pytorch(void **state)
{
    (void)state;
    json_error_t je;
    json_t *manifest = json_load_file(FIXTURES "/manifest.json", 0, &je);
    if (!manifest)
        fail_msg(FIXTURES "/manifest.json: %s", je.text);
    json_t *cases = json_is_array(manifest) ? manifest : json_object_get(manifest, "cases");
    assert_true(json_array_size(cases) >= 12);
    int seen_grey_256 = 0, seen_rgb_odd = 0;
    size_t i;
    json_t *cs;
    json_array_foreach(cases, i, cs) {
        const char *weights = json_string_value(json_object_get(cs, "weights"));
        const int c = (int)json_integer_value(json_object_get(cs, "c"));
        const int h = (int)json_integer_value(json_object_get(cs, "h"));
        const int w = (int)json_integer_value(json_object_get(cs, "w"));
        const double sigma = json_number_value(json_object_get(cs, "sigma"));
        char wpath[4096], name[64];
        snprintf(name, sizeof name, "ffdnet/%s", weights);
        TESTDATA_REQUIRE(name, wpath);
        cnn_ffdnet *net = NULL;
        sci_error err = {0};
        if (cnn_ffdnet_load(wpath, &net, &err) < 0)
            fail_msg("%s", err.msg);
        assert_int_equal(cnn_ffdnet_channels(net), c);
        const size_t count = (size_t)c * h * w;
        float *in = read_f32(json_string_value(json_object_get(cs, "input")), count);
        float *want = read_f32(json_string_value(json_object_get(cs, "output")), count);
        float *got = malloc(count * sizeof *got);
        for (int portable = 0; portable < 2; portable++) {
            cnn_ffdnet_plan *p = NULL;
            assert_int_equal(cnn_ffdnet_plan_new(net, w, h, 2, &p, &err), 0);
            cnn_ffdnet_plan_portable(p, portable);
            cnn_ffdnet_denoise(p, in, (float)sigma, got);
            double worst = 0, moved = 0;
            for (size_t k = 0; k < count; k++) {
                worst = fmax(worst, fabs((double)got[k] - want[k]));
                moved = fmax(moved, fabs((double)want[k] - in[k]));
            }
            printf("  %s %dx%d sigma %5.1f/255 %-8s: max |C - PyTorch| %.2e (the network moved pixels by up to %.3f)\n",
                   c == 1 ? "grey  " : "colour", w, h, sigma * 255, portable ? "openblas" : "default", worst, moved);
            assert_true(worst <= TOLERANCE);
            assert_true(moved > 100 * TOLERANCE); /* the comparison is not of two identities */
            cnn_ffdnet_plan_free(p);
        }
        seen_grey_256 |= c == 1 && w == 256 && h == 256;
        seen_rgb_odd |= c == 3 && (w % 2 || h % 2);
        free(in);
        free(want);
        free(got);
        cnn_ffdnet_free(net);
    }
    assert_true(seen_grey_256 && seen_rgb_odd);
    json_decref(manifest);
}

/* A state dict of the wrong network, or with a tensor of the wrong shape, is refused naming file and tensor. */
static void test_wrong_network_refused(void **state)
{
    (void)state;
    char wpath[4096];
    TESTDATA_REQUIRE("ffdnet/net_gray.pth", wpath);
    cnn_ffdnet *net = NULL;
    sci_error err = {0};
    assert_int_equal(cnn_ffdnet_load(wpath, &net, &err), 0);
    assert_int_equal(cnn_ffdnet_layers(net), 15);
    assert_int_equal(cnn_ffdnet_features(net), 64);
    cnn_ffdnet_free(net);
    assert_true(cnn_ffdnet_load("/nonexistent/net.pth", &net, &err) < 0);
    assert_null(net);
    assert_non_null(strstr(err.msg, "/nonexistent/net.pth"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_matches_pytorch),
        cmocka_unit_test(test_wrong_network_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
