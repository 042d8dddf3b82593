/* tests/integration/test_extra_method.c — a new method is its file and one row of the table (recon/solver.c), and
 * nothing else: the test build in BUILD/extra-method/ (Makefile: recon/solver.c compiled with
 * -DSCICAP_EXTRA_SOLVER=sci_toy_mean_solver, tests/extra_method/toy_mean.c linked in) must offer "toy-mean" in
 *   - scicap --help and scicap recon --help: its summary, its options --iters/--gain with the table's help and range;
 *   - scicap recon --method toy-mean: --gain and --set gain=... set it (result.json's params say so), a value out
 *     of the table's range is refused naming the option;
 *   - scicapd: a capture reconstructed with it (recon/toy-mean/result.json, recon.done naming it), its params
 *     range-checked by the reconstruct request;
 *   - scicap bench --methods toy-mean: its quick grid measured into the CSV.
 * The toy has only "iters" (every row's) and a key of its own: the keys other methods share (metrics_every, ...)
 * must not be needed anywhere. Python is tests/python/test_extra_method.py. The normal build's programs must not
 * know the method (the row is what brings it). Everything here runs in a few seconds: the toy is a few passes over a 256x256x8 cube. */
#include <jansson.h>
#include <libgen.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "io/curves.h"
#include "tests/helpers/cli_child.h"
#include "tests/integration/daemon_harness.h"

static char build[1024];   /* BUILD, from this program's place (BUILD/tests/integration/x) */
static char scicap[1200];  /* BUILD/extra-method/scicap */
static char plain[1200];   /* BUILD/scicap: the build without the row */
static char dir[256];      /* this group's folder */
static char problem[400];  /* a simulated problem folder in dir */

static int group_setup(void **state)
{
    (void)state;
    char self[1024];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0)
        return -1;
    self[n] = 0;
    snprintf(build, sizeof build, "%s/../..", dirname(self));
    snprintf(scicap, sizeof scicap, "%s/extra-method/scicap", build);
    snprintf(plain, sizeof plain, "%s/scicap", build);
    if (access(scicap, X_OK) != 0 || access(plain, X_OK) != 0) {
        fprintf(stderr, "test_extra_method: %s or %s not built (make tests builds both)\n", scicap, plain);
        return -1;
    }
    snprintf(dir, sizeof dir, "/tmp/scicap-extra-method-XXXXXX");
    if (!mkdtemp(dir))
        return -1;
    snprintf(problem, sizeof problem, "%s/problem", dir);
    cli_child c;
    cli_child_run(&c, plain, (const char *const[]){"sim", "--default", "-q", "-o", problem, NULL}, dir);
    if (cli_child_exit_code(&c) != 0) {
        fprintf(stderr, "scicap sim --default failed: %s\n", c.err);
        return -1;
    }
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    return dir[0] ? cli_child_remove_dir(dir) : 0;
}

static void must_contain(const char *text, const char *want, const char *what)
{
    if (!strstr(text, want))
        fail_msg("%s lacks \"%s\":\n%s", what, want, text);
}

/* `prog recon --help` whole (malloc'd; cli_child keeps 8 KB of stdout, the text is longer): through a file. */
static char *recon_help(const char *prog)
{
    char path[300];
    snprintf(path, sizeof path, "%s/help.txt", dir);
    cli_child c;
    cli_child_run(&c, "/bin/sh", (const char *const[]){"-c", "exec \"$0\" recon --help > \"$1\"", prog, path, NULL},
                  dir);
    assert_int_equal(cli_child_exit_code(&c), 0);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char *text = calloc(1, 1 << 16);
    assert_non_null(text);
    size_t n = fread(text, 1, (1 << 16) - 1, f);
    fclose(f);
    assert_true(n > 0 && n < (1 << 16) - 1);
    return text;
}

/* The help texts list the method and its settings, all from the row. */
static void test_help(void **state)
{
    (void)state;
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"--help", NULL}, dir);
    assert_int_equal(cli_child_exit_code(&c), 0);
    must_contain(c.out, "  toy-mean    the snapshot over the masks' sum", "scicap --help");
    char *text = recon_help(scicap);
    must_contain(text, "  toy-mean     the snapshot over the masks' sum", "scicap recon --help");
    must_contain(text, "\n  toy-mean:\n", "scicap recon --help");
    must_contain(text, "--gain X", "scicap recon --help");
    must_contain(text, "step of each projection onto the snapshot [0.1, 1.9]", "scicap recon --help");
    must_contain(text, "projections after the mean start [1, 100]", "scicap recon --help");
    free(text);
    /* the normal build has no such row */
    text = recon_help(plain);
    must_contain(text, "\n  gap-tv:\n", "the normal build's scicap recon --help");
    assert_null(strstr(text, "toy-mean"));
    free(text);
}

/* result.json's params.gain of a reconstruction in out. */
static double result_gain(const char *out)
{
    char path[600];
    json_error_t je;
    snprintf(path, sizeof path, "%s/result.json", out);
    json_t *r = json_load_file(path, 0, &je);
    if (!r)
        fail_msg("%s: %s", path, je.text);
    json_t *params = json_object_get(r, "params");
    assert_string_equal(json_string_value(json_object_get(params, "method")), "toy-mean");
    double g = json_number_value(json_object_get(params, "gain"));
    json_decref(r);
    return g;
}

static void test_recon_options(void **state)
{
    (void)state;
    char out[400];
    cli_child c;
    snprintf(out, sizeof out, "%s/by-option", dir);
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", "--method", "toy-mean", "--gain", "0.7", "-i", "2",
                                                    problem, "-o", out, NULL}, dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("scicap recon --method toy-mean --gain 0.7: %s", c.err);
    assert_true(result_gain(out) == 0.7);
    snprintf(out, sizeof out, "%s/by-set", dir);
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", "--method", "toy-mean", "--set", "gain=0.5",
                                                    problem, "-o", out, NULL}, dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("scicap recon --method toy-mean --set gain=0.5: %s", c.err);
    assert_true(result_gain(out) == 0.5);
    /* the row's range, by either spelling */
    snprintf(out, sizeof out, "%s/refused", dir);
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", "--method", "toy-mean", "--gain", "5", problem,
                                                    "-o", out, NULL}, dir);
    assert_int_equal(cli_child_exit_code(&c), 2);
    must_contain(c.err, "--gain wants a number in [0.1, 1.9], got '5'", "--gain 5");
    cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", "--method", "toy-mean", "--set", "gain=5", problem,
                                                    "-o", out, NULL}, dir);
    assert_int_equal(cli_child_exit_code(&c), 2);
    must_contain(c.err, "toy-mean: gain: must be a number in [0.1, 1.9] (got 5)", "--set gain=5");
    assert_int_equal(access(out, F_OK), -1);
}

/* scicapd from the extra build: a capture reconstructed with the toy, its settings checked by the request. */
static void test_daemon(void **state)
{
    (void)state;
    harness h;
    harness_init(&h, NULL);
    snprintf(h.bin, sizeof h.bin, "%s/extra-method/scicapd", build);
    if (access(h.bin, X_OK) != 0)
        fail_msg("no %s (make tests builds it)", h.bin);
    harness_spawn(&h, NULL);
    hconn c;
    hconn_open(&c, &h);
    /* refused for the row's range of gain, not for a key the row lacks */
    json_t *m = hconn_call(&c, "capture", json_pack("{s:b, s:s, s:{s:f}}", "reconstruct", 1, "method", "toy-mean",
                                                    "params", "gain", 5.0));
    json_t *e = json_object_get(m, "error");
    const char *msg = json_string_value(json_object_get(e, "message"));
    print_message("  scicapd refuses gain 5: %s\n", msg ? msg : "(accepted)");
    assert_string_equal(json_string_value(json_object_get(e, "code")), "bad_arguments");
    assert_non_null(strstr(msg, "gain"));
    assert_non_null(strstr(msg, "1.9"));
    json_decref(m);
    json_decref(hconn_request(&c, "capture", json_pack("{s:b, s:s, s:{s:f, s:i}}", "reconstruct", 1, "method",
                                                      "toy-mean", "params", "gain", 0.6, "iters", 2)));
    json_t *st = hconn_wait_event(&c, "capture.stored", 20000);
    char cap[64];
    snprintf(cap, sizeof cap, "%s", json_string_value(json_object_get(json_object_get(st, "data"), "capture")));
    json_decref(st);
    json_t *done = hconn_wait_event(&c, "recon.done", 30000);
    json_t *d = json_object_get(done, "data");
    assert_string_equal(json_string_value(json_object_get(d, "method")), "toy-mean");
    double psnr = json_number_value(json_object_get(d, "psnr"));
    print_message("  scicapd: %s reconstructed by toy-mean, %.2f dB\n", cap, psnr);
    assert_true(psnr > 10);
    json_decref(done);
    char path[800];
    snprintf(path, sizeof path, "%s/captures/%s/recon/toy-mean/result.json", h.store, cap);
    json_error_t je;
    json_t *r = json_load_file(path, 0, &je);
    if (!r)
        fail_msg("%s: %s", path, je.text);
    assert_true(json_number_value(json_object_get(json_object_get(r, "params"), "gain")) == 0.6);
    json_decref(r);
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

/* scicap bench measures the toy's quick grid (its bench_quick: iters 1 and 4) like any method's; the second point's
 * setting names its real and its boolean as --set reads them, and reads back to that point. */
static void test_bench(void **state)
{
    (void)state;
    char out[400], csv[450];
    snprintf(out, sizeof out, "%s/bench", dir);
    snprintf(csv, sizeof csv, "%s/results.csv", out);
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"bench", "--quick", "--methods", "toy-mean", "--scene", "video2d",
                                                    "-j", "1", "--out", out, "--csv", csv, NULL}, dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("scicap bench --methods toy-mean: %s", c.err);
    FILE *f = fopen(csv, "r");
    assert_non_null(f);
    char line[512];
    int rows = 0, toy = 0, named = 0;
    while (fgets(line, sizeof line, f)) {
        rows++;
        toy += strncmp(line, "video2d,toy-mean,iters=", 23) == 0;
        named += strncmp(line, "video2d,toy-mean,iters=4 gain=0.7 mean_start=false,", 51) == 0;
    }
    fclose(f);
    print_message("  bench: %d toy-mean points of %d rows\n", toy, rows - 1);
    assert_int_equal(toy, 2);
    assert_int_equal(rows, 3);
    assert_int_equal(named, 1);
    json_t *js = sci_curves_setting_json("iters=4 gain=0.7 mean_start=false"); /* what a budget choice runs */
    assert_int_equal(json_integer_value(json_object_get(js, "iters")), 4);
    assert_true(json_real_value(json_object_get(js, "gain")) == 0.7);
    assert_true(json_is_false(json_object_get(js, "mean_start")));
    json_decref(js);
    /* and in the report's table of the scene */
    char md[450];
    snprintf(md, sizeof md, "%s/report.md", out);
    f = fopen(md, "r");
    assert_non_null(f);
    char *text = calloc(1, 1 << 16);
    assert_non_null(text);
    size_t n = fread(text, 1, (1 << 16) - 1, f);
    fclose(f);
    assert_true(n > 0);
    must_contain(text, "| toy-mean | iters=1 |", "the bench report");
    free(text);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help),
        cmocka_unit_test(test_recon_options),
        cmocka_unit_test(test_daemon),
        cmocka_unit_test(test_bench),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
