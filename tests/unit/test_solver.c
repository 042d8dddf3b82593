/* tests/unit/test_solver.c — the method table (recon/solver.h): lookup by name, presets (one vocabulary, the
 * deprecated aliases, the values each method had before the table), settings to/from JSON with clear errors, the
 * bench grids, and a run through the table that matches the method's own solve bit for bit and can be canceled. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "recon/admmtv.h"
#include "recon/gaptv.h"
#include "recon/nerf/rayformer_solve.h"
#include "recon/nerf/scinerf_solve.h"
#include "recon/nerf/trainer.h"
#include "recon/solver.h"
#include "sim/default_scene.h"
#include "sim/simulate.h"

static void test_lookup(void **state)
{
    (void)state;
    size_t n = 0;
    const solver_ops *const *l = solver_list(&n);
    assert_true(n >= 4);
    assert_null(l[n]);
    for (size_t i = 0; i < n; i++) {
        assert_ptr_equal(solver_find(l[i]->name), l[i]);
        assert_non_null(l[i]->summary);
        assert_non_null(l[i]->run);
    }
    assert_ptr_equal(solver_find(sci_gaptv_solver.name), &sci_gaptv_solver);
    assert_ptr_equal(solver_find(sci_rayformer_solver.name), &sci_rayformer_solver);
    char upper[64];
    snprintf(upper, sizeof upper, "%s", l[0]->name);
    for (char *c = upper; *c; c++)
        *c = (char)(*c >= 'a' && *c <= 'z' ? *c - 'a' + 'A' : *c);
    assert_null(solver_find(upper)); /* names are case-sensitive */
    assert_null(solver_find(NULL));
    sci_error err = {0};
    assert_null(solver_find_err("nope", &err));
    printf("%s\n", err.msg);
    /* the list in the message is the table's, in its order */
    char names[256], want[300];
    solver_names_text(names, sizeof names, ", ");
    snprintf(want, sizeof want, "unknown method 'nope' (%s)", names);
    assert_non_null(strstr(err.msg, want));
    snprintf(want, sizeof want, "%s, %s", l[0]->name, l[1]->name);
    assert_non_null(strstr(names, want));
    /* a table handed in (the command line's seam) is searched as given, and named in the message */
    const solver_ops *const mine[] = {l[1], NULL};
    assert_ptr_equal(solver_list_find(mine, l[1]->name, &err), l[1]);
    assert_null(solver_list_find(mine, l[0]->name, &err));
    snprintf(want, sizeof want, "unknown method '%s' (%s)", l[0]->name, l[1]->name);
    assert_string_equal(err.msg, want);
    assert_int_equal(solver_list_check(&err), 0);
    /* a name that a SOLVER_NAME_MAX buffer would cut is refused; one byte shorter fits */
    char longest[SOLVER_NAME_MAX + 1];
    memset(longest, 'x', sizeof longest - 1);
    longest[SOLVER_NAME_MAX] = 0;
    solver_ops too_long = sci_gaptv_solver;
    too_long.name = longest;
    const solver_ops *const bad[] = {l[0], &too_long, NULL};
    assert_int_equal(solver_table_check(bad, &err), -EINVAL);
    printf("%s\n", err.msg);
    assert_non_null(strstr(err.msg, "SOLVER_NAME_MAX"));
    longest[SOLVER_NAME_MAX - 1] = 0;
    assert_int_equal(solver_table_check(bad, &err), 0);
    /* a checkpointing method's name must also fit the checkpoint header, which keeps its 16 bytes */
    solver_ops ckpt = sci_rayformer_solver;
    ckpt.name = "rayformer-16byte";
    const solver_ops *const bad_ckpt[] = {&ckpt, NULL};
    assert_int_equal((int)strlen(ckpt.name), NERF_CKPT_METHOD_MAX);
    assert_int_equal(solver_table_check(bad_ckpt, &err), -EINVAL);
    printf("%s\n", err.msg);
    assert_non_null(strstr(err.msg, "checkpoint header"));
    ckpt.name = "rayformer-15byt";
    assert_int_equal(solver_table_check(bad_ckpt, &err), 0);
    /* only the NeRF methods need a camera and checkpoint */
    assert_false(sci_gaptv_solver.caps & SOLVER_NEEDS_CAMERA);
    assert_true(sci_scinerf_solver.caps & SOLVER_NEEDS_CAMERA);
    assert_true(sci_rayformer_solver.caps & SOLVER_CHECKPOINTS);
}

/* The presets' values: the classical methods' from their measured curves (fast 80, balanced 130, best 300, 5 TV
 * passes each) and the NeRF preset functions' for rayformer and scinerf. */
static void test_presets(void **state)
{
    (void)state;
    solver_preset p;
    int dep = -1;
    sci_error err = {0};
    assert_int_equal(solver_preset_parse("balanced", &p, &dep, &err), 0);
    assert_int_equal(p, SOLVER_PRESET_BALANCED);
    assert_int_equal(dep, 0);
    assert_int_equal(solver_preset_parse("default", &p, &dep, &err), 0);
    assert_int_equal(p, SOLVER_PRESET_BALANCED);
    assert_int_equal(dep, 1);
    assert_int_equal(solver_preset_parse("quality", &p, &dep, &err), 0);
    assert_int_equal(p, SOLVER_PRESET_BEST);
    assert_int_equal(solver_preset_parse("turbo", &p, NULL, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "fast, balanced, best"));
    /* the same words read from JSON (scicapd's configuration and requests): an alias is the preset it means,
     * absent is 1, anything else is refused at its path */
    static const char text[] = "{\"a\": \"quality\",\n \"b\": \"turbo\", \"c\": 3}";
    sci_json_doc *doc = NULL;
    assert_int_equal(sci_json_doc_load_string(&doc, "r.json", text, sizeof text - 1, &err), 0);
    const json_t *o = sci_json_doc_root(doc);
    assert_int_equal(solver_preset_get(doc, o, "", "a", &p, &err), 0);
    assert_int_equal(p, SOLVER_PRESET_BEST);
    assert_int_equal(solver_preset_get(doc, o, "", "none", &p, &err), 1);
    assert_int_equal(solver_preset_get(doc, o, "", "b", &p, &err), SCI_ECONFIG);
    assert_string_equal(err.msg, "r.json:2:2: b: must be fast, balanced or best (got \"turbo\")");
    assert_int_equal(solver_preset_get(doc, o, "", "c", &p, &err), SCI_ECONFIG);
    sci_json_doc_free(doc);

    /* the presets are written once, in each method's file: here only their relations (GAP-TV and ADMM-TV share
     * the measured points; each preset costs more than the one before) */
    int prev_iters = 0;
    for (int k = 0; k < SOLVER_PRESET_COUNT; k++) {
        sci_gaptv_params g;
        sci_admmtv_params a;
        sci_gaptv_params_default(&g);
        sci_admmtv_params_default(&a);
        solver_settings_preset(&sci_gaptv_solver, &g, (solver_preset)k);
        solver_settings_preset(&sci_admmtv_solver, &a, (solver_preset)k);
        assert_true(g.iters > prev_iters);
        prev_iters = g.iters;
        assert_int_equal(a.iters, g.iters);
        assert_int_equal(a.tv_iters, g.tv_iters);
        sci_rayformer_params r1, r2;
        sci_rayformer_params_default(&r1);
        sci_rayformer_params_default(&r2);
        solver_settings_preset(&sci_rayformer_solver, &r1, (solver_preset)k);
        assert_int_equal(sci_rayformer_params_preset(&r2, solver_preset_names[k]), 0);
        assert_memory_equal(&r1, &r2, sizeof r1);
        sci_scinerf_params s1, s2;
        sci_scinerf_params_default(&s1);
        sci_scinerf_params_default(&s2);
        solver_settings_preset(&sci_scinerf_solver, &s1, (solver_preset)k);
        assert_int_equal(sci_scinerf_params_preset(&s2, solver_preset_names[k]), 0);
        assert_memory_equal(&s1, &s2, sizeof s1);
    }
    /* balanced is the defaults, for every method but the TV ones: their defaults are PnP-SCI's benchmark settings
     * (100 × 5, reproducing its published figures), their balanced preset the measured curve's (130 × 5) */
    for (const solver_ops *const *m = solver_list(NULL); *m; m++) {
        if (*m == &sci_gaptv_solver || *m == &sci_admmtv_solver)
            continue;
        void *d = solver_settings_new(*m), *b = solver_settings_new(*m);
        solver_settings_preset(*m, b, SOLVER_PRESET_BALANCED);
        json_t *jd = solver_settings_to_json(*m, d), *jb = solver_settings_to_json(*m, b);
        assert_true(json_equal(jd, jb));
        json_decref(jd), json_decref(jb);
        solver_settings_free(d), solver_settings_free(b);
    }
    /* the rayformer presets: each trains longer than the one before, on the same windows and samples, and best
     * decays the rate at least as far */
    sci_rayformer_params r[SOLVER_PRESET_COUNT];
    for (int k = 0; k < SOLVER_PRESET_COUNT; k++) {
        sci_rayformer_params_default(&r[k]);
        solver_settings_preset(&sci_rayformer_solver, &r[k], (solver_preset)k);
        if (k > 0) {
            assert_true(r[k].iters > r[k - 1].iters);
            assert_int_equal(r[k].samples, r[0].samples);
            assert_int_equal(r[k].patches_per_step, r[0].patches_per_step);
            assert_true(r[k].lr_final <= r[k - 1].lr_final);
        }
    }
}

static void test_json(void **state)
{
    (void)state;
    sci_error err = {0};
    for (const solver_ops *const *m = solver_list(NULL); *m; m++) {
        /* to_json reads back to the same settings */
        void *a = solver_settings_new(*m), *b = solver_settings_new(*m);
        solver_settings_preset(*m, a, SOLVER_PRESET_FAST);
        json_t *j = solver_settings_to_json(*m, a);
        assert_non_null(j);
        if (solver_settings_from_json(*m, b, j, NULL, "settings", &err) != 0)
            fail_msg("%s: %s", (*m)->name, err.msg);
        assert_memory_equal(a, b, (*m)->settings_size);
        json_decref(j);
        /* every bench grid point is valid settings */
        for (int q = 0; q < 2; q++)
            for (const char *const *g = q ? (*m)->bench_full : (*m)->bench_quick; g && *g; g++) {
                json_t *pt = json_loads(*g, 0, NULL);
                assert_non_null(pt);
                void *s = solver_settings_new(*m);
                if (solver_settings_from_json(*m, s, pt, NULL, "point", &err) != 0)
                    fail_msg("%s %s: %s", (*m)->name, *g, err.msg);
                solver_settings_free(s);
                json_decref(pt);
            }
        solver_settings_free(a), solver_settings_free(b);
    }
    /* errors name the method, the key and the value */
    sci_gaptv_params g;
    sci_gaptv_params_default(&g);
    json_t *bad = json_pack("{s:i, s:f}", "iters", 50, "gamma", 0.1);
    assert_int_equal(solver_settings_from_json(&sci_gaptv_solver, &g, bad, NULL, "params", &err), -EINVAL);
    printf("%s\n", err.msg);
    char want[160];
    snprintf(want, sizeof want, "%s: params.gamma: no such setting", sci_gaptv_solver.name);
    assert_non_null(strstr(err.msg, want));
    json_decref(bad);
    bad = json_pack("{s:f}", "iters", 2.5);
    assert_int_equal(solver_settings_from_json(&sci_gaptv_solver, &g, bad, NULL, "params", &err), -EINVAL);
    const solver_field *iters = solver_field_find(&sci_gaptv_solver, "iters", NULL);
    snprintf(want, sizeof want, "params.iters: must be an integer in [%.15g, %.15g] (got 2.5)", iters->lo, iters->hi);
    assert_non_null(strstr(err.msg, want));
    json_decref(bad);
    bad = json_pack("{s:s}", "preset", "quality");
    assert_int_equal(solver_settings_from_json(&sci_gaptv_solver, &g, bad, NULL, "params", &err), 0);
    assert_int_equal(g.iters, 300);
    json_decref(bad);
    bad = json_pack("{s:s}", "method", sci_admmtv_solver.name);
    assert_true(solver_settings_from_json(&sci_gaptv_solver, &g, bad, NULL, "params", &err) < 0);
    json_decref(bad);
    /* enums by name; the ablation action; the bench's patch rule keeps the rays per step */
    sci_rayformer_params r;
    sci_rayformer_params_default(&r);
    json_t *rj = json_pack("{s:s, s:s, s:s, s:i, s:i}", "preset", "fast", "pose_mode", "per-frame", "ablation",
                           "inter", "patch", 8, "table", 14);
    assert_int_equal(solver_settings_from_json(&sci_rayformer_solver, &r, rj, NULL, "s", &err), 0);
    assert_int_equal(r.pose_mode, NERF_POSES_PER_FRAME);
    assert_true(r.patch_sampling && r.inter_ray && !r.intra_ray && r.tv_weight == 0);
    assert_int_equal(r.patch, 8);
    assert_int_equal(r.patches_per_step, 128 * 4 / 64); /* the fast preset's 128 windows of 2 × 2 */
    assert_int_equal(r.log2_table, 14);
    json_decref(rj);
    rj = json_pack("{s:s}", "pose_mode", "sideways");
    assert_true(solver_settings_from_json(&sci_rayformer_solver, &r, rj, NULL, "s", &err) < 0);
    assert_non_null(strstr(err.msg, "must be one of known, linear, per-frame (got 'sideways')"));
    json_decref(rj);
}

static int count_rows(const sci_trace_entry *e, void *user)
{
    (void)e;
    ++*(int *)user;
    return 0;
}

/* A run through the table equals the method's own solve bit for bit; the cancel flag stops it. */
static void test_run_and_cancel(void **state)
{
    (void)state;
    sim_scene *sc = NULL;
    sci_error err = {0};
    if (sim_default_scene_load(&sc, &err) < 0 || sim_scene_set_snapshots(sc, 1, &err) < 0)
        fail_msg("%s", err.msg);
    sci_problem **p = NULL;
    int k = 0;
    assert_int_equal(sim_run(sc, &p, &k, NULL, NULL, NULL, &err), 0);
    sim_scene_free(sc);
    sci_gaptv_params g;
    sci_gaptv_params_default(&g);
    g.iters = 12;
    sci_result a = {0}, b = {0};
    assert_int_equal(sci_gaptv_solve(p[0], &g, &a, NULL, NULL), 0);
    int rows = 0;
    solver_io io = {.progress = count_rows, .user = &rows};
    assert_int_equal(solver_run(&sci_gaptv_solver, p[0], &g, &io, &b), 0);
    assert_int_equal(rows, 12);
    assert_string_equal(b.method, sci_gaptv_solver.name);
    assert_memory_equal(a.frames->data, b.frames->data, sci_cube_count(a.frames) * sizeof(float));
    sci_result_free_contents(&a);
    sci_result_free_contents(&b);
    /* cancel: the flag set before the run stops it after its first iteration */
    atomic_int cancel = 1;
    sci_result c = {0};
    io.cancel = &cancel;
    rows = 0;
    assert_int_equal(solver_run(&sci_admmtv_solver, p[0], &(sci_admmtv_params){.iters = 50, .lambda = 1,
                                                                             .tv_weight = 0.07, .tv_iters = 2},
                                &io, &c),
                     SCI_ECANCELED);
    assert_int_equal(c.iters_done, 1);
    assert_int_equal(rows, 1);
    sci_result_free_contents(&c);
    /* invalid settings are refused with the method's message */
    g.iters = 0;
    sci_result d = {0};
    assert_int_equal(solver_run(&sci_gaptv_solver, p[0], &g, NULL, &d), -EINVAL);
    char want[96];
    snprintf(want, sizeof want, "%s: iters must be in", sci_gaptv_solver.name);
    assert_non_null(strstr(d.error.msg, want));
    sci_result_free_contents(&d);
    sci_problem_array_free(p, k);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lookup),
        cmocka_unit_test(test_presets),
        cmocka_unit_test(test_json),
        cmocka_unit_test(test_run_and_cancel),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
