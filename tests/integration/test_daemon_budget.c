/* scicapd's reconstruct request with a time budget: it picks, from the measured accuracy-against-time curves,
 * the most accurate setting that fits, says what it picked, and refuses a budget nothing fits. The curves here
 * are a small hand-written CSV in the `scicap bench` format, so the expected choice is known exactly. Without
 * reconstruction.curves the daemon finds them as installed, or through $SCICAP_DATADIR, or — run from a build tree
 * before `make install` — in the tree's bench/results.csv. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "tests/helpers/daemon_child.h"

/* Two scenes of 256×256×8 without a camera; times in seconds of solver time. */
static const char curves[] =
    "scene,method,setting,psnr_db,psnr_peak1_db,ssim,wall_s,cpu_s,peak_rss_mib,pareto,recommended,threads,voxels,camera\n"
    "a,gap-tv,iters=10 tv_iters=5,15.0,15.0,0.3,0.010,0.02,100,1,0,2,524288,0\n"
    "b,gap-tv,iters=10 tv_iters=5,16.0,16.0,0.3,0.012,0.02,100,1,0,2,524288,0\n"
    "a,gap-tv,iters=50 tv_iters=5,30.0,30.0,0.9,0.050,0.10,100,1,1,2,524288,0\n"
    "b,gap-tv,iters=50 tv_iters=5,31.0,31.0,0.9,0.060,0.10,100,1,1,2,524288,0\n"
    "a,admm-tv,iters=100 tv_iters=5,33.0,33.0,0.95,0.400,0.8,100,1,1,2,524288,0\n"
    "b,admm-tv,iters=100 tv_iters=5,34.0,34.0,0.95,0.450,0.8,100,1,1,2,524288,0\n"
    "s,rayformer,iters=300 patch=8 samples=32,20.0,20.0,0.5,40.0,80,300,1,1,2,131072,1\n";

static json_t *result_params(const harness *h, const char *cap, const char *method)
{
    json_t *r = daemon_child_result(h, cap, method);
    json_t *p = json_incref(json_object_get(r, "params"));
    json_decref(r);
    return p;
}

/* The hand-written curves as h's folder/name; its path into path (n bytes). */
static void write_curves(const harness *h, const char *name, char *path, size_t n)
{
    snprintf(path, n, "%s/%s", h->dir, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(curves, f);
    fclose(f);
}

static void budget_picks_from_curves(void **state)
{
    (void)state;
    harness h;
    harness_init(&h, NULL);
    char csv[400], cfg[800];
    write_curves(&h, "curves.csv", csv, sizeof csv);
    snprintf(cfg, sizeof cfg, "{\"reconstruction\": {\"curves\": \"%s\"}}", csv);
    harness_write_config(&h, cfg);
    harness_spawn(&h, NULL);
    hconn c;
    hconn_open(&c, &h);
    char cap[64];
    daemon_child_capture(&c, cap, sizeof cap, 20000);

    /* 0.1 s: gap-tv 50 iterations (30.5 dB mean, 0.06 s) fits; admm-tv (0.45 s) does not. */
    json_decref(hconn_request(&c, "reconstruct", json_pack("{s:s, s:f}", "capture", cap, "budget_s", 0.1)));
    json_decref(hconn_wait_event(&c, "recon.done", 60000));
    json_t *p = result_params(&h, cap, "gap-tv");
    assert_int_equal(json_integer_value(json_object_get(p, "iters")), 50);
    json_t *b = json_object_get(p, "budget");
    assert_non_null(b);
    assert_true(fabs(json_number_value(json_object_get(b, "predicted_s")) - 0.06) < 1e-9);
    assert_true(fabs(json_number_value(json_object_get(b, "expected_psnr_db")) - 30.5) < 1e-9);
    json_decref(p);

    /* 1 s: admm-tv 100 iterations, the most accurate (33.5 dB). */
    json_decref(hconn_request(&c, "reconstruct", json_pack("{s:s, s:f}", "capture", cap, "budget_s", 1.0)));
    json_decref(hconn_wait_event(&c, "recon.done", 60000));
    p = result_params(&h, cap, "admm-tv");
    assert_int_equal(json_integer_value(json_object_get(p, "iters")), 100);
    json_decref(p);

    /* 1 ms: nothing fits; refused, naming the cheapest. */
    json_t *m = hconn_call(&c, "reconstruct", json_pack("{s:s, s:f}", "capture", cap, "budget_s", 0.001));
    assert_true(json_is_false(json_object_get(m, "ok")));
    const char *msg = json_string_value(json_object_get(json_object_get(m, "error"), "message"));
    printf("  tiny budget: %s\n", msg);
    assert_non_null(strstr(msg, "cheapest"));
    assert_non_null(strstr(msg, "budget_s"));
    json_decref(m);
    hconn_close(&c);
    daemon_child_teardown(&h);
}

/* After harness_init: scicapd started with $SCICAP_DATADIR at datadir, c connected, and one capture stored (its id
 * into cap). */
static void spawn_with_datadir(harness *h, const char *datadir, hconn *c, char *cap, size_t ncap)
{
    char env[600];
    snprintf(env, sizeof env, "SCICAP_DATADIR=%s", datadir);
    char *envv[] = {env, NULL};
    harness_spawn(h, envv);
    hconn_open(c, h);
    daemon_child_capture(c, cap, ncap, 20000);
}

/* No curves in the config: $SCICAP_DATADIR/results.csv wins over the installed file (here: the hand-written
 * curves, so the choice is known: gap-tv 50 iterations for 0.1 s). */
static void budget_curves_from_env_datadir(void **state)
{
    (void)state;
    harness h;
    harness_init(&h, NULL);
    char csv[400], cap[64];
    write_curves(&h, "results.csv", csv, sizeof csv);
    hconn c;
    spawn_with_datadir(&h, h.dir, &c, cap, sizeof cap);
    json_decref(hconn_request(&c, "reconstruct", json_pack("{s:s, s:f}", "capture", cap, "budget_s", 0.1)));
    json_decref(hconn_wait_event(&c, "recon.done", 60000));
    json_t *p = result_params(&h, cap, "gap-tv");
    assert_int_equal(json_integer_value(json_object_get(p, "iters")), 50);
    json_decref(p);
    hconn_close(&c);
    daemon_child_teardown(&h);
}

/* The binary run from the build tree, nothing installed where $SCICAP_DATADIR points: the daemon falls back to
 * <build>/../bench/results.csv, the measured curves `scicap recon --capture ID --budget S` needs before
 * `make install`. The chosen setting must be one of that file's rows. */
static void budget_curves_from_build_tree(void **state)
{
    (void)state;
    char self[1024], tree_csv[1100];
    ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
    assert_true(len > 0);
    self[len] = '\0';
    /* BUILD/tests/integration/test_daemon_budget -> BUILD/../bench/results.csv, as the daemon computes it */
    snprintf(tree_csv, sizeof tree_csv, "%s/../../../bench/results.csv", dirname(self));
    if (access(tree_csv, R_OK) != 0)
        fail_msg("no %s: the build tree's curves are part of the checkout", tree_csv);
    harness h;
    harness_init(&h, NULL);
    char datadir[400], cap[64];
    snprintf(datadir, sizeof datadir, "%s/not-installed", h.dir);
    hconn c;
    spawn_with_datadir(&h, datadir, &c, cap, sizeof cap);
    json_decref(hconn_request(&c, "reconstruct", json_pack("{s:s, s:f}", "capture", cap, "budget_s", 5.0)));
    json_t *e = hconn_wait_event(&c, "recon.done", 60000);
    const char *method = json_string_value(json_object_get(json_object_get(e, "data"), "method"));
    assert_non_null(method);
    char m[32];
    snprintf(m, sizeof m, "%s", method);
    json_decref(e);
    json_t *p = result_params(&h, cap, m);
    json_t *b = json_object_get(p, "budget");
    assert_non_null(b);
    double predicted = json_number_value(json_object_get(b, "predicted_s"));
    json_int_t iters = json_integer_value(json_object_get(p, "iters"));
    json_int_t tv = json_integer_value(json_object_get(p, "tv_iters"));
    printf("  5 s from the build tree's curves: %s iters=%lld tv_iters=%lld, predicted %.3f s, expected %.2f dB\n",
           m, (long long)iters, (long long)tv, predicted, json_number_value(json_object_get(b, "expected_psnr_db")));
    assert_true(predicted > 0 && predicted <= 5.0);
    /* the setting it ran is a row of bench/results.csv (the hand-written curves above have no such row) */
    FILE *f = fopen(tree_csv, "r");
    assert_non_null(f);
    char line[4096], want[256];
    snprintf(want, sizeof want, ",%s,iters=%lld tv_iters=%lld,", m, (long long)iters, (long long)tv);
    int found = 0;
    while (!found && fgets(line, sizeof line, f))
        found = strstr(line, want) != NULL;
    fclose(f);
    if (!found)
        fail_msg("no row '%s' in %s", want, tree_csv);
    json_decref(p);
    hconn_close(&c);
    daemon_child_teardown(&h);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(budget_picks_from_curves),
                                       cmocka_unit_test(budget_curves_from_env_datadir),
                                       cmocka_unit_test(budget_curves_from_build_tree)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
