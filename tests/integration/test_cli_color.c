/* Colour SCI end to end through the real binary: the colour scene etc/scenes/cacti_color.json (Bayer
 * RGGB behind random masks) is simulated by `scicap sim` and reconstructed by `scicap recon` per CFA plane with
 * GAP-TV then demosaiced: RGB PSNR (mean over R, G, B) printed and recorded, RGB EXR frames and colour PNG
 * previews written; result.json's top-level PSNR is the RGB one (the mosaic's under "mosaic"), and trace.csv names
 * each row's CFA plane, iterations counting from 1 in each. Treating the same mosaic as a grey image (--cfa none) is far worse — that is what the colour
 * path is for. A grey scene writes no colour files (nothing is paid by monochrome scenes). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "tests/helpers/cli_child.h"
#include <jansson.h>

static char dir[] = "/tmp/scicap-test-cli-color-XXXXXX";
static char scicap[1024];

static int exists(const char *name)
{
    char path[2048];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return access(path, F_OK) == 0;
}

/* PNG colour type from the IHDR chunk: 2 = RGB, 0 = grey. */
static int png_color_type(const char *name)
{
    char path[2048];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "rb");
    unsigned char b[26] = {0};
    size_t got = f ? fread(b, 1, sizeof b, f) : 0;
    if (f)
        fclose(f);
    assert_int_equal(got, 26);
    assert_memory_equal(b + 1, "PNG", 3);
    return b[25];
}

static int setup(void **state) { return cli_child_setup(scicap, sizeof scicap, "scicap", dir); }

static int teardown(void **state) { return cli_child_remove_dir(dir); }

static void test_color_scene_end_to_end(void **state)
{
    assert_int_equal(cli_child_shell("%s sim etc/scenes/cacti_color.json -o %s/sim -q >/dev/null", scicap, dir), 0);
    json_t *man = cli_child_load_json(dir, "sim/problem.json");
    assert_string_equal(json_string_value(json_object_get(man, "cfa")), "RGGB");
    assert_string_equal(json_string_value(json_object_get(man, "truth_rgb")), "truth_rgb.json");
    json_decref(man);
    assert_int_equal(png_color_type("sim/preview_truth_rgb_000.png"), 2);

    assert_int_equal(cli_child_shell("%s recon %s/sim -o %s/rgb -q > %s/out.txt", scicap, dir, dir, dir), 0);
    assert_int_equal(cli_child_shell("grep -q 'mean .* RGB$' %s/out.txt", dir), 0); /* the RGB PSNR line is printed */
    cli_child_shell("cat %s/out.txt", dir);
    json_t *res = cli_child_load_json(dir, "rgb/result.json");
    json_t *color = json_object_get(res, "color");
    assert_non_null(color);
    assert_string_equal(json_string_value(json_object_get(color, "cfa")), "RGGB");
    assert_string_equal(json_string_value(json_object_get(color, "demosaic")), "mhc");
    const double rgb1 = json_number_value(json_object_get(json_object_get(color, "psnr_rgb_peak1_db"), "mean"));
    const double rgbm = json_number_value(json_object_get(json_object_get(color, "psnr_rgb_frame_max_db"), "mean"));
    /* the top-level PSNR is what the user sees: the RGB one; the raw mosaic's is kept under "mosaic" */
    assert_true(json_number_value(json_object_get(json_object_get(res, "psnr_peak1_db"), "mean")) == rgb1);
    assert_true(json_number_value(json_object_get(json_object_get(res, "psnr_frame_max_db"), "mean")) == rgbm);
    assert_non_null(json_object_get(json_object_get(res, "mosaic"), "psnr_peak1_db"));
    json_decref(res);
    printf("RGB PSNR %.2f dB (peak 1), %.2f dB (peak = frame max)\n", rgb1, rgbm);
    /* trace.csv: a plane column; each plane's iterations 1..100 */
    assert_int_equal(cli_child_shell("head -1 %s/rgb/trace.csv | grep -q ',plane$'", dir), 0);
    for (int pl = 1; pl <= 4; pl++)
        assert_int_equal(cli_child_shell("awk -F, -v p=%d 'NR > 1 && $NF == p { n++; if ($1 != n) bad = 1 } END { exit !(n == 100 "
                             "&& !bad) }' %s/rgb/trace.csv", pl, dir),
                         0);
    assert_true(rgb1 > 22.0); /* measured 24.00 */
    for (int f = 0; f < 8; f++) {
        char name[64];
        snprintf(name, sizeof name, "rgb/rgb_%03d.exr", f);
        assert_true(exists(name));
        snprintf(name, sizeof name, "rgb/preview_rgb_%03d.png", f);
        assert_int_equal(png_color_type(name), 2);
    }

    /* The same mosaic reconstructed as a grey image: its raw-mosaic PSNR is far below the colour result's. */
    assert_int_equal(cli_child_shell("%s recon %s/sim --cfa none -o %s/grey -q >/dev/null", scicap, dir, dir), 0);
    res = cli_child_load_json(dir, "grey/result.json");
    const double grey = json_number_value(json_object_get(json_object_get(res, "psnr_peak1_db"), "mean"));
    assert_null(json_object_get(res, "color"));
    json_decref(res);
    printf("as grey: %.2f dB on the raw mosaic\n", grey);
    assert_true(rgb1 > grey + 5);
    assert_false(exists("grey/preview_rgb_000.png"));

    /* NeRF methods are refused for a mosaic (usage error), naming the way out. */
    assert_int_equal(cli_child_shell("%s recon %s/sim --method scinerf -o %s/nerf -q 2>/dev/null", scicap, dir, dir), 2);
}

static void test_grey_scene_has_no_colour(void **state)
{
    assert_int_equal(cli_child_shell("%s sim etc/scenes/cacti_layers.json --snapshots 1 -o %s/grey-sim -q >/dev/null", scicap, dir),
                     0);
    json_t *man = cli_child_load_json(dir, "grey-sim/problem.json");
    assert_null(json_object_get(man, "cfa"));
    assert_null(json_object_get(man, "truth_rgb"));
    json_decref(man);
    assert_false(exists("grey-sim/preview_truth_rgb_000.png"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_color_scene_end_to_end),
        cmocka_unit_test(test_grey_scene_has_no_colour),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
