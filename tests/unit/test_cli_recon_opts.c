/* tests/unit/test_cli_recon_opts.c — a method added to the table reaches `scicap recon`'s options and help with no
 * other edit: a table made of the real gap-tv row and a toy row (its own keys, an enum, a range) is handed to the
 * command line's functions (cli/recon_opts.h take the table as a parameter), which must accept --toy-knob, refuse
 * a value out of the toy's range naming it, reach toy keys by --set, and list the toy and its settings in the help.
 *
 * The module under test is the one scicap links: cli/recon_opts.o from the command line's archive
 * (libscicap-cli.a), which every test links. */
#include <errno.h>
#include <getopt.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "cli/recon_opts.h"
#include "recon/gaptv.h"
#include "recon/nerf/rayformer_solve.h"
#include "tests/helpers/testfiles.h"

/* The toy method: a knob, a mode and the "iters" every row must have; it never runs here. */
typedef struct toy_params {
    int iters;
    double knob;
    int mode;
} toy_params;

static const char *const toy_modes[] = {"calm", "wild", NULL};
static const solver_field toy_fields[] = {
    {"iters", SOLVER_FIELD_INT, offsetof(toy_params, iters), 1, 50, NULL, 0, "toy steps"},
    {"toy_knob", SOLVER_FIELD_DOUBLE, offsetof(toy_params, knob), 0.5, 2, NULL, 0, "how far the toy turns"},
    {"toy_mode", SOLVER_FIELD_ENUM, offsetof(toy_params, mode), 0, 0, toy_modes, 0, "the toy's temper"},
};

static void toy_defaults(void *s) { *(toy_params *)s = (toy_params){.iters = 3, .knob = 1, .mode = 0}; }
static void toy_preset(void *s, solver_preset p) { ((toy_params *)s)->iters = 10 * (1 + (int)p); }
static int toy_run(const sci_problem *p, const void *s, const solver_io *io, sci_result *r) { return -ENOSYS; }

static const char *const toy_bench[] = {"{\"iters\":1}", NULL};
static const solver_ops toy_solver = {
    .name = "toy",
    .summary = "a method that exists only in this test",
    .settings_size = sizeof(toy_params),
    .fields = {{toy_fields, sizeof toy_fields / sizeof toy_fields[0], 0}},
    .defaults = toy_defaults,
    .preset = toy_preset,
    .run = toy_run,
    .bench_quick = toy_bench,
    .bench_full = toy_bench,
};

static const solver_ops *const table[] = {&sci_gaptv_solver, &toy_solver, NULL};

/* The command's own options in this test: only the method (the real command's are in cli/recon.c). */
static const struct option own[] = {
    {"method", required_argument, 0, 'm'},
    {"preset", required_argument, 0, CLI_RECON_OPT_PRESET},
    {"set", required_argument, 0, CLI_RECON_OPT_SET},
    {"iters", required_argument, 0, CLI_RECON_OPT_SETTING_SHORT('i')},
    {0, 0, 0, 0},
};

/* Parse argv (NULL-terminated) as scicap recon does, then apply to the chosen method's fresh settings. Returns 0
 * or 2 as cli_recon_opts_apply; *out receives the settings (free them), *method the method. */
static int parse_in(const solver_ops *const *tbl, const char *const *args, const solver_ops **method, void **out);
static int parse(const char *const *args, const solver_ops **method, void **out)
{
    return parse_in(table, args, method, out);
}

/* The same with another table. An option getopt refuses (unknown, ambiguous) returns 1. */
static int parse_in(const solver_ops *const *tbl, const char *const *args, const solver_ops **method, void **out)
{
    char *argv[32];
    int argc = 0;
    argv[argc++] = (char *)"recon";
    while (*args)
        argv[argc++] = (char *)*args++;
    argv[argc] = NULL;
    struct option *all = cli_recon_opts_longopts(tbl, own);
    assert_non_null(all);
    cli_recon_given g = {.methods = tbl};
    *method = tbl[0];
    *out = NULL;
    int c, idx = -1, rc = 0;
    optind = 1;
    opterr = 0;
    while (rc == 0 && (c = getopt_long(argc, argv, "m:i:", all, &idx)) != -1) {
        if (c == '?')
            rc = 1;
        else if (c == 'm')
            rc = (*method = solver_list_find(tbl, optarg, NULL)) ? 0 : 2;
        else
            rc = cli_recon_opts_take(&g, all, c, idx, optarg);
        idx = -1;
    }
    free(all);
    if (rc)
        return rc;
    *out = solver_settings_new(*method);
    assert_non_null(*out);
    return cli_recon_opts_apply(&g, *method, *out);
}

static void test_toy_options(void **state)
{
    (void)state;
    sci_error err = {0};
    const solver_ops *m;
    void *s;
    /* the toy's own keys are options, its enum by name; -i and --set reach it as any method */
    assert_int_equal(parse((const char *[]){"-m", "toy", "--toy-knob", "1.5", "--toy-mode", "wild", "-i", "7", NULL},
                           &m, &s), 0);
    assert_ptr_equal(m, &toy_solver);
    const toy_params *t = s;
    assert_int_equal(t->iters, 7);
    assert_true(t->knob == 1.5);
    assert_int_equal(t->mode, 1);
    solver_settings_free(s);
    assert_int_equal(parse((const char *[]){"--method=toy", "--preset", "best", "--set", "toy_knob=0.75", NULL}, &m,
                           &s), 0);
    t = s;
    assert_int_equal(t->iters, 30);
    assert_true(t->knob == 0.75);
    solver_settings_free(s);
    /* the toy's range and names are the table's */
    assert_int_equal(parse((const char *[]){"-m", "toy", "--toy-knob", "3", NULL}, &m, &s), 2);
    solver_settings_free(s);
    assert_int_equal(parse((const char *[]){"-m", "toy", "--toy-mode", "sulky", NULL}, &m, &s), 2);
    solver_settings_free(s);
    assert_int_equal(parse((const char *[]){"-m", "toy", "-i", "51", NULL}, &m, &s), 2);
    solver_settings_free(s);
    /* another method ignores the toy's option, as it does every setting it lacks */
    assert_int_equal(parse((const char *[]){"-m", "gap-tv", "--toy-knob", "1", "-i", "9", NULL}, &m, &s), 0);
    assert_int_equal(((sci_gaptv_params *)s)->iters, 9);
    solver_settings_free(s);
    assert_int_equal(solver_list_find(table, "nope", &err), NULL);
    assert_non_null(strstr(err.msg, "(gap-tv, toy)"));
}

static void test_toy_help(void **state)
{
    (void)state;
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    assert_non_null(f);
    struct option *all = cli_recon_opts_longopts(table, own);
    cli_recon_methods_usage(f, table, 12);
    cli_recon_opts_usage(f, table, all);
    fclose(f);
    free(all);
    printf("%s", text);
    char want[160];
    snprintf(want, sizeof want, "  %-12s %s\n", toy_solver.name, toy_solver.summary);
    testfiles_expect_all(text, (const char *const[]){want, "\n  toy:\n", "--toy-knob X",
                                                     "how far the toy turns [0.5, 2]", "--toy-mode calm|wild",
                                                     "-i, --iters N", NULL});
    free(text);
}

/* An abbreviation that fits several settings options is refused, not taken as the first of them; the usual --pose
 * stays --pose-mode although the NeRF methods' other pose_* keys are options too. */
static void test_abbreviations(void **state)
{
    (void)state;
    const solver_ops *m;
    void *s = NULL;
    static const solver_ops *const nerf_table[] = {&sci_gaptv_solver, &sci_rayformer_solver, NULL};
    /* --toy fits --toy-knob and --toy-mode */
    assert_int_equal(parse((const char *[]){"-m", "toy", "--toy", "1.5", NULL}, &m, &s), 1);
    assert_null(s);
    /* a unique prefix still works */
    assert_int_equal(parse((const char *[]){"-m", "toy", "--toy-k", "1.5", NULL}, &m, &s), 0);
    assert_true(((toy_params *)s)->knob == 1.5);
    solver_settings_free(s);
    /* --pose is --pose-mode; --pose-l fits --pose-lr and --pose-lr-final */
    assert_int_equal(parse_in(nerf_table, (const char *[]){"-m", "rayformer", "--pose", "linear", NULL}, &m, &s), 0);
    json_t *j = solver_settings_to_json(m, s);
    assert_string_equal(json_string_value(json_object_get(j, "pose_mode")), "linear");
    json_decref(j);
    solver_settings_free(s);
    s = NULL;
    assert_int_equal(parse_in(nerf_table, (const char *[]){"-m", "rayformer", "--pose-l", "0.1", NULL}, &m, &s), 1);
    assert_null(s);
    assert_int_equal(parse_in(nerf_table, (const char *[]){"-m", "rayformer", "--pose-lr", "0.1", NULL}, &m, &s), 0);
    j = solver_settings_to_json(m, s);
    assert_true(json_number_value(json_object_get(j, "pose_lr")) == 0.1);
    json_decref(j);
    solver_settings_free(s);
    /* the help names the kept spelling */
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    struct option *all = cli_recon_opts_longopts(nerf_table, own);
    cli_recon_opts_usage(f, nerf_table, all);
    fclose(f);
    free(all);
    assert_non_null(strstr(text, "; also --pose\n"));
    free(text);
}

/* Every row of the real table fits the settings a by-value holder (scicapd's spec, daemon/protocol.h) reserves. */
static void test_settings_sizes(void **state)
{
    (void)state;
    size_t n = 0, biggest = 0;
    const solver_ops *const *l = solver_list(&n);
    for (size_t i = 0; i < n; i++) {
        printf("%-12s settings of %zu bytes\n", l[i]->name, l[i]->settings_size);
        biggest = l[i]->settings_size > biggest ? l[i]->settings_size : biggest;
    }
    printf("largest %zu of SOLVER_SETTINGS_MAX %d\n", biggest, SOLVER_SETTINGS_MAX);
    assert_true(biggest <= SOLVER_SETTINGS_MAX);
    assert_true(toy_solver.settings_size <= SOLVER_SETTINGS_MAX);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_toy_options),
        cmocka_unit_test(test_toy_help),
        cmocka_unit_test(test_abbreviations),
        cmocka_unit_test(test_settings_sizes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
