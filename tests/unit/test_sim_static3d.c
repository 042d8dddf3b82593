/* static3d: SE(3) poses (exp/log round trip, geodesic with exact end poses), the camera convention of
 * recon/problem.h, and occlusion by ray casting. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "base/rng.h"
#include "sim/pose.h"
#include "sim/simulate.h"

static uint64_t test_seed(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    uint64_t seed = s ? strtoull(s, NULL, 0) : 11;
    printf("seed %llu (set SCICAP_TEST_SEED to change)\n", (unsigned long long)seed);
    return seed;
}

static double maxdiff12(const double *a, const double *b)
{
    double m = 0;
    for (int i = 0; i < 12; i++)
        m = fmax(m, fabs(a[i] - b[i]));
    return m;
}

/* log(exp(ξ)) = ξ over angles from 1e-9 (Taylor branch) through the branch switch to near π. */
static void test_exp_log_round_trip(void **state)
{
    sci_rng r;
    sci_rng_seed(&r, test_seed(), 1);
    double angles[] = {0, 1e-9, 1e-4, 0.049, 0.051, 0.5, 2.0, 3.1, 3.14159};
    double worst = 0;
    for (size_t a = 0; a < sizeof angles / sizeof *angles; a++)
        for (int t = 0; t < 50; t++) {
            double xi[6], back[6], T[12], axis[3], n = 0;
            for (int i = 0; i < 3; i++) {
                xi[i] = 2 * sci_rng_uniform(&r) - 1;
                axis[i] = sci_rng_normal(&r);
                n += axis[i] * axis[i];
            }
            for (int i = 0; i < 3; i++)
                xi[3 + i] = axis[i] / sqrt(n) * angles[a];
            sim_pose_exp(xi, T);
            /* R orthonormal */
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++) {
                    double d = T[4 * i] * T[4 * j] + T[4 * i + 1] * T[4 * j + 1] + T[4 * i + 2] * T[4 * j + 2];
                    assert_true(fabs(d - (i == j)) < 1e-12);
                }
            sim_pose_log(T, back);
            for (int i = 0; i < 6; i++)
                worst = fmax(worst, fabs(back[i] - xi[i]));
        }
    printf("exp/log round trip: worst error %.3g\n", worst);
    assert_true(worst < 1e-8);
}

/* The camera path: N = 8 poses on the geodesic; the first and last are the given poses bit for bit, the steps
 * between neighbours are equal (constant velocity along the geodesic). */
static void test_path_hits_end_poses(void **state)
{
    const char *text =
        "{\"kind\": \"static3d\", \"width\": 32, \"height\": 32, \"frames\": 8,"
        " \"objects\": [{\"type\": \"sphere\", \"radius\": 1, \"center\": [0, 0, -4], \"texture\": {\"type\": \"constant\"}}],"
        " \"camera\": {\"start\": {\"matrix\": [1,0,0,0.1, 0,1,0,-0.2, 0,0,1,0.3]},"
        "            \"end\": {\"position\": [0.5, 0.3, 0.2], \"rotation_rad\": [0.05, -0.3, 0.1]}}}";
    sim_scene *sc;
    sci_error err = {0};
    if (sim_scene_load_string(&sc, "path.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    const sim_static3d *s = &sc->static3d;
    assert_int_equal(s->npose, 8);
    double start[12] = {1, 0, 0, 0.1, 0, 1, 0, -0.2, 0, 0, 1, 0.3}, end[12], R[9], w[3] = {0.05, -0.3, 0.1};
    sim_rot_exp(w, R);
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            end[4 * i + j] = R[3 * i + j];
    }
    end[3] = 0.5;
    end[7] = 0.3;
    end[11] = 0.2;
    assert_memory_equal(s->pose[0], start, sizeof start);
    assert_memory_equal(s->pose[7], end, sizeof end);
    double step0[6];
    for (int i = 0; i < 7; i++) {
        double inv[12], rel[12], xi[6];
        sim_pose_inv(s->pose[i], inv);
        sim_pose_mul(inv, s->pose[i + 1], rel);
        sim_pose_log(rel, xi);
        if (i == 0)
            memcpy(step0, xi, sizeof xi);
        for (int j = 0; j < 6; j++)
            assert_true(fabs(xi[j] - step0[j]) < 1e-12);
    }
    /* pose_at between frames follows the geodesic; at frames it is the frame pose exactly */
    double T[12];
    sim_static3d_pose_at(s, 3, T);
    assert_memory_equal(T, s->pose[3], sizeof T);
    sim_static3d_pose_at(s, 3.5, T);
    double mid[12];
    sim_pose_interp(s->pose[0], s->pose[7], 3.5 / 7, mid);
    printf("path: ends exact; equal steps; pose at t=3.5 off the global geodesic by %.2g\n", maxdiff12(T, mid));
    assert_true(maxdiff12(T, mid) < 1e-12);
    /* The problems carry these poses and the intrinsics. */
    sci_problem **p;
    int k;
    assert_int_equal(sim_run(sc, &p, &k, NULL, NULL, NULL, &err), 0);
    assert_non_null(p[0]->camera);
    assert_int_equal(p[0]->camera->n, 8);
    assert_memory_equal(p[0]->camera->pose, s->pose, 8 * sizeof *s->pose);
    assert_true(p[0]->camera->fx == 32 && p[0]->camera->cx == 16);
    for (int i = 0; i < k; i++)
        sci_problem_free(p[i]);
    free(p);
    /* Two snapshots: the path spreads over 16 frames, still exact at both ends. */
    assert_int_equal(sim_scene_set_snapshots(sc, 2, &err), 0);
    assert_int_equal(sc->static3d.npose, 16);
    assert_memory_equal(sc->static3d.pose[0], start, sizeof start);
    assert_memory_equal(sc->static3d.pose[15], end, sizeof end);
    sim_scene_free(sc);
}

static sim_scene *load3d(const char *objects, const char *extra)
{
    char text[4096];
    snprintf(text, sizeof text,
             "{\"kind\": \"static3d\", \"width\": 64, \"height\": 64, \"frames\": 1, \"background\": 0.05,"
             " \"objects\": [%s], \"camera\": {\"fx\": 64, \"start\": {\"position\": [0, 0, 0],"
             " \"look_at\": [0, 0, -1]}}%s}",
             objects, extra);
    sim_scene *sc;
    sci_error err = {0};
    if (sim_scene_load_string(&sc, "occ.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    return sc;
}

static float px(const sim_scene *sc, float *buf, int x, int y)
{
    sim_render_frame(sc, 0, buf);
    return buf[y * sc->w + x];
}

#define SPHERE "{\"type\": \"sphere\", \"center\": [0, 0, -3], \"radius\": 1, \"texture\": {\"type\": \"constant\", \"value\": 0.9}}"
#define WALL "{\"type\": \"plane\", \"center\": [0, 0, -6], \"size\": [20, 20], \"texture\": {\"type\": \"constant\", \"value\": 0.3}}"
#define BOX "{\"type\": \"box\", \"center\": [0, 0, -1.5], \"size\": [0.3, 0.3, 0.3], \"rotation_rad\": [0.3, 0.5, 0], \"texture\": {\"type\": \"constant\", \"value\": 0.6}}"

/* The nearest surface wins, whatever the order objects are listed in. */
static void test_occlusion(void **state)
{
    float buf[64 * 64];
    const char *orders[] = {SPHERE "," WALL "," BOX, BOX "," WALL "," SPHERE, WALL "," SPHERE "," BOX};
    for (int o = 0; o < 3; o++) {
        sim_scene *sc = load3d(orders[o], "");
        assert_true(px(sc, buf, 32, 32) == 0.6f);       /* box in front of the sphere */
        assert_true(px(sc, buf, 32, 20) == 0.9f);       /* sphere above the box, in front of the wall */
        assert_true(px(sc, buf, 2, 2) == 0.3f);         /* wall beyond the sphere's silhouette */
        sim_scene_free(sc);
    }
    /* Move the sphere behind the wall: the wall hides it. */
    sim_scene *sc = load3d("{\"type\": \"sphere\", \"center\": [0, 0, -8], \"radius\": 1, \"texture\":"
                           " {\"type\": \"constant\", \"value\": 0.9}}," WALL, "");
    assert_true(px(sc, buf, 32, 20) == 0.3f);
    sim_scene_free(sc);
    /* Nothing hit: background. */
    sc = load3d(SPHERE, "");
    assert_true(px(sc, buf, 1, 1) == 0.05f);
    sim_scene_free(sc);
    printf("occlusion: nearest surface in all three listing orders; hidden sphere stays hidden\n");
}

/* recon/problem.h: pixel (px, py) looks along ((px+0.5−cx)/fx, −(py+0.5−cy)/fy, −1). A small sphere placed on the
 * ray through the centre of pixel (40, 28) (right of and above the centre) lights that pixel and not its mirror
 * images. */
static void test_camera_convention(void **state)
{
    float buf[64 * 64];
    /* depth 4: x = (40.5 − 32)/64·4, y = −(28.5 − 32)/64·4 */
    char obj[256];
    snprintf(obj, sizeof obj,
             "{\"type\": \"sphere\", \"center\": [%.17g, %.17g, -4], \"radius\": 0.03, \"texture\": {\"type\":"
             " \"constant\", \"value\": 1}}",
             8.5 / 16, 3.5 / 16);
    sim_scene *sc = load3d(obj, "");
    assert_true(px(sc, buf, 40, 28) == 1.0f);
    assert_true(buf[28 * 64 + 23] == 0.05f); /* mirrored in x */
    assert_true(buf[35 * 64 + 40] == 0.05f); /* mirrored in y */
    assert_true(buf[28 * 64 + 42] == 0.05f);
    sim_scene_free(sc);
    /* Lighting: a lit sphere is brighter on the side facing the light. */
    sc = load3d(SPHERE, ", \"light\": {\"direction\": [1, 0, 0], \"ambient\": 0.2}");
    sim_render_frame(sc, 0, buf);
    assert_true(buf[32 * 64 + 40] > buf[32 * 64 + 24]);
    sim_scene_free(sc);
}

/* Supersampling averages s×s rays: an edge pixel gets an intermediate value, interior pixels stay exact. */
static void test_supersampling(void **state)
{
    const char *text =
        "{\"kind\": \"static3d\", \"width\": 64, \"height\": 64, \"frames\": 1, \"supersample\": 4,"
        " \"objects\": [" SPHERE "], \"camera\": {\"fx\": 64, \"start\": {\"position\": [0, 0, 0],"
        " \"look_at\": [0, 0, -1]}}}";
    sim_scene *sc;
    sci_error err = {0};
    assert_int_equal(sim_scene_load_string(&sc, "ss.json", text, NULL, &err), 0);
    float buf[64 * 64];
    sim_render_frame(sc, 0, buf);
    int partial = 0;
    for (int i = 0; i < 64 * 64; i++)
        partial += buf[i] > 0 && buf[i] < 0.9f;
    printf("supersample 4: %d edge pixels with partial coverage\n", partial);
    assert_true(buf[32 * 64 + 32] == 0.9f);
    assert_true(partial > 20);
    sim_scene_free(sc);
}

/* The example scenes' near/far bound their depth range (what the NeRF methods sample): every frame renders bit for
 * bit as with the default 0.05 … 100, so no visible surface lies outside it. */
static void test_example_depth_ranges(void **state)
{
    static const char *const files[] = {"etc/scenes/static3d_corridor.json", "etc/scenes/static3d_orbit.json",
                                        "etc/scenes/static3d_noisy.json", "etc/scenes/static3d_tabletop.json"};
    for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
        sim_scene *sc;
        sci_error err = {0};
        if (sim_scene_load_file(&sc, files[f], &err) < 0)
            fail_msg("%s", err.msg);
        const size_t px = (size_t)sc->w * sc->h;
        float *a = malloc(px * sizeof *a), *b = malloc(px * sizeof *b);
        assert_non_null(a);
        assert_non_null(b);
        const double near = sc->static3d.near_m, far = sc->static3d.far_m;
        assert_true(near > 0.05 && far < 100); /* the file sets a range of its own */
        size_t differ = 0;
        for (int g = 0; g < sc->n; g++) {
            sc->static3d.near_m = near, sc->static3d.far_m = far;
            sim_render_frame(sc, g, a);
            sc->static3d.near_m = 0.05, sc->static3d.far_m = 100;
            sim_render_frame(sc, g, b);
            for (size_t i = 0; i < px; i++)
                differ += a[i] != b[i];
        }
        printf("%s: near %g far %g, %zu pixels differ from 0.05 … 100\n", files[f], near, far, differ);
        assert_int_equal(differ, 0);
        free(a);
        free(b);
        sim_scene_free(sc);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_exp_log_round_trip),
        cmocka_unit_test(test_path_hits_end_poses),
        cmocka_unit_test(test_occlusion),
        cmocka_unit_test(test_camera_convention),
        cmocka_unit_test(test_supersampling),
        cmocka_unit_test(test_example_depth_ranges),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
