/* The NeRF methods' presets as points of their measured ceiling curves (io/ceiling.h): on the photographic scenes'
 * ceiling tables (bench/results/nerf_ceiling_photo_*.md), every method that needs a camera has its fast preset at
 * the least evaluated step within 1 dB of its plateau, balanced within 0.3 dB, best within 0.1 dB, on the table that
 * asks for the most steps; and its presets differ from fast only in steps, so the ceiling (a long run of fast's
 * settings) is the curve they sit on. A preset re-chosen without a new ceiling, or a ceiling re-measured without
 * re-choosing, fails here. The loader's own errors are checked on written tables. */
#include <errno.h>
#include <glob.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include <jansson.h>

#include "io/ceiling.h"

#define TABLES "bench/results/nerf_ceiling_photo_*.md"

static int preset_iters(const solver_ops *m, solver_preset p)
{
    void *s = solver_settings_new(m);
    assert_non_null(s);
    solver_settings_preset(m, s, p);
    int iters = solver_settings_iters(m, s);
    solver_settings_free(s);
    return iters;
}

/* The preset's settings as JSON with its step count replaced by `iters`. */
static json_t *settings_at(const solver_ops *m, solver_preset p, int iters)
{
    void *s = solver_settings_new(m);
    assert_non_null(s);
    solver_settings_preset(m, s, p);
    json_t *j = solver_settings_to_json(m, s);
    assert_non_null(j);
    json_object_set_new(j, "iters", json_integer(iters));
    solver_settings_free(s);
    return j;
}

static void test_presets_differ_in_steps_only(void **state)
{
    size_t n;
    const solver_ops *const *ms = solver_list(&n);
    int checked = 0;
    for (size_t i = 0; i < n; i++) {
        if (!(ms[i]->caps & SOLVER_NEEDS_CAMERA))
            continue;
        json_t *fast = settings_at(ms[i], SOLVER_PRESET_FAST, 0);
        for (int p = SOLVER_PRESET_BALANCED; p < SOLVER_PRESET_COUNT; p++) {
            json_t *other = settings_at(ms[i], (solver_preset)p, 0);
            if (!json_equal(fast, other)) {
                char *a = json_dumps(fast, JSON_SORT_KEYS), *b = json_dumps(other, JSON_SORT_KEYS);
                fail_msg("%s: %s differs from fast in more than its steps:\n  fast: %s\n  %s: %s", ms[i]->name,
                         solver_preset_name((solver_preset)p), a, solver_preset_name((solver_preset)p), b);
            }
            json_decref(other);
        }
        json_decref(fast);
        checked++;
    }
    assert_true(checked >= 2); /* rayformer and scinerf at least */
}

static void test_presets_on_the_ceilings(void **state)
{
    glob_t g;
    assert_int_equal(glob(TABLES, 0, NULL, &g), 0); /* no table: GLOB_NOMATCH, a failure, not a skip */
    static sci_ceiling tab[8];
    int nt = 0;
    assert_true(g.gl_pathc <= 8); /* every table is read: none dropped */
    for (size_t k = 0; k < g.gl_pathc; k++, nt++) {
        sci_error err = {0};
        if (sci_ceiling_load(g.gl_pathv[k], &tab[nt], &err) < 0)
            fail_msg("%s", err.msg);
    }
    size_t n;
    const solver_ops *const *ms = solver_list(&n);
    int methods = 0;
    for (size_t i = 0; i < n; i++) {
        if (!(ms[i]->caps & SOLVER_NEEDS_CAMERA))
            continue;
        for (int p = 0; p < SOLVER_PRESET_COUNT; p++) {
            sci_ceiling_place at;
            if (sci_ceiling_place_preset(tab, nt, ms[i]->name, (solver_preset)p, &at) < 0)
                fail_msg("%s: no ceiling measured on a photographic scene (%s)", ms[i]->name, TABLES);
            const int iters = preset_iters(ms[i], (solver_preset)p);
            printf("%s %s: %d steps; %s (plateau %.2f dB) puts it in (%d, %d]\n", ms[i]->name,
                   solver_preset_name((solver_preset)p), iters, g.gl_pathv[at.table], at.plateau_db, at.prev,
                   at.step);
            if (!sci_ceiling_place_holds(&at, iters))
                fail_msg("%s %s: %d steps, outside (%d, %d]", ms[i]->name, solver_preset_name((solver_preset)p),
                         iters, at.prev, at.step);
        }
        methods++;
    }
    globfree(&g);
    assert_true(methods >= 2);
}

/* Writes text to a temporary file and loads it; returns the load's result, the message in err. */
static int load_text(const char *text, sci_ceiling *c, sci_error *err)
{
    char path[] = "/tmp/scicap-ceiling-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, text, strlen(text)), (ssize_t)strlen(text));
    close(fd);
    int rc = sci_ceiling_load(path, c, err);
    unlink(path);
    return rc;
}

static void test_loader(void **state)
{
    static sci_ceiling c;
    sci_error err = {0};
    const char *head = "Prose.\n\n| method | step | wall s | PSNR dB | residual | largest weight |\n"
                       "|---|---:|---:|---:|---:|---:|\n";
    char text[1024];
    snprintf(text, sizeof text, "%s| m | 100 | 10.0 | 20.00 | 0.1 | 0.2 |\n| m | 200 | 20.0 | 24.50 | 0.1 | 0.2 |\n"
                                "| m | 300 | 30.0 | 25.00 | 0.1 | 0.2 |\n| m | 400 | 40.0 | 25.20 | 0.1 | 0.2 |\n", head);
    assert_int_equal(load_text(text, &c, &err), 0);
    assert_int_equal(c.n, 4);
    int step, prev;
    double plateau;
    assert_int_equal(sci_ceiling_preset_step(&c, "m", SOLVER_PRESET_FAST, &step, &prev, &plateau), 0);
    assert_int_equal(step, 200); /* 24.50 ≥ 25.20 − 1 */
    assert_int_equal(prev, 100);
    assert_true(plateau == 25.20);
    assert_int_equal(sci_ceiling_preset_step(&c, "m", SOLVER_PRESET_BALANCED, &step, &prev, &plateau), 0);
    assert_int_equal(step, 300); /* 25.00 ≥ 24.90 */
    assert_int_equal(sci_ceiling_preset_step(&c, "m", SOLVER_PRESET_BEST, &step, &prev, &plateau), 0);
    assert_int_equal(step, 400);
    assert_int_equal(sci_ceiling_preset_step(&c, "other", SOLVER_PRESET_FAST, &step, &prev, &plateau), -ENOENT);
    double at;
    assert_int_equal(sci_ceiling_psnr_at(&c, "m", 15.0, &at), 0);
    assert_float_equal(at, 22.25, 1e-9); /* halfway from 20.00 to 24.50 */
    assert_int_equal(sci_ceiling_psnr_at(&c, "m", 40.0, &at), 0);
    assert_float_equal(at, 25.20, 1e-9);
    assert_int_equal(sci_ceiling_psnr_at(&c, "m", 5.0, &at), -ERANGE);
    assert_int_equal(sci_ceiling_psnr_at(&c, "m", 41.0, &at), -ERANGE);
    assert_int_equal(sci_ceiling_psnr_at(&c, "other", 15.0, &at), -ENOENT);

    snprintf(text, sizeof text, "%s| m | 200 | 10.0 | 20.00 | 0.1 | 0.2 |\n| m | 100 | 20.0 | 24.50 | 0.1 | 0.2 |\n",
             head);
    assert_int_equal(load_text(text, &c, &err), SCI_EFORMAT);
    printf("steps going back: %s\n", err.msg);
    assert_non_null(strstr(err.msg, ":6: m: step 100 after step 200"));
    snprintf(text, sizeof text, "%s| m | 200 | 10.0 | twenty | 0.1 | 0.2 |\n", head);
    assert_int_equal(load_text(text, &c, &err), SCI_EFORMAT);
    assert_non_null(strstr(err.msg, ":5: not a ceiling row"));
    assert_int_equal(load_text(head, &c, &err), SCI_EFORMAT);
    assert_non_null(strstr(err.msg, "no ceiling rows"));
    assert_true(sci_ceiling_load("/nonexistent/ceiling.txt", &c, &err) == -ENOENT);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_loader),
        cmocka_unit_test(test_presets_differ_in_steps_only),
        cmocka_unit_test(test_presets_on_the_ceilings),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
