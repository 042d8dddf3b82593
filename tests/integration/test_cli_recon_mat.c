/* `scicap recon` on any .mat: the drop40 benchmark rewritten by this test as a lab would ship it — values already
 * on [0, 1], variables named y (measurements) and X (truth), the masks as Phi in a separate file, in MATLAB v5 and
 * in v7.3 (HDF5), or with grey masks — reconstructs through --mask/--mask-var/--meas-var/--truth-var and the
 * inferred scales to the same PSNR as the original file (34.63 dB, peak = frame max, snapshot 1, GAP-TV defaults),
 * with no scale option; a wrong scale is warned about; a capture that used the first 10 of 50 masks needs
 * --frames 10 (a truth of 10 frames is an error without it, no truth a warning); the real capture of
 * data/real reconstructs to frames neither black nor saturated; a missing variable is refused with the list of
 * what the file holds and the option to use. Runs the real binary. */
#include <errno.h>
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
#include <jansson.h>
#include <matio.h>

#include "io/matfile.h"
#include "tests/helpers/testdata.h"

/* Under AddressSanitizer (make check-asan, whose point is memory errors) every reconstruction without its own
 * --iters stops at 50 iterations (33 dB on drop40): the scale checks compare runs with one another, which holds at
 * any count; the golden 34.63 dB of the full default run is checked in the optimised build. */
#include "tests/helpers/sanitized.h"
#include "tests/helpers/cli_child.h"

static char dir[] = "/tmp/scicap-test-cli-mat-XXXXXX";
static char scicap[1024];
static char drop40[4096];
static int have_drop40;

/* Run a shell command; its stderr goes to dir/stderr.txt. Returns the exit status. */
static int run(const char *fmt, ...)
{
    char cmd[8192], full[8400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    const char *iters = SANITIZED && strstr(cmd, " recon ") && !strstr(cmd, "--iters") ? " --iters 50" : "";
    snprintf(full, sizeof full, "%s%s -q --snapshot 1 --force >/dev/null 2>%s/stderr.txt", cmd, iters, dir);
    int rc = system(full);
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

static char *read_stderr(void)
{
    static char buf[8192];
    char path[2048];
    snprintf(path, sizeof path, "%s/stderr.txt", dir);
    FILE *f = fopen(path, "r");
    size_t n = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
    buf[n] = 0;
    if (f)
        fclose(f);
    return buf;
}

/* The last run's stderr holds `needle`; with a label, the whole stderr is printed after it first. */
static void expect_stderr(const char *label, const char *needle)
{
    const char *e = read_stderr();
    if (label)
        printf("%s%s", label, e);
    if (!strstr(e, needle))
        fail_msg("stderr lacks \"%s\":\n%s", needle, e);
}

/* out/result.json under the test's folder (fails the test when missing). */
static json_t *result_of(const char *out)
{
    char name[1024];
    snprintf(name, sizeof name, "%s/result.json", out);
    return cli_child_load_json(dir, name);
}

static double psnr_of(const char *out)
{
    json_t *j = result_of(out);
    double v = json_number_value(json_object_get(json_object_get(j, "psnr_frame_max_db"), "mean"));
    json_decref(j);
    return v;
}

/* Write cubes (frame-major) as one column-major H×W×F variable of the given class. */
static void put(mat_t *m, const char *name, sci_cube *const *c, int nc, enum matio_classes cls)
{
    const int w = c[0]->w, h = c[0]->h;
    size_t f = 0;
    for (int i = 0; i < nc; i++)
        f += (size_t)c[i]->n;
    double *d = malloc((size_t)w * h * f * sizeof *d);
    assert_non_null(d);
    size_t g = 0;
    for (int i = 0; i < nc; i++)
        for (int k = 0; k < c[i]->n; k++, g++)
            for (int x = 0; x < w; x++)
                for (int y = 0; y < h; y++)
                    d[y + (size_t)h * x + (size_t)h * w * g] = c[i]->data[((size_t)k * h + y) * w + x];
    size_t dims[3] = {(size_t)h, (size_t)w, f};
    matvar_t *v;
    if (cls == MAT_C_SINGLE) {
        float *s = malloc((size_t)w * h * f * sizeof *s);
        assert_non_null(s);
        for (size_t i = 0; i < (size_t)w * h * f; i++)
            s[i] = (float)d[i];
        v = Mat_VarCreate(name, MAT_C_SINGLE, MAT_T_SINGLE, 3, dims, s, 0);
        free(s);
    } else {
        v = Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, d, 0);
    }
    free(d);
    assert_non_null(v);
    assert_int_equal(Mat_VarWrite(m, v, MAT_COMPRESSION_ZLIB), 0);
    Mat_VarFree(v);
}

/* drop40 on [0, 1] as data<tag>.mat (y, X) + mask<tag>.mat (Phi). */
static void write_lab_files(const char *tag, enum mat_ft ver, enum matio_classes cls)
{
    sci_problem **p;
    int k;
    sci_error err = {0};
    if (sci_mat_read(drop40, 255, &p, &k, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube *meas[16], *truth[16];
    assert_true(k <= 16);
    for (int j = 0; j < k; j++)
        meas[j] = p[j]->meas, truth[j] = p[j]->truth;
    char path[2048];
    snprintf(path, sizeof path, "%s/data%s.mat", dir, tag);
    mat_t *m = Mat_CreateVer(path, NULL, ver);
    if (!m)
        fail_msg("libmatio cannot create %s (%s)", path, ver == MAT_FT_MAT73 ? "built without HDF5?" : "v5");
    put(m, "y", meas, k, cls);
    put(m, "X", truth, k, cls);
    Mat_Close(m);
    snprintf(path, sizeof path, "%s/mask%s.mat", dir, tag);
    m = Mat_CreateVer(path, NULL, ver);
    assert_non_null(m);
    put(m, "Phi", &p[0]->mask, 1, cls);
    Mat_Close(m);
    sci_problem_array_free(p, k);
}

static int setup(void **state)
{
    have_drop40 = testdata_path("drop40_cacti.mat", drop40, sizeof drop40);
    return cli_child_setup(scicap, sizeof scicap, "scicap", dir);
}

static int teardown(void **state) { return cli_child_remove_dir(dir); }

#define REQUIRE_DROP40()                                                                                           \
    do {                                                                                                           \
        if (!have_drop40) {                                                                                        \
            if (testdata_is_ci())                                                                                  \
                fail_msg("drop40_cacti.mat missing under CI");                                                     \
            skip();                                                                                                \
        }                                                                                                          \
    } while (0)

static double reference_psnr(void)
{
    static double ref = NAN;
    if (isnan(ref)) {
        assert_int_equal(run("%s recon %s -o %s/ref", scicap, drop40, dir), 0);
        ref = psnr_of("ref");
        printf("original drop40 #1: %.4f dB%s\n", ref, SANITIZED ? " (AddressSanitizer build: 50 iterations)" : "");
        if (!SANITIZED)
            assert_true(fabs(ref - 34.63) < 0.006); /* docs/usage.md's golden value */
    }
    return ref;
}

static void check_lab_layout(const char *tag, enum mat_ft ver, enum matio_classes cls)
{
    REQUIRE_DROP40();
    const double ref = reference_psnr();
    write_lab_files(tag, ver, cls);
    /* Every name and the scale given. */
    assert_int_equal(run("%s recon %s/data%s.mat --mask %s/mask%s.mat --mask-var Phi --meas-var y --truth-var X "
                         "--scale 1 -o %s/given%s",
                         scicap, dir, tag, dir, tag, dir, tag),
                     0);
    char out[64];
    snprintf(out, sizeof out, "given%s", tag);
    double given = psnr_of(out);
    printf("%s, names and --scale 1: %.4f dB\n", tag, given);
    assert_true(fabs(given - ref) < 1e-9);
    /* --scale auto from the truth, and the mask file's only variable taken without --mask-var. */
    assert_int_equal(run("%s recon %s/data%s.mat --mask %s/mask%s.mat --meas-var y --truth-var X --scale auto "
                         "-o %s/auto%s",
                         scicap, dir, tag, dir, tag, dir, tag),
                     0);
    printf("%s auto: ", tag);
    expect_stderr("", "truth 'X' peaks at 1");
    expect_stderr(NULL, "white is 1 ");
    snprintf(out, sizeof out, "auto%s", tag);
    assert_true(fabs(psnr_of(out) - ref) < 1e-9);
}

static void test_lab_v5_double(void **state) { check_lab_layout("5", MAT_FT_MAT5, MAT_C_DOUBLE); }
static void test_lab_v73_single(void **state) { check_lab_layout("73", MAT_FT_MAT73, MAT_C_SINGLE); }

/* Without a truth, auto judges from y / Σ M: still 1 for the [0, 1] file, 255 for the original. */
static void test_scale_auto_from_meas(void **state)
{
    REQUIRE_DROP40();
    write_lab_files("m", MAT_FT_MAT5, MAT_C_DOUBLE);
    assert_int_equal(run("%s recon %s/datam.mat --mask %s/maskm.mat --meas-var y --scale auto -o %s/nt", scicap, dir,
                         dir, dir),
                     0);
    expect_stderr("no truth: ", "meas 'y' over the sum of the 8 masks reaches");
    expect_stderr(NULL, "white is 1 ");
    assert_int_equal(run("%s recon %s --scale auto -o %s/orig-auto", scicap, drop40, dir), 0);
    expect_stderr("original: ", "white is 255");
    assert_true(fabs(psnr_of("orig-auto") - reference_psnr()) < 1e-9);
}

/* One .mat with the benchmark's names: masks × mask_gain, meas and truth × gain (drop40 read on [0, 1]). */
static void write_scaled(const char *name, double mask_gain, double gain)
{
    sci_problem **p;
    int k;
    sci_error err = {0};
    if (sci_mat_read(drop40, 255, &p, &k, &err) < 0)
        fail_msg("%s", err.msg);
    for (int j = 0; j < k; j++) {
        for (size_t i = 0; i < sci_cube_count(p[j]->meas); i++)
            p[j]->meas->data[i] *= (float)gain;
        for (size_t i = 0; i < sci_cube_count(p[j]->truth); i++)
            p[j]->truth->data[i] *= (float)gain;
    }
    for (size_t i = 0; i < sci_cube_count(p[0]->mask); i++)
        p[0]->mask->data[i] *= (float)mask_gain;
    char path[2048];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (sci_mat_write(path, p, k, 1.0, &err) < 0)
        fail_msg("%s", err.msg);
    sci_problem_array_free(p, k);
}

/* drop40 as stored (0–255), as [0, 1] doubles, and with masks of 0–115 grey: 34.63 dB each with no scale option,
 * the inferred scales printed in one line. */
static void test_scales_inferred_without_options(void **state)
{
    REQUIRE_DROP40();
    const double ref = reference_psnr();
    assert_int_equal(run("%s recon %s --iters 1 -o %s/one", scicap, drop40, dir), 0);
    expect_stderr(NULL, "scale: truth 'orig' peaks at 255, so white is 255");
    write_scaled("unit.mat", 1, 1);
    write_scaled("grey.mat", 115, 255);
    assert_int_equal(run("%s recon %s/unit.mat -o %s/unit", scicap, dir, dir), 0);
    expect_stderr("[0, 1]: ", "white is 1 ");
    assert_int_equal(run("%s recon %s/grey.mat -o %s/grey", scicap, dir, dir), 0);
    expect_stderr("grey masks: ", "masks 'mask' peak at 115, divided by it");
    printf("PSNR: stored %.4f, [0, 1] %.4f, masks 0-115 %.4f dB\n", ref, psnr_of("unit"), psnr_of("grey"));
    assert_true(fabs(psnr_of("unit") - ref) < 1e-3);
    assert_true(fabs(psnr_of("grey") - ref) < 1e-3);
    json_t *j = result_of("grey");
    assert_true(json_number_value(json_object_get(json_object_get(j, "input"), "mask_white")) == 115);
    json_decref(j);
    /* The same masks with the measurement made through them (×115 too): the gain against the truth is found. */
    write_scaled("both.mat", 115, 255);
    {
        sci_problem **p;
        int k;
        sci_error err = {0};
        char path[2048];
        snprintf(path, sizeof path, "%s/both.mat", dir);
        sci_mat_options o = {.white = 1, .mask_white = 1};
        assert_int_equal(sci_mat_read_opts(path, &o, &p, &k, NULL, &err), 0);
        for (int jj = 0; jj < k; jj++)
            for (size_t i = 0; i < sci_cube_count(p[jj]->meas); i++)
                p[jj]->meas->data[i] *= 115;
        assert_int_equal(sci_mat_write(path, p, k, 1.0, &err), 0);
        sci_problem_array_free(p, k);
    }
    assert_int_equal(run("%s recon %s/both.mat -o %s/both", scicap, dir, dir), 0);
    expect_stderr("meas x115 too: ", "times what the truth makes through the masks");
    assert_true(fabs(psnr_of("both") - ref) < 1e-3);
}

/* A scale given wrong: the frames' levels say so, on stderr and in result.json. */
static void test_wrong_scale_warned(void **state)
{
    REQUIRE_DROP40();
    assert_int_equal(run("%s recon %s --scale 65535 --iters 20 -o %s/dark", scicap, drop40, dir), 0);
    expect_stderr("", "WARNING: the frames' 99th percentile is");
    expect_stderr(NULL, "nearly black");
    json_t *j = result_of("dark");
    assert_int_equal(json_array_size(json_object_get(j, "warnings")), 1);
    assert_true(json_number_value(json_object_get(json_object_get(j, "levels"), "p99")) < 0.05);
    json_decref(j);
    /* and none on the right scale; a compare sheet with the truth; auto-contrast previews state their range */
    assert_int_equal(run("%s recon %s --iters 20 --preview-range auto -o %s/lit", scicap, drop40, dir), 0);
    assert_null(strstr(read_stderr(), "WARNING"));
    j = result_of("lit");
    assert_null(json_object_get(j, "warnings"));
    json_t *pr = json_object_get(j, "preview");
    assert_string_equal(json_string_value(json_object_get(pr, "mode")), "auto");
    double top = json_number_value(json_array_get(json_object_get(pr, "range"), 1));
    printf("auto-contrast top %.3f of white\n", top);
    assert_true(top > 0.3 && top < 1.5);
    json_decref(j);
    char path[2048];
    snprintf(path, sizeof path, "%s/lit/compare.png", dir);
    assert_int_equal(access(path, R_OK), 0);
}

/* 50 masks, a measurement made with the first 10 (drop40 frames 1–10 at 0–255, random binary masks). */
static void write_cr10(const char *name, int with_truth)
{
    sci_problem **p;
    int k;
    sci_error err = {0};
    if (sci_mat_read(drop40, 1.0, &p, &k, &err) < 0)
        fail_msg("%s", err.msg);
    const int w = p[0]->mask->w, h = p[0]->mask->h;
    sci_problem q = {.peak = 255};
    snprintf(q.name, sizeof q.name, "cr10");
    assert_int_equal(sci_cube_new(&q.mask, w, h, 50, &err), 0);
    assert_int_equal(sci_cube_new(&q.meas, w, h, 1, &err), 0);
    if (with_truth)
        assert_int_equal(sci_cube_new(&q.truth, w, h, 10, &err), 0);
    unsigned seed = 7;
    for (size_t i = 0; i < sci_cube_count(q.mask); i++)
        q.mask->data[i] = (float)((rand_r(&seed) >> 7) & 1);
    const size_t px = (size_t)w * h;
    for (int f = 0; f < 10; f++) {
        const float *x = (f < 8 ? p[0]->truth->data + px * f : p[1]->truth->data + px * (f - 8));
        for (size_t i = 0; i < px; i++) {
            q.meas->data[i] += q.mask->data[px * f + i] * x[i];
            if (with_truth)
                q.truth->data[px * f + i] = x[i];
        }
    }
    char path[2048];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    sci_problem *qs[1] = {&q};
    assert_int_equal(sci_mat_write(path, qs, 1, 1.0, &err), 0);
    sci_cube_free(q.mask), sci_cube_free(q.meas), sci_cube_free(q.truth);
    sci_problem_array_free(p, k);
}

static int count_frames(const char *out)
{
    json_t *j = result_of(out);
    int n = (int)json_integer_value(json_object_get(json_object_get(j, "input"), "frames"));
    json_decref(j);
    char path[2048];
    snprintf(path, sizeof path, "%s/%s/frame_%03d.exr", dir, out, n - 1);
    assert_int_equal(access(path, R_OK), 0);
    snprintf(path, sizeof path, "%s/%s/frame_%03d.exr", dir, out, n);
    assert_int_not_equal(access(path, R_OK), 0);
    return n;
}

static void test_frames_of_a_longer_mask(void **state)
{
    REQUIRE_DROP40();
    write_cr10("cr10.mat", 1);
    write_cr10("cr10nt.mat", 0);
    /* a truth of 10 frames beside 50 masks: an error naming both counts and the option */
    assert_int_equal(run("%s recon %s/cr10.mat --iters 5 -o %s/x", scicap, dir, dir), 1);
    expect_stderr("", "has 10 frames but the masks 'mask' 50 per snapshot");
    expect_stderr(NULL, "--frames 10");
    assert_int_equal(run("%s recon %s/cr10.mat --frames 10 -o %s/cr10", scicap, dir, dir), 0);
    assert_int_equal(count_frames("cr10"), 10);
    printf("--frames 10: %.2f dB\n", psnr_of("cr10"));
    assert_true(psnr_of("cr10") > 20);
    /* no truth: the measurement's pattern gives the count away; a warning names it before the work */
    assert_int_equal(run("%s recon %s/cr10nt.mat --iters 5 -o %s/nt50", scicap, dir, dir), 0);
    expect_stderr("", "WARNING: the measurement matches the first 10 of the 50 mask frames");
    assert_int_equal(run("%s recon %s/cr10nt.mat --frames 10 --iters 5 -o %s/nt10", scicap, dir, dir), 0);
    assert_null(strstr(read_stderr(), "WARNING"));
    assert_int_equal(count_frames("nt10"), 10);
    assert_int_equal(run("%s recon %s/cr10nt.mat --frames 51 -o %s/x", scicap, dir, dir), 1);
    expect_stderr(NULL, "--frames 51, but the masks 'mask' hold 50 frames");
}

/* The real capture of data/real (float counts to ~945, measured grey masks 0–113, no truth): no options, frames
 * neither black nor saturated, the measurement fitted. */
static void test_real_capture(void **state)
{
    char real[4096];
    TESTDATA_REQUIRE("real/6fan14_cacti.mat", real);
    assert_int_equal(run("%s recon %s -o %s/real", scicap, real, dir), 0);
    expect_stderr("", "masks 'mask' peak at 113, divided by it");
    json_t *j = result_of("real");
    testdata_expect_real_levels(j, "real capture");
    json_decref(j);
}

/* A missing variable: exit 1, every variable listed with shape and class, the option named. */
static void test_missing_variable_lists_present(void **state)
{
    REQUIRE_DROP40();
    write_lab_files("e", MAT_FT_MAT5, MAT_C_DOUBLE);
    assert_int_equal(run("%s recon %s/datae.mat --mask %s/maske.mat -o %s/err", scicap, dir, dir, dir), 1);
    expect_stderr("missing meas: ", "no variable 'meas'");
    expect_stderr(NULL, "y 256x256x5 double");
    expect_stderr(NULL, "X 256x256x40 double");
    expect_stderr(NULL, "--meas-var");
    assert_int_equal(run("%s recon %s/datae.mat --meas-var y -o %s/err", scicap, dir, dir), 1);
    expect_stderr("missing mask: ", "no variable 'mask'");
    expect_stderr(NULL, "--mask FILE");
    assert_int_equal(run("%s recon %s/datae.mat --mask %s/maske.mat --meas-var y --truth-var orig -o %s/err", scicap,
                         dir, dir, dir),
                     1);
    expect_stderr(NULL, "--truth-var");
    /* Options that belong to .mat input are refused for a problem folder (usage error). (`dir` itself holds .mat
     * files, not a problem: scicap recon takes such a folder as a batch of its inputs.) */
    assert_int_equal(run("%s sim --default -o %s/prob", scicap, dir), 0);
    assert_int_equal(run("%s recon %s/prob --scale 1 -o %s/err", scicap, dir, dir), 2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lab_v5_double),
        cmocka_unit_test(test_lab_v73_single),
        cmocka_unit_test(test_scale_auto_from_meas),
        cmocka_unit_test(test_missing_variable_lists_present),
        cmocka_unit_test(test_scales_inferred_without_options),
        cmocka_unit_test(test_wrong_scale_warned),
        cmocka_unit_test(test_frames_of_a_longer_mask),
        cmocka_unit_test(test_real_capture),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
