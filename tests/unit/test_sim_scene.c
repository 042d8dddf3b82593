/* Scene files: the default scene loads, every kind of mistake is reported at file:line:column with its key path,
 * and command-line overrides re-derive what depends on them. Also the mask kinds. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "io/image.h"
#include "sim/default_scene.h"
#include "sim/masks.h"
#include "sim/simulate.h"

static void test_default_scene_loads(void **state)
{
    sim_scene *sc;
    sci_error err = {0};
    if (sim_default_scene_load(&sc, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(sc->kind, SIM_SCENE_VIDEO2D);
    assert_int_equal(sc->w, 256);
    assert_int_equal(sc->h, 256);
    assert_int_equal(sc->n, 8);
    assert_int_equal(sc->video2d.nlayers, 3);
    assert_int_equal(sc->fx.listed, 0);
    /* Nearest layer first: the disc (listed last). */
    assert_int_equal(sc->video2d.layer[0].shape, SIM_SHAPE_DISC);
    assert_int_equal(sc->video2d.layer[2].shape, SIM_SHAPE_RECT);
    sim_scene_free(sc);
}

typedef struct bad_case {
    const char *text;
    const char *expect; /* substring of the message, including file:line:col */
} bad_case;

#define HEAD "{\n  \"kind\": \"video2d\",\n  \"width\": 32, \"height\": 32,\n"
#define LAYER "  \"layers\": [{\"texture\": {\"type\": \"constant\"}}]"

static void test_positioned_errors(void **state)
{
    static const bad_case cases[] = {
        {"{\n  \"kind\": \"video2d\",\n  \"width\": -4, \"height\": 32\n}", "t.json:3:3: width: must be in [1, 16384] (got -4)"},
        {HEAD "  \"colour\": 3,\n" LAYER "\n}", "t.json:4:3: colour: unknown key"},
        {HEAD LAYER ",\n  \"effects\": {\"shot_nosie\": true}\n}", "t.json:5:15: effects.shot_nosie: unknown key"},
        {HEAD LAYER ",\n  \"effects\": {\n    \"read_noise\": {\"sigma_e\": -1}\n  }\n}",
         "t.json:6:20: effects.read_noise.sigma_e: must be in [0, 1e+06] (got -1)"},
        {HEAD "  \"layers\": [\n    {\"texture\": {\"type\": \"constant\"}},\n    {\"texture\": {\"type\": \"plaid\"}}\n  ]\n}",
         "t.json:6:18: layers[1].texture.type: unknown value \"plaid\""},
        {HEAD LAYER ",\n  \"camera\": {}\n}", "t.json:5:3: camera: belongs to static3d scenes"},
        {HEAD LAYER ",\n  \"masks\": {\"type\": \"file\"}\n}", "t.json:5:3: masks.path: required key is missing"},
        {HEAD LAYER ",\n  \"masks\": {\"type\": \"random\", \"density\": 1.5}\n}",
         "t.json:5:31: masks.density: must be in"},
        {HEAD "  \"layers\": [{\"shape\": \"polygon\", \"texture\": {\"type\": \"constant\"}}]\n}",
         "t.json:4:14: layers[0]: a polygon needs \"vertices\" or \"sides\""},
        {HEAD "  \"layers\": [{\"texture\": {\"type\": \"image\", \"path\": \"/nonexistent/x.png\"}}]\n}",
         "t.json:4:44: layers[0].texture.path: /nonexistent/x.png"},
        {HEAD "  \"layers\": [{\"texture\": {\"type\": \"constant\"}]\n}", "t.json:4:46: '}' expected"},
        {"{\n  \"kind\": \"static3d\",\n  \"width\": 32, \"height\": 32,\n  \"objects\": [{\"type\": \"sphere\","
         " \"radius\": 1, \"texture\": {\"type\": \"constant\"}}]\n}",
         "t.json:1:1: camera: required key is missing"},
        {"{\n  \"kind\": \"static3d\",\n  \"width\": 32, \"height\": 32, \"frames\": 8,\n  \"objects\": [{\"type\": "
         "\"sphere\", \"radius\": 1, \"texture\": {\"type\": \"constant\"}}],\n  \"camera\": {\"poses\": []}\n}",
         "t.json:5:14: camera.poses: must be an array of 8 poses"},
        {"{\n  \"kind\": \"static3d\",\n  \"width\": 32, \"height\": 32,\n  \"objects\": [{\"type\": \"box\","
         " \"texture\": {\"type\": \"constant\"}}],\n  \"camera\": {\"start\": {\"position\": [0, 0, 0]}}\n}",
         "t.json:4:15: objects[0].size: required key is missing"},
        {"{\n  \"kind\": \"static3d\",\n  \"width\": 32, \"height\": 32,\n  \"objects\": [{\"type\": \"sphere\","
         " \"radius\": 1, \"texture\": {\"type\": \"constant\"}}],\n  \"camera\": {\"start\": {\"position\": [0, 0, 0],"
         " \"look_at\": [0, 0, 0]}}\n}",
         "t.json:5:14: camera.start: look_at equals position"},
        {"{\n  \"kind\": \"static3d\",\n  \"width\": 32, \"height\": 32,\n  \"objects\": [{\"type\": \"sphere\","
         " \"radius\": 1, \"texture\": {\"type\": \"constant\"}}],\n  \"camera\": {\"start\": {\"matrix\": "
         "[1,0,0,0, 0,2,0,0, 0,0,1,0]}}\n}",
         "t.json:5:24: camera.start.matrix: the 3×3 part must be a rotation"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        sim_scene *sc = NULL;
        sci_error err = {0};
        int rc = sim_scene_load_string(&sc, "t.json", cases[i].text, NULL, &err);
        printf("case %zu: %s\n", i, err.msg);
        assert_true(rc < 0);
        assert_null(sc);
        if (!strstr(err.msg, cases[i].expect))
            fail_msg("case %zu: expected \"%s\" in \"%s\"", i, cases[i].expect, err.msg);
    }
}

static void test_overrides(void **state)
{
    sim_scene *sc;
    sci_error err = {0};
    assert_int_equal(sim_default_scene_load(&sc, &err), 0);
    sci_cube *m1, *m2;
    assert_int_equal(sim_masks_make(&sc->masks, sc->w, sc->h, sc->n, sc->seed, &m1, &err), 0);
    assert_int_equal(sim_scene_set_seed(sc, 99, &err), 0);
    assert_int_equal(sc->seed, 99);
    assert_int_equal(sim_masks_make(&sc->masks, sc->w, sc->h, sc->n, sc->seed, &m2, &err), 0);
    assert_memory_not_equal(m1->data, m2->data, sci_cube_count(m1) * 4);
    assert_int_equal(sim_scene_set_snapshots(sc, 3, &err), 0);
    assert_int_equal(sc->snapshots, 3);
    assert_int_equal(sc->seed, 99);
    assert_int_equal(json_integer_value(json_object_get(sc->record, "snapshots")), 3);
    assert_true(sim_scene_set_snapshots(sc, 0, &err) < 0);
    sci_cube_free(m1);
    sci_cube_free(m2);
    sim_scene_free(sc);
}

static sci_cube *masks_of(const char *masks_json, int w, int h, int n)
{
    char text[2048];
    snprintf(text, sizeof text,
             "{\"kind\": \"video2d\", \"width\": %d, \"height\": %d, \"frames\": %d,"
             " \"layers\": [{\"texture\": {\"type\": \"constant\"}}], \"masks\": %s}",
             w, h, n, masks_json);
    sim_scene *sc;
    sci_error err = {0};
    if (sim_scene_load_string(&sc, "m.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube *m;
    if (sim_masks_make(&sc->masks, w, h, n, sc->seed, &m, &err) < 0)
        fail_msg("%s", err.msg);
    sim_scene_free(sc);
    return m;
}

static void test_mask_kinds(void **state)
{
    const int w = 64, h = 48, n = 6;
    /* Random: density. */
    sci_cube *m = masks_of("{\"type\": \"random\", \"density\": 0.3}", w, h, n);
    double on = 0;
    for (size_t i = 0; i < sci_cube_count(m); i++) {
        assert_true(m->data[i] == 0 || m->data[i] == 1);
        on += m->data[i];
    }
    printf("random: density %.3f (asked 0.3)\n", on / sci_cube_count(m));
    assert_true(fabs(on / sci_cube_count(m) - 0.3) < 0.02);
    sci_cube_free(m);
    /* Shifting: frame i is frame 0 shifted by i·step pixels, both directions and signs. */
    const char *shifting[] = {"{\"type\": \"shifting\", \"direction\": \"y\"}",
                              "{\"type\": \"shifting\", \"direction\": \"x\", \"step\": -2}"};
    for (int t = 0; t < 2; t++) {
        m = masks_of(shifting[t], w, h, n);
        int dx = t ? -2 : 0, dy = t ? 0 : 1;
        for (int k = 1; k < n; k++)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) {
                    int sx = x - k * dx, sy = y - k * dy;
                    if (sx >= 0 && sx < w && sy >= 0 && sy < h)
                        assert_true(sci_cube_frame(m, k)[y * w + x] == sci_cube_frame(m, 0)[sy * w + sx]);
                }
        /* and the entering rows/columns are fresh pattern, not a wrap-around */
        assert_memory_not_equal(sci_cube_frame(m, 1), sci_cube_frame(m, 0), (size_t)w * h * 4);
        sci_cube_free(m);
    }
    /* Superpixel: constant over 4×4 blocks. */
    m = masks_of("{\"type\": \"superpixel\", \"block\": 4}", w, h, n);
    for (int k = 0; k < n; k++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                assert_true(sci_cube_frame(m, k)[y * w + x] == sci_cube_frame(m, k)[(y / 4 * 4) * w + x / 4 * 4]);
    sci_cube_free(m);
    /* DMD mapping: 2 sensor pixels per mirror → each mirror covers 2×2 pixels; offset shifts it. */
    m = masks_of("{\"type\": \"random\", \"dmd\": {\"width\": 32, \"height\": 24, \"scale\": 2}}", w, h, n);
    for (int k = 0; k < n; k++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                assert_true(sci_cube_frame(m, k)[y * w + x] == sci_cube_frame(m, k)[(y & ~1) * w + (x & ~1)]);
    sci_cube_free(m);
    /* Half a mirror per pixel: each pixel averages 2×2 mirrors, values in quarters. */
    m = masks_of("{\"type\": \"random\", \"dmd\": {\"width\": 128, \"height\": 96, \"scale\": 0.5}}", w, h, n);
    int fractional = 0;
    for (size_t i = 0; i < sci_cube_count(m); i++) {
        float q = m->data[i] * 4;
        assert_true(q == floorf(q) && q >= 0 && q <= 4);
        fractional += q != 0 && q != 4;
    }
    assert_true(fractional > 0);
    sci_cube_free(m);
    /* A DMD smaller than the sensor, offset: pixels outside see no mirror (0). */
    m = masks_of("{\"type\": \"random\", \"density\": 1, \"dmd\": {\"width\": 10, \"height\": 10, \"offset\": [5, 7]}}",
                 w, h, n);
    assert_true(m->data[0] == 0 && m->data[7 * w + 5] == 1 && m->data[16 * w + 14] == 1 && m->data[17 * w + 15] == 0);
    sci_cube_free(m);
}

/* Masks from a stack file round-trip exactly; a PSF image is normalised, and one of even size is refused with its
 * position. */
static void test_files(void **state)
{
    char dir[] = "/tmp/scicap-test-sim-XXXXXX";
    assert_non_null(mkdtemp(dir));
    const int w = 24, h = 16, n = 4;
    sci_cube *m = masks_of("{\"type\": \"random\", \"density\": 0.5}", w, h, n);
    sci_error err = {0};
    if (sci_stack_write(dir, "mask", "exr", m, SCI_PIXEL_F32, 1.0, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    char spec[512];
    snprintf(spec, sizeof spec, "{\"type\": \"file\", \"path\": \"%s/mask.json\"}", dir);
    sci_cube *back = masks_of(spec, w, h, n);
    assert_memory_equal(back->data, m->data, sci_cube_count(m) * 4);
    sci_cube_free(back);
    sci_cube_free(m);

    sci_cube *psf;
    assert_int_equal(sci_cube_new(&psf, 3, 3, 1, NULL), 0);
    for (int i = 0; i < 9; i++)
        psf->data[i] = (float)(i % 2 + 1);
    char path[600], text[1200];
    snprintf(path, sizeof path, "%s/psf.exr", dir);
    assert_int_equal(sci_image_write(path, psf, 0, SCI_PIXEL_F32, 1.0, NULL, &err), 0);
    snprintf(text, sizeof text,
             "{\"kind\": \"video2d\", \"width\": 16, \"height\": 16,\n"
             " \"layers\": [{\"texture\": {\"type\": \"constant\"}}],\n"
             " \"effects\": {\"blur\": {\"psf\": \"psf.exr\"}}}");
    sim_scene *sc;
    if (sim_scene_load_string(&sc, "p.json", text, dir, &err) < 0)
        fail_msg("%s", err.msg);
    double sum = 0;
    for (int i = 0; i < 9; i++)
        sum += sc->fx.psf->data[i];
    assert_true(fabs(sum - 1) < 1e-6);
    assert_true(sc->fx.psf->data[1] == 2 * sc->fx.psf->data[0]);
    sim_scene_free(sc);
    sci_cube_free(psf);
    assert_int_equal(sci_cube_new(&psf, 4, 3, 1, NULL), 0);
    psf->data[0] = 1;
    assert_int_equal(sci_image_write(path, psf, 0, SCI_PIXEL_F32, 1.0, NULL, &err), 0);
    assert_true(sim_scene_load_string(&sc, "p.json", text, dir, &err) < 0);
    printf("even PSF: %s\n", err.msg);
    assert_non_null(strstr(err.msg, "p.json:3:23: effects.blur.psf:"));
    sci_cube_free(psf);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_default_scene_loads),
        cmocka_unit_test(test_positioned_errors),
        cmocka_unit_test(test_overrides),
        cmocka_unit_test(test_mask_kinds),
        cmocka_unit_test(test_files),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
