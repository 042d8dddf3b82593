/* scicapd reconstructs a capture of the simulated bench with desci through its real socket: the job reports
 * recon.progress events with an ETA (eta_s, finite and positive while iterations remain, elapsed_s growing), and a
 * cancel mid-run ends it with recon.canceled within the next iteration (the solver sees the job's flag), with no
 * result folder. About 4 s in all. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "tests/helpers/daemon_child.h"

static harness H;
static char scicap[1024];

static int group_setup(void **state)
{
    (void)state;
    return daemon_child_setup(&H, scicap, sizeof scicap,
                              "{\"reconstruction\": {\"workers\": 1, \"threads\": 2}}\n");
}

static int group_teardown(void **state)
{
    (void)state;
    return daemon_child_teardown(&H);
}

static void progress_with_eta_then_cancel(void **state)
{
    (void)state;
    hconn c;
    hconn_open(&c, &H);
    char cap[32];
    daemon_child_capture(&c, cap, sizeof cap, 30000);
    /* many cheap iterations at one σ (keys every 8 pixels, 20 patches a group, window ±8; a few seconds each on
     * 2 threads instead of half a minute at the defaults): the run would take far longer than the test */
    json_t *r = hconn_request(&c, "reconstruct",
                              json_pack("{s:s, s:s, s:{s:i, s:[i], s:i, s:i, s:i, s:i, s:i}}", "capture", cap, "method",
                                        "desci", "params", "iters", 1000, "sigma", 12, "tv_init", 0, "step", 8, "group",
                                        20, "window", 8, "metrics_every", 0));
    const json_int_t job = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    assert_true(job > 0);

    /* two progress events with an ETA */
    int progress = 0, last_iter = 0;
    double last_elapsed = -1, eta = NAN;
    const int64_t t0 = h_now_ms();
    while (progress < 2) {
        int left = 120000 - (int)(h_now_ms() - t0);
        json_t *m = left > 0 ? hconn_read(&c, left) : NULL;
        if (!m)
            fail_msg("%d progress event(s) within 120 s", progress);
        const char *ev = json_string_value(json_object_get(m, "event"));
        json_t *d = json_object_get(m, "data");
        if (ev && json_integer_value(json_object_get(m, "job")) == job) {
            if (!strcmp(ev, "recon.done") || !strcmp(ev, "recon.failed") || !strcmp(ev, "recon.canceled"))
                fail_msg("the job ended before the cancel: %s %s", ev,
                         json_string_value(json_object_get(d, "error")) ?: "");
            if (!strcmp(ev, "recon.progress")) {
                const int it = (int)json_integer_value(json_object_get(d, "iter"));
                const double el = json_number_value(json_object_get(d, "elapsed_s"));
                eta = json_number_value(json_object_get(d, "eta_s"));
                print_message("  recon.progress: iter %d of %lld, elapsed %.2f s, eta %.1f s\n", it,
                              (long long)json_integer_value(json_object_get(d, "iters")), el, eta);
                assert_int_equal(json_integer_value(json_object_get(d, "iters")), 1000);
                assert_true(it > last_iter && it < 1000);
                assert_true(el > last_elapsed);
                assert_true(isfinite(eta) && eta > 0);
                last_iter = it, last_elapsed = el;
                progress++;
            }
        }
        json_decref(m);
    }

    /* cancel: recon.canceled soon, nothing written */
    const int64_t t1 = h_now_ms();
    json_decref(hconn_request(&c, "cancel", json_pack("{s:I}", "job", job)));
    const char *end = NULL;
    json_t *m = NULL;
    while (!end) {
        int left = 60000 - (int)(h_now_ms() - t1);
        m = left > 0 ? hconn_read(&c, left) : NULL;
        if (!m)
            fail_msg("no end event within 60 s of the cancel");
        const char *ev = json_string_value(json_object_get(m, "event"));
        if (ev && json_integer_value(json_object_get(m, "job")) == job &&
            (!strcmp(ev, "recon.done") || !strcmp(ev, "recon.failed") || !strcmp(ev, "recon.canceled")))
            end = ev;
        else
            json_decref(m);
    }
    print_message("  %s %lld ms after the cancel (at iteration %d, last eta %.1f s); result folder: %s\n", end,
                  (long long)(h_now_ms() - t1), last_iter, eta,
                  daemon_child_recon_exists(&H, cap, "desci") ? "yes" : "no");
    assert_string_equal(end, "recon.canceled");
    /* the cancel reaches the solver inside an iteration: the run ends within the iteration after the last one
     * reported (a count, not a time: it holds on a loaded machine) */
    int done = -1;
    const char *why = json_string_value(json_object_get(json_object_get(m, "data"), "error"));
    assert_non_null(why);
    assert_int_equal(sscanf(why, "canceled after %d iterations", &done), 1);
    print_message("  %s\n", why);
    assert_true(done >= last_iter && done <= last_iter + 2);
    json_decref(m);
    assert_false(daemon_child_recon_exists(&H, cap, "desci"));
    hconn_close(&c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(progress_with_eta_then_cancel)};
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
