/* io/: image round trips through OpenImageIO, stacks, problem folders, .mat round trip, and bad input that must
 * be refused with a message naming the file and the fault. */
#include <errno.h>
#include <signal.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <matio.h>

#include "io/image.h"
#include "io/limits.h"
#include "io/staging.h"
#include "io/matfile.h"
#include "io/problem_dir.h"
#include "io/source.h"
#include "tests/helpers/testdata.h"

static char tmpdir[256];

static int setup(void **state)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/scicap-test-io-XXXXXX");
    return mkdtemp(tmpdir) ? 0 : -1;
}

static int teardown(void **state)
{
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

static sci_cube *ramp(int w, int h, int n, float scale)
{
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, w, h, n, NULL), 0);
    for (size_t i = 0; i < sci_cube_count(c); i++)
        c->data[i] = (float)(i % 977) * scale;
    return c;
}

static void test_image_roundtrip(void **state)
{
    const struct { const char *ext; sci_pixel_type t; float scale; } cases[] = {
        {"tif", SCI_PIXEL_U16, 1.0f}, {"png", SCI_PIXEL_U8, 0.25f}, {"png", SCI_PIXEL_U16, 1.0f},
        {"exr", SCI_PIXEL_F32, 0.001f}, {"tif", SCI_PIXEL_F32, 0.37f},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        sci_cube *c = ramp(37, 21, 2, cases[i].scale), *back = NULL;
        char path[512];
        snprintf(path, sizeof path, "%s/img%zu.%s", tmpdir, i, cases[i].ext);
        sci_error err = {0};
        if (sci_image_write(path, c, 1, cases[i].t, 1.0, "test", &err) < 0)
            fail_msg("%s", err.msg);
        int bits = 0;
        if (sci_image_read(path, &back, &bits, &err) < 0)
            fail_msg("%s", err.msg);
        assert_int_equal(back->w, 37);
        assert_int_equal(back->h, 21);
        assert_int_equal(back->n, 1);
        for (size_t k = 0; k < sci_cube_frame_size(c); k++) {
            float want = sci_cube_frame(c, 1)[k];
            if (cases[i].t == SCI_PIXEL_U8)
                want = fminf(255.0f, nearbyintf(want));
            else if (cases[i].t == SCI_PIXEL_U16)
                want = nearbyintf(want);
            if (back->data[k] != want)
                fail_msg("%s: pixel %zu is %g, wrote %g", path, k, (double)back->data[k], (double)want);
        }
        sci_cube_free(c);
        sci_cube_free(back);
    }
}

static void test_stack_roundtrip_exact(void **state)
{
    sci_cube *c = ramp(16, 9, 5, 1.0f / 3.0f), *back = NULL;
    char dir[512], side[600];
    snprintf(dir, sizeof dir, "%s/stack", tmpdir);
    sci_error err = {0};
    json_t *prov = json_pack("{s:s}", "by", "test");
    assert_int_equal(sci_stack_write(dir, "frame", "exr", c, SCI_PIXEL_F32, 1.0, prov, &err), 0);
    json_decref(prov);
    snprintf(side, sizeof side, "%s/frame.json", dir);
    json_t *p2 = NULL;
    if (sci_stack_read(side, &back, &p2, &err) < 0)
        fail_msg("%s", err.msg);
    assert_memory_equal(back->data, c->data, sci_cube_count(c) * sizeof(float));
    assert_string_equal(json_string_value(json_object_get(p2, "by")), "test");
    json_decref(p2);
    sci_cube_free(back);
    /* A frame of the wrong size must be refused, naming the file. */
    sci_cube *small = ramp(4, 4, 1, 1);
    char bad[600];
    snprintf(bad, sizeof bad, "%s/frame_002.exr", dir);
    assert_int_equal(sci_image_write(bad, small, 0, SCI_PIXEL_F32, 1.0, NULL, &err), 0);
    assert_int_equal(sci_stack_read(side, &back, NULL, &err), SCI_ESHAPE);
    assert_non_null(strstr(err.msg, "frame_002.exr"));
    assert_null(back);
    sci_cube_free(small);
    sci_cube_free(c);
}

static sci_problem *make_problem(int w, int h, int n, int with_truth)
{
    sci_problem *p = calloc(1, sizeof *p);
    p->mask = ramp(w, h, n, 0);
    for (size_t i = 0; i < sci_cube_count(p->mask); i++)
        p->mask->data[i] = (float)((i * 7 + i / 3) % 2);
    p->meas = ramp(w, h, 1, 0.01f);
    if (with_truth)
        p->truth = ramp(w, h, n, 0.001f);
    p->peak = 1;
    snprintf(p->name, sizeof p->name, "synthetic");
    return p;
}

static void test_problem_dir_roundtrip(void **state)
{
    sci_problem *ps[2] = {make_problem(12, 10, 4, 1), make_problem(12, 10, 4, 1)};
    ps[1]->meas->data[5] = 42;
    ps[0]->camera = sci_camera_new(4);
    ps[1]->camera = sci_camera_new(4);
    for (int j = 0; j < 2; j++) {
        ps[j]->camera->fx = ps[j]->camera->fy = 100;
        ps[j]->camera->cx = 6;
        ps[j]->camera->cy = 5;
        ps[j]->camera->near_m = 0.1;
        ps[j]->camera->far_m = 10;
        for (int f = 0; f < 4; f++)
            ps[j]->camera->pose[f][3] = j * 10 + f;
    }
    char dir[512];
    snprintf(dir, sizeof dir, "%s/prob", tmpdir);
    sci_error err = {0};
    if (sci_problem_dir_write(dir, ps, 2, NULL, 0, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(sci_problem_dir_write(dir, ps, 2, NULL, 0, &err), -EEXIST);
    sci_problem **back;
    int k;
    if (sci_source_read(dir, &back, &k, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(k, 2);
    for (int j = 0; j < 2; j++) {
        assert_memory_equal(back[j]->meas->data, ps[j]->meas->data, 12 * 10 * sizeof(float));
        assert_memory_equal(back[j]->mask->data, ps[0]->mask->data, 12 * 10 * 4 * sizeof(float));
        assert_memory_equal(back[j]->truth->data, ps[j]->truth->data, 12 * 10 * 4 * sizeof(float));
        assert_true(back[j]->camera->pose[3][3] == j * 10 + 3);
    }
    sci_problem_array_free(back, k);
    sci_problem_free(ps[0]);
    sci_problem_free(ps[1]);
    /* No temporary folder is left behind. */
    char tmp[600];
    snprintf(tmp, sizeof tmp, "%s.tmp-%d", dir, (int)getpid());
    assert_int_not_equal(access(tmp, F_OK), 0);
}

static void test_mat_roundtrip_and_faults(void **state)
{
    sci_problem *ps[2] = {make_problem(9, 7, 3, 1), make_problem(9, 7, 3, 1)};
    char path[512];
    snprintf(path, sizeof path, "%s/p.mat", tmpdir);
    sci_error err = {0};
    if (sci_mat_write(path, ps, 2, 1.0, &err) < 0)
        fail_msg("%s", err.msg);
    sci_problem **back;
    int k;
    if (sci_mat_read(path, 1.0, &back, &k, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(k, 2);
    assert_memory_equal(back[1]->truth->data, ps[1]->truth->data, 9 * 7 * 3 * sizeof(float));
    assert_memory_equal(back[0]->mask->data, ps[0]->mask->data, 9 * 7 * 3 * sizeof(float));
    sci_problem_array_free(back, k);

    /* Truncated file. */
    FILE *f = fopen(path, "rb");
    char buf[4096];
    size_t got = fread(buf, 1, sizeof buf, f);
    fclose(f);
    char trunc[512];
    snprintf(trunc, sizeof trunc, "%s/trunc.mat", tmpdir);
    f = fopen(trunc, "wb");
    fwrite(buf, 1, got / 2, f);
    fclose(f);
    int rc = sci_mat_read(trunc, 1.0, &back, &k, &err);
    assert_true(rc == SCI_EFORMAT);
    assert_non_null(strstr(err.msg, "trunc.mat"));
    printf("truncated: %s\n", err.msg);

    /* Not a MAT file at all. */
    snprintf(trunc, sizeof trunc, "%s/text.mat", tmpdir);
    f = fopen(trunc, "w");
    fputs("hello, this is not MATLAB\n", f);
    fclose(f);
    assert_int_equal(sci_mat_read(trunc, 1.0, &back, &k, &err), SCI_EFORMAT);
    printf("not a mat: %s\n", err.msg);

    /* Missing file; unknown format. */
    assert_int_equal(sci_source_read("/nonexistent/x.mat", &back, &k, &err), -ENOENT);
    assert_non_null(strstr(err.msg, "/nonexistent/x.mat"));
    snprintf(trunc, sizeof trunc, "%s/x.xyz", tmpdir);
    f = fopen(trunc, "w");
    fclose(f);
    assert_int_equal(sci_source_read(trunc, &back, &k, &err), SCI_EFORMAT);
    printf("unknown: %s\n", err.msg);

    /* Sizes that disagree: a mask of another size. */
    sci_problem *odd = make_problem(9, 7, 3, 0);
    sci_cube_free(odd->mask);
    odd->mask = ramp(8, 7, 3, 0);
    snprintf(trunc, sizeof trunc, "%s/shape.mat", tmpdir);
    assert_int_equal(sci_mat_write(trunc, &odd, 1, 1.0, &err), 0);
    assert_int_equal(sci_mat_read(trunc, 1.0, &back, &k, &err), SCI_ESHAPE);
    printf("shape: %s\n", err.msg);

    /* NaN in the measurement. */
    sci_cube_free(odd->mask);
    odd->mask = ramp(9, 7, 3, 0);
    odd->meas->data[3] = NAN;
    assert_int_equal(sci_mat_write(trunc, &odd, 1, 1.0, &err), 0);
    assert_int_equal(sci_mat_read(trunc, 1.0, &back, &k, &err), SCI_ENONFINITE);
    assert_non_null(strstr(err.msg, "meas"));
    printf("nan: %s\n", err.msg);
    sci_problem_free(odd);
    sci_problem_free(ps[0]);
    sci_problem_free(ps[1]);
}

static void test_drop40_shape(void **state)
{
    char path[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", path);
    sci_problem **p;
    int k;
    sci_error err = {0};
    if (sci_mat_read(path, 0, &p, &k, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(k, 5);
    float lo, hi;
    sci_cube_minmax(p[0]->truth, &lo, &hi);
    assert_true(lo >= 0 && hi <= 1.0f && hi > 0.9f);
    assert_true(p[0]->peak == 1.0);
    sci_problem_array_free(p, k);
}

/* Per-snapshot masks, as H×W×N×k (rank 4) and as H×W×(N·k) beside a truth that says N: snapshot j gets masks
 * j·N … j·N + N − 1; shared H×W×N masks go to every snapshot. Values checked element by element. */
static void test_mat_masks_per_snapshot(void **state)
{
    const size_t h = 3, w = 4, n = 2, k = 3;
    double mask[3 * 4 * 2 * 3], meas[3 * 4 * 3], orig[3 * 4 * 2 * 3];
    for (size_t i = 0; i < h * w * n * k; i++)
        mask[i] = (double)(i % 5), orig[i] = (double)i;
    for (size_t i = 0; i < h * w * k; i++)
        meas[i] = 2.0 * i;
    for (int layout = 0; layout < 2; layout++) {
        char path[512];
        snprintf(path, sizeof path, "%s/per%d.mat", tmpdir, layout);
        mat_t *m = Mat_CreateVer(path, NULL, MAT_FT_MAT5);
        assert_non_null(m);
        size_t d4[4] = {h, w, n, k}, d3[3] = {h, w, n * k}, dy[3] = {h, w, k};
        matvar_t *v = layout == 0 ? Mat_VarCreate("M", MAT_C_DOUBLE, MAT_T_DOUBLE, 4, d4, mask, 0)
                                  : Mat_VarCreate("M", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, d3, mask, 0);
        assert_int_equal(Mat_VarWrite(m, v, MAT_COMPRESSION_NONE), 0);
        Mat_VarFree(v);
        v = Mat_VarCreate("meas", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dy, meas, 0);
        assert_int_equal(Mat_VarWrite(m, v, MAT_COMPRESSION_NONE), 0);
        Mat_VarFree(v);
        v = Mat_VarCreate("orig", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, d3, orig, 0);
        assert_int_equal(Mat_VarWrite(m, v, MAT_COMPRESSION_NONE), 0);
        Mat_VarFree(v);
        Mat_Close(m);
        sci_mat_options o = {.mask_var = "M", .white = 2, .mask_white = 1}; /* masks as stored */
        sci_mat_info info;
        sci_problem **p;
        int kk;
        sci_error err = {0};
        if (sci_mat_read_opts(path, &o, &p, &kk, &info, &err) < 0)
            fail_msg("%s", err.msg);
        assert_int_equal(kk, (int)k);
        assert_int_equal(info.mask_per_snapshot, 1);
        for (size_t j = 0; j < k; j++) {
            assert_int_equal(p[j]->mask->n, (int)n);
            assert_true(p[j]->peak == 1.0);
            for (size_t f = 0; f < n; f++)
                for (size_t y = 0; y < h; y++)
                    for (size_t x = 0; x < w; x++) {
                        size_t col = y + h * x + h * w * (j * n + f);
                        assert_true(p[j]->mask->data[(f * h + y) * w + x] == (float)mask[col]);
                        assert_true(p[j]->truth->data[(f * h + y) * w + x] == (float)(orig[col] / 2));
                    }
            assert_true(p[j]->meas->data[w + 1] == (float)(meas[1 + h * 1 + h * w * j] / 2));
        }
        sci_problem_array_free(p, kk);
    }
}

/* OpenImageIO 2.4's GIF writer dies of SIGSEGV on frames over 2^24 pixels (4096² works, 4200² crashed scicap recon
 * and scicap sim): the preview is shrunk by the smallest integer factor under SCI_GIF_MAX_PIXELS. */
static void test_gif_large_frames_scaled_down(void **state)
{
    const struct { int w, h, factor, gw, gh; } cases[] = {
        {4200, 4200, 3, 1400, 1400}, {2048, 2048, 1, 2048, 2048}, {70000, 3, 2, 35000, 2},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        sci_cube *c = ramp(cases[i].w, cases[i].h, 1, 1.0f / 977), *back = NULL;
        char path[512];
        snprintf(path, sizeof path, "%s/large%zu.gif", tmpdir, i);
        sci_error err = {0};
        int factor = 0;
        if (sci_image_write_gif_opt(path, c, 255.0, 100, &factor, &err) < 0)
            fail_msg("%dx%d: %s", cases[i].w, cases[i].h, err.msg);
        assert_int_equal(factor, cases[i].factor);
        if (sci_image_read(path, &back, NULL, &err) < 0)
            fail_msg("%s", err.msg);
        assert_int_equal(back->w, cases[i].gw);
        assert_int_equal(back->h, cases[i].gh);
        sci_cube_free(back);
        sci_cube_free(c);
    }
}

/* Publish-on-success (io/staging.h): a set stop flag publishes nothing and removes the staging folder; an existing
 * output is kept without overwrite and replaced with it, with nothing left beside it. */
static void test_staging_publish(void **state)
{
    char out[512], tmp[600], file[700], cmd[800];
    snprintf(out, sizeof out, "%s/published", tmpdir);
    volatile sig_atomic_t stop = 1;
    sci_error err = {0};
    for (int round = 0; round < 4; round++) {
        assert_int_equal(sci_staging_name(tmp, sizeof tmp, out), 0);
        assert_int_equal(mkdir(tmp, 0755), 0);
        snprintf(file, sizeof file, "%s/round%d", tmp, round);
        FILE *f = fopen(file, "w");
        assert_non_null(f);
        fclose(f);
        const int rc = sci_staging_publish(tmp, out, round == 3 ? SCI_STAGING_OVERWRITE : 0, &stop, &err);
        assert_int_equal(access(tmp, F_OK), -1); /* never left behind */
        if (round == 0) {
            assert_int_equal(rc, SCI_ECANCELED);
            assert_int_equal(access(out, F_OK), -1);
            stop = 0;
        } else if (round == 1) {
            assert_int_equal(rc, 0);
        } else if (round == 2) {
            assert_int_equal(rc, -EEXIST);
            snprintf(file, sizeof file, "%s/round1", out);
            assert_int_equal(access(file, F_OK), 0);
        } else {
            assert_int_equal(rc, 0);
            snprintf(file, sizeof file, "%s/round3", out);
            assert_int_equal(access(file, F_OK), 0);
            snprintf(file, sizeof file, "%s/round1", out);
            assert_int_equal(access(file, F_OK), -1);
        }
    }
    snprintf(cmd, sizeof cmd, "ls -d '%s'.* 2>/dev/null | grep -q .", out);
    assert_int_not_equal(system(cmd), 0); /* no .tmp-PID or .old-PID */
}

/* sci_staging_sync: a published tree (files, a subfolder, a dangling symlink and a FIFO, neither followed nor
 * opened — opening a FIFO would block) syncs to 0, alone, with its parent, and one file alone; a missing path,
 * a symlink and a FIFO named directly are errors. A durable publish (SCI_STAGING_DURABLE) publishes like any
 * other. Durability itself needs a power cut to see; this checks the walks. */
static void test_staging_sync(void **state)
{
    char out[512], path[700], tmp[700];
    snprintf(out, sizeof out, "%s/durable", tmpdir);
    assert_int_equal(mkdir(out, 0755), 0);
    snprintf(path, sizeof path, "%s/sub", out);
    assert_int_equal(mkdir(path, 0755), 0);
    const char *files[] = {"a.json", "sub/b.exr"};
    for (int i = 0; i < 2; i++) {
        snprintf(path, sizeof path, "%s/%s", out, files[i]);
        FILE *f = fopen(path, "w");
        assert_non_null(f);
        fputs("x\n", f);
        fclose(f);
    }
    snprintf(path, sizeof path, "%s/dangling", out);
    assert_int_equal(symlink("/nonexistent/scicap-target", path), 0);
    assert_int_equal(sci_staging_sync(path, 0), -ELOOP);
    snprintf(path, sizeof path, "%s/sub/fifo", out);
    assert_int_equal(mkfifo(path, 0600), 0);
    assert_int_equal(sci_staging_sync(path, 0), -EINVAL);
    assert_int_equal(sci_staging_sync(out, SCI_SYNC_TREE), 0);
    assert_int_equal(sci_staging_sync(out, SCI_SYNC_TREE | SCI_SYNC_PARENT), 0);
    snprintf(path, sizeof path, "%s/a.json", out);
    assert_int_equal(sci_staging_sync(path, SCI_SYNC_PARENT), 0);
    snprintf(path, sizeof path, "%s/missing", out);
    assert_int_equal(sci_staging_sync(path, SCI_SYNC_TREE), -ENOENT);

    /* the tree published durably, over an existing folder: the same result as a plain publish */
    snprintf(tmp, sizeof tmp, "%s/durable-pub.tmp", tmpdir);
    snprintf(path, sizeof path, "%s/durable-pub", tmpdir);
    assert_int_equal(mkdir(path, 0755), 0);
    assert_int_equal(rename(out, tmp), 0);
    sci_error err = {0};
    assert_int_equal(sci_staging_publish(tmp, path, SCI_STAGING_DURABLE, NULL, &err), -EEXIST);
    assert_int_equal(access(tmp, F_OK), -1); /* removed on the error, as documented */
    assert_int_equal(mkdir(tmp, 0755), 0);
    snprintf(out, sizeof out, "%s/c.json", tmp);
    FILE *f = fopen(out, "w");
    assert_non_null(f);
    fclose(f);
    assert_int_equal(sci_staging_publish(tmp, path, SCI_STAGING_DURABLE | SCI_STAGING_OVERWRITE, NULL, &err), 0);
    snprintf(out, sizeof out, "%s/c.json", path);
    assert_int_equal(access(out, F_OK), 0);
    assert_int_equal(access(tmp, F_OK), -1);
    assert_int_equal(sci_staging_remove(path), 0);
}

/* The limits name the figure, the limit and the override; sci_io_limits_none lifts them. */
static void test_limits_messages(void **state)
{
    sci_io_limits none;
    sci_io_limits_none(&none);
    sci_error err = {0};
    assert_int_equal(sci_io_limits_check_output(NULL, "OUT", 1e6, 4000005, &err), -EFBIG);
    assert_non_null(strstr(err.msg, "4000005"));
    assert_non_null(strstr(err.msg, "--allow-large"));
    assert_int_equal(sci_io_limits_check_output(&none, "OUT", 1e15, 1e12, &err), 0);
    assert_int_equal(sci_io_limits_check_cube(NULL, "mask.json", 24576, 24576, 1, &err), -EFBIG);
    assert_non_null(strstr(err.msg, "24576x24576x1"));
    assert_int_equal(sci_io_limits_check_cube(&none, "mask.json", 24576, 24576, 1, &err), 0);
    assert_int_equal(sci_io_limits_check_input(NULL, "x.mat", 256, 256, 8, 5, &err), 0); /* drop40 */
    assert_int_equal(sci_io_limits_check_input(NULL, "x.mat", 1LL << 31, 1LL << 31, 1LL << 31, 1, &err), -EFBIG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_image_roundtrip), cmocka_unit_test(test_stack_roundtrip_exact),
        cmocka_unit_test(test_gif_large_frames_scaled_down), cmocka_unit_test(test_staging_publish), cmocka_unit_test(test_staging_sync),
        cmocka_unit_test(test_limits_messages),
        cmocka_unit_test(test_problem_dir_roundtrip), cmocka_unit_test(test_mat_roundtrip_and_faults),
        cmocka_unit_test(test_drop40_shape), cmocka_unit_test(test_mat_masks_per_snapshot),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
