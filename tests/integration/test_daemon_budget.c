/* scicapd's reconstruct request with a time budget: it picks, from the measured accuracy-against-time curves,
 * the most accurate setting that fits, says what it picked, and refuses a budget nothing fits. The curves here
 * are a small hand-written CSV in the `scicap bench` format, so the expected choice is known exactly. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "tests/integration/daemon_harness.h"

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
    char path[800];
    snprintf(path, sizeof path, "%s/captures/%s/recon/%s/result.json", h->store, cap, method);
    json_t *r = json_load_file(path, 0, NULL);
    if (!r)
        fail_msg("no %s", path);
    json_t *p = json_incref(json_object_get(r, "params"));
    json_decref(r);
    return p;
}

static void budget_picks_from_curves(void **state)
{
    (void)state;
    harness h;
    harness_init(&h, NULL);
    char csv[400], cfg[800];
    snprintf(csv, sizeof csv, "%s/curves.csv", h.dir);
    FILE *f = fopen(csv, "w");
    assert_non_null(f);
    fputs(curves, f);
    fclose(f);
    snprintf(cfg, sizeof cfg, "{\"reconstruction\": {\"curves\": \"%s\"}}", csv);
    harness_write_config(&h, cfg);
    harness_spawn(&h, NULL);
    hconn c;
    hconn_open(&c, &h);
    json_decref(hconn_request(&c, "capture", json_pack("{s:b}", "reconstruct", 0)));
    json_t *st = hconn_wait_event(&c, "capture.stored", 20000);
    char cap[64];
    snprintf(cap, sizeof cap, "%s", json_string_value(json_object_get(json_object_get(st, "data"), "capture")));
    json_decref(st);

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
    harness_stop(&h);
    harness_cleanup(&h);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(budget_picks_from_curves)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
