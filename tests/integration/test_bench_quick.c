/* The accuracy-against-time report pipeline, end to end on the quick suite: `scicap bench --quick` runs every
 * method in child processes and must produce the CSV, the report and one plot per scene, with each method's
 * Pareto front and exactly one recommended setting per (scene, method). Checks correctness of the report, not
 * speed: the figures themselves come from `make bench-report` on a quiet machine. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>
#include <errno.h>

/* Under AddressSanitizer (make check-asan) the quick report runs on static3d alone, the one scene on which every
 * method of the table runs: the same methods and the same checks, the other scenes' points left to the optimised
 * build (over every scene this test alone took 13 of check-asan's 23 minutes). */
#if defined(__SANITIZE_ADDRESS__)
#define QUICK_SCENES " --scene static3d"
#define QUICK_CAMERA 1 /* the kind of problem the budget picks are for: the scenes measured have a camera */
static const char *const plots[] = {"static3d"};
#else
#define QUICK_SCENES ""
#define QUICK_CAMERA 0
static const char *const plots[] = {"video2d", "static3d"};
#endif

#include "io/curves.h"
#include "recon/gaptv.h"
#include "recon/pnp_ffdnet.h"
#include "recon/solver.h"

static void test_quick_report(void **state)
{
    const char *build = getenv("BUILD");
    char dir[] = "/tmp/scicap-test-bench-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "%s/scicap bench --quick%s --out %s --csv %s/results.csv 2>%s/log",
             build ? build : "build", QUICK_SCENES, dir, dir, dir);
    if (*QUICK_SCENES)
        printf("(AddressSanitizer build:%s)\n", QUICK_SCENES);
    int rc = system(cmd);
    if (rc != 0) {
        snprintf(cmd, sizeof cmd, "cat %s/log", dir);
        if (system(cmd) != 0)
            fprintf(stderr, "(no log)\n");
        fail_msg("scicap bench --quick failed (%d)", rc);
    }
    char path[2200];
    snprintf(path, sizeof path, "%s/results.csv", dir);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[1024];
    assert_non_null(fgets(line, sizeof line, f));
    assert_non_null(strstr(line, "scene,method,setting,psnr_db"));
    /* scene, method -> count of recommended; scenes seen */
    _Static_assert(SOLVER_NAME_MAX == 32, "the sscanf width below reads SOLVER_NAME_MAX - 1 bytes");
    char keys[64][32 + SOLVER_NAME_MAX];
    int rec[64] = {0}, nk = 0, rows = 0, fronts = 0;
    while (fgets(line, sizeof line, f)) {
        char scene[32], method[SOLVER_NAME_MAX], setting[96];
        double psnr, psnr1, ssim, wall, cpu, rss;
        int pareto, recommended, threads, camera;
        double voxels;
        int got = sscanf(line, "%31[^,],%31[^,],%95[^,],%lf,%lf,%lf,%lf,%lf,%lf,%d,%d,%d,%lf,%d", scene, method,
                         setting, &psnr, &psnr1, &ssim, &wall, &cpu, &rss, &pareto, &recommended, &threads, &voxels,
                         &camera);
        assert_int_equal(got, 14);
        assert_true(voxels >= 128 * 128 * 8);
        assert_true(isfinite(psnr) && isfinite(ssim) && wall > 0 && rss > 1);
        rows++;
        fronts += pareto;
        char key[32 + SOLVER_NAME_MAX];
        snprintf(key, sizeof key, "%s/%s", scene, method);
        int k;
        for (k = 0; k < nk && strcmp(keys[k], key) != 0; k++)
            ;
        if (k == nk && nk < 64)
            snprintf(keys[nk++], sizeof keys[0], "%s", key);
        if (k < 64)
            rec[k] += recommended;
    }
    fclose(f);
    printf("%d points, %d on fronts, %d scene/method pairs\n", rows, fronts, nk);
    assert_true(rows >= 8);
    assert_true(nk >= 6); /* the classical methods on every scene, rayformer and scinerf on static3d */
    for (int k = 0; k < nk; k++)
        if (rec[k] != 1)
            fail_msg("%s has %d recommended settings, expected exactly 1", keys[k], rec[k]);
    /* The time-budget picker reads the same CSV: a generous budget picks the most accurate setting, a tiny one
     * is refused with the cheapest named. */
    sci_curves *cv;
    sci_error err = {0};
    snprintf(path, sizeof path, "%s/results.csv", dir);
    if (sci_curves_load(&cv, path, &err) < 0)
        fail_msg("%s", err.msg);
    sci_curve_choice ch;
    assert_int_equal(sci_curves_pick(cv, NULL, QUICK_CAMERA, 256 * 256 * 8, 1e6, &ch, &err), 0);
    printf("1e6 s budget, camera %d: %s %s, %.2f dB mean, %.3f s\n", QUICK_CAMERA, ch.method, ch.setting, ch.mean_psnr,
           ch.predicted_s);
    sci_curve_choice tight;
    assert_int_equal(sci_curves_pick(cv, NULL, QUICK_CAMERA, 256 * 256 * 8, 1e-9, &tight, &err), -ERANGE);
    assert_non_null(strstr(err.msg, "cheapest"));
    assert_true(tight.predicted_s <= ch.predicted_s);
    assert_int_equal(sci_curves_pick(cv, "rayformer", 1, 128 * 128 * 8, 1e6, &ch, &err), 0);
    assert_int_equal(sci_curves_pick(cv, "rayformer", 0, 128 * 128 * 8, 1e6, &ch, &err), -ENOENT);
    assert_int_equal(sci_curves_pick(cv, "scinerf", 1, 128 * 128 * 8, 1e6, &ch, &err), 0);
    assert_non_null(strstr(ch.setting, "preset=fast"));
    sci_curves_free(cv);
    snprintf(path, sizeof path, "%s/report.md", dir);
    assert_int_equal(access(path, R_OK), 0);
    for (size_t i = 0; i < sizeof plots / sizeof plots[0]; i++) {
        snprintf(path, sizeof path, "%s/psnr_time_%s.png", dir, plots[i]);
        if (access(path, R_OK) != 0)
            fail_msg("missing plot %s", path);
    }
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
}

/* A curve setting reads back as `scicap recon --set` reads it, and the solver takes what it reads. */
static void test_setting_json(void **state)
{
    (void)state;
    sci_error err = {0};
    json_t *js = sci_curves_setting_json("iters=100 tv_iters=5");
    assert_int_equal(json_integer_value(json_object_get(js, "iters")), 100);
    json_decref(js);
    /* the NeRF points name their preset: a word stays a string, a number an integer */
    js = sci_curves_setting_json("preset=fast iters=20");
    assert_non_null(js);
    assert_string_equal(json_string_value(json_object_get(js, "preset")), "fast");
    assert_int_equal(json_integer_value(json_object_get(js, "iters")), 20);
    json_decref(js);
    /* a list setting is written 50/25 (no comma in a CSV column) and reads back as the list */
    js = sci_curves_setting_json("iters=10 sigma=50/25");
    const solver_ops *pnp = solver_find("pnp-ffdnet");
    void *ps = solver_settings_new(pnp);
    assert_int_equal(solver_settings_from_json(pnp, ps, js, NULL, "setting", &err), 0);
    assert_int_equal(((const sci_pnp_params *)ps)->sigma.n, 2);
    assert_true(((const sci_pnp_params *)ps)->sigma.v[1] == 25);
    json_decref(js);
    /* a list of one is written as its number (the grids' sigma=[12]) and reads back as that list */
    js = sci_curves_setting_json("iters=10 sigma=12");
    if (solver_settings_from_json(pnp, ps, js, NULL, "setting", &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(((const sci_pnp_params *)ps)->sigma.n, 1);
    assert_true(((const sci_pnp_params *)ps)->sigma.v[0] == 12);
    solver_settings_free(ps);
    json_decref(js);
    assert_null(sci_curves_setting_json("iters="));
    assert_null(sci_curves_setting_json("=5"));
    assert_null(sci_curves_setting_json("iters"));
    char longset[SCI_CURVE_SETTING_MAX + 8];
    memset(longset, 0, sizeof longset);
    for (size_t k = 0; k + 8 < SCI_CURVE_SETTING_MAX; k += 8)
        memcpy(longset + k, "iters=1 ", 8);
    assert_non_null(js = sci_curves_setting_json(longset)); /* SCI_CURVE_SETTING_MAX − 1 bytes and less: read */
    json_decref(js);
    strcat(longset, "iters=1 ");
    assert_null(sci_curves_setting_json(longset)); /* longer: refused, not cut to a prefix */
    /* a real stays a real: a budget choice of lambda=0.5 runs, not refused as the string "0.5" */
    js = sci_curves_setting_json("iters=10 lambda=0.5");
    assert_true(json_is_real(json_object_get(js, "lambda")));
    const solver_ops *gap = solver_find("gap-tv");
    void *gs = solver_settings_new(gap);
    if (solver_settings_from_json(gap, gs, js, NULL, "setting", &err) < 0)
        fail_msg("%s", err.msg);
    assert_true(((const sci_gaptv_params *)gs)->lambda == 0.5);
    solver_settings_free(gs);
    json_decref(js);
}

/* A grid point's settings written as the setting's text read back equal: types kept, a real to the last bit, a
 * string that looks like another value quoted; what the text cannot hold is refused, never written wrong. */
static void test_setting_text(void **state)
{
    (void)state;
    static const char *const same[] = {
        "{\"preset\": \"fast\", \"iters\": 300}", "{\"lambda\": 0.30000000000000004, \"w\": 1e-07}",
        "{\"x\": 3.0, \"on\": false, \"z\": null}", "{\"s\": \"5\", \"t\": \"true\", \"u\": \"[1]\"}",
        "{\"q\": \"\\\"fast\\\"\", \"path\": \"a/b\", \"neg\": -2}",
    };
    char text[SCI_CURVE_SETTING_MAX];
    for (size_t i = 0; i < sizeof same / sizeof same[0]; i++) {
        json_t *obj = json_loads(same[i], 0, NULL), *back = NULL;
        assert_non_null(obj);
        assert_int_equal(sci_curves_setting_text(obj, text, sizeof text), 0);
        if (!json_equal(obj, back = sci_curves_setting_json(text)))
            fail_msg("%s written as '%s' read back otherwise", same[i], text);
        json_decref(back);
        json_decref(obj);
    }
    json_t *obj = json_loads("{\"iters\": 20, \"sigma\": [50, 25], \"s\": \"5\"}", 0, NULL);
    assert_int_equal(sci_curves_setting_text(obj, text, sizeof text), 0);
    assert_string_equal(text, "iters=20 sigma=50/25 s=\"5\""); /* the list as the solvers read a list */
    const size_t len = strlen(text);
    assert_int_equal(sci_curves_setting_text(obj, text, len + 1), 0); /* an exact fit is kept */
    assert_int_equal(sci_curves_setting_text(obj, text, len), -ENAMETOOLONG); /* one byte short: refused, empty */
    assert_string_equal(text, "");
    json_decref(obj);
    static const char *const refused[] = {
        "{\"s\": \"a b\"}", "{\"s\": \"a,b\"}", "{\"s\": \"\"}",      "{\"o\": {}}",           "{\"l\": [\"a\"]}",
        "{\"l\": []}",      "{\"k=x\": 1}",     "{\"\": 1}",           "{\"s\": \"a\\nb\"}",
    };
    for (size_t i = 0; i < sizeof refused / sizeof refused[0]; i++) {
        assert_non_null(obj = json_loads(refused[i], 0, NULL));
        if (sci_curves_setting_text(obj, text, sizeof text) != -EINVAL)
            fail_msg("%s was written as '%s'", refused[i], text);
        json_decref(obj);
    }
}

/* Re-measuring one method keeps the others' points from the previous CSV: the report and plots still show them.
 * On static3d alone (its 15 GAP-TV points): the keeping is per row, and the whole suite's 75 points took 56 s. */
static void test_methods_keep_the_others(void **state)
{
    const char *build = getenv("BUILD");
    char dir[] = "/tmp/scicap-test-bench-keep-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[2200], cmd[4096];
    snprintf(path, sizeof path, "%s/results.csv", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "scene,method,setting,psnr_db,psnr_peak1_db,ssim,wall_s,cpu_s,peak_rss_mib,pareto,recommended,threads,"
               "voxels,camera\n"
               "static3d,rayformer,preset=fast,23.0400,23.1000,0.85940,227.5,450.1,546.0,1,1,2,131072,1\n"
               "static3d,gap-tv,iters=1 tv_iters=1,1.0,1.0,0.1,0.001,0.001,10.0,1,1,2,131072,1\n"
               "nosuchscene,admm-tv,iters=5 tv_iters=2,9.0,9.0,0.1,0.01,0.01,10.0,1,1,2,131072,0\n"
               "static3d,admm-tv,");
    for (int k = 0; k < 160; k++) /* a setting too long to keep, on a line over 1 KiB: dropped whole, and said */
        fputs("iters=5 ", f);
    fputs("tv_iters=2,9.0,9.0,0.1,0.01,0.01,10.0,1,1,2,131072,0\n", f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/scicap bench --full --methods gap-tv --scene static3d --out %s --csv %s 2>%s/log",
             build ? build : "build", dir, path, dir);
    if (system(cmd) != 0) {
        snprintf(cmd, sizeof cmd, "cat %s/log", dir);
        assert_int_equal(system(cmd), 0);
        fail_msg("scicap bench --full --methods gap-tv failed");
    }
    /* the rayformer row is kept as it was; the old gap-tv row is replaced by the measured ones; a row of a scene
     * not in the suite is dropped */
    snprintf(cmd, sizeof cmd, "grep -c '^static3d,rayformer,preset=fast,23.0400,' %s | grep -qx 1", path);
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "grep -q 'iters=1 tv_iters=1' %s", path);
    assert_int_not_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "grep -q nosuchscene %s", path);
    assert_int_not_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "grep -q '1 row of scenes not in the suite dropped' %s/log", dir); /* and says so */
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "grep -q 'results.csv:5: not kept: setting of 1290 bytes' %s/log && ! grep -q admm-tv %s",
             dir, path);
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "grep -c ',gap-tv,' %s | awk '$1 >= 15 { ok = 1 } END { exit !ok }'", path);
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "grep -q '| rayformer | preset=fast | 23.04 |' %s/report.md && grep -q 'kept from the "
             "previous full run' %s/report.md", dir, dir);
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
}

/* A curves file whose setting is too long for SCI_CURVE_SETTING_MAX is refused at its line, not read cut short (a
 * cut setting would be run as a different one). */
static void test_long_setting_refused(void **state)
{
    (void)state;
    char path[] = "/tmp/scicap-test-curves-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    FILE *f = fdopen(fd, "w");
    assert_non_null(f);
    fprintf(f, "scene,method,setting,psnr_db,psnr_peak1_db,ssim,wall_s,cpu_s,peak_rss_mib,pareto,recommended,threads,"
               "voxels,camera\nstatic3d,gap-tv,iters=5 tv_iters=2,15.0,15.5,0.4,0.5,0.5,100,1,1,1,131072,1\n"
               "static3d,gap-tv,");
    for (int k = 0; k < SCI_CURVE_SETTING_MAX / 8; k++)
        fputs("iters=5 ", f);
    fputs("tv_iters=2,15.0,15.5,0.4,0.5,0.5,100,1,1,1,131072,1\n", f);
    fclose(f);
    sci_curves *cv = NULL;
    sci_error err = {0};
    assert_int_equal(sci_curves_load(&cv, path, &err), SCI_EFORMAT);
    assert_non_null(strstr(err.msg, ":3: "));
    assert_non_null(strstr(err.msg, "setting longer than"));
    unlink(path);
}

/* A run refused after its scenes folder was made (an unknown --scene) exits 2 and leaves nothing in $TMPDIR. */
static void test_refused_run_leaves_no_scenes(void **state)
{
    const char *build = getenv("BUILD");
    char dir[] = "/tmp/scicap-test-bench-tmp-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "TMPDIR=%s %s/scicap bench --quick --scene nosuchscene --out %s/out --csv %s/r.csv "
             "2>%s/log; echo $? > %s/rc", dir, build ? build : "build", dir, dir, dir, dir);
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "grep -qx 2 %s/rc && grep -q \"unknown scene 'nosuchscene'\" %s/log", dir, dir);
    assert_int_equal(system(cmd), 0);
    snprintf(cmd, sizeof cmd, "ls -d %s/scicap-bench-* 2>/dev/null | grep -q .", dir);
    if (system(cmd) == 0)
        fail_msg("the refused run left its scenes folder in %s", dir);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_quick_report),
                                       cmocka_unit_test(test_methods_keep_the_others),
                                       cmocka_unit_test(test_refused_run_leaves_no_scenes),
                                       cmocka_unit_test(test_long_setting_refused),
                                       cmocka_unit_test(test_setting_json),
                                       cmocka_unit_test(test_setting_text)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
