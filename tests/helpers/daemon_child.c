/* tests/helpers/daemon_child.c — see the header. */
#include "tests/helpers/daemon_child.h"

#include "io/problem_dir.h"
#include "tests/helpers/cli_child.h"

int daemon_child_setup(harness *h, char *scicap, size_t n, const char *config)
{
    if (cli_child_program(scicap, n, "scicap") < 0)
        return -1;
    harness_start(h, config, NULL);
    return 0;
}

int daemon_child_teardown(harness *h)
{
    harness_stop(h);
    harness_cleanup(h);
    return 0;
}

const char *daemon_child_capture(hconn *c, char *id, size_t n, int timeout_ms)
{
    json_decref(hconn_request(c, "capture", json_pack("{s:b}", "reconstruct", 0)));
    json_t *st = hconn_wait_event(c, "capture.stored", timeout_ms);
    snprintf(id, n, "%s", json_string_value(json_object_get(json_object_get(st, "data"), "capture")));
    json_decref(st);
    return id;
}

int daemon_child_resumed(hconn *c)
{
    json_t *r = hconn_request(c, "status", NULL);
    json_t *n = json_object_get(json_object_get(r, "recovered"), "reconstructions_resumed");
    int v = json_is_integer(n) ? (int)json_integer_value(n) : -1;
    json_decref(r);
    return v;
}

static void result_path(const harness *h, const char *cap, const char *method, char *p, size_t n)
{
    snprintf(p, n, "%s/captures/%s/recon/%s/result.json", h->store, cap, method);
}

int daemon_child_recon_exists(const harness *h, const char *cap, const char *method)
{
    char p[800];
    result_path(h, cap, method, p, sizeof p);
    return access(p, F_OK) == 0;
}

int daemon_child_wait_recon(const harness *h, const char *cap, const char *method, int timeout_ms)
{
    int64_t t0 = h_now_ms();
    while (!daemon_child_recon_exists(h, cap, method)) {
        if (h_now_ms() - t0 > timeout_ms)
            return 0;
        h_sleep_ms(50);
    }
    return 1;
}

json_t *daemon_child_result(const harness *h, const char *cap, const char *method)
{
    char p[800];
    json_error_t je;
    result_path(h, cap, method, p, sizeof p);
    json_t *r = json_load_file(p, 0, &je);
    if (!r)
        fail_msg("%s: %s", p, je.text);
    return r;
}

json_t *daemon_child_reconstruct(hconn *c, const char *cap, int iters)
{
    json_t *r = hconn_request(c, "reconstruct", json_pack("{s:s, s:s, s:{s:i}}", "capture", cap, "method", "gap-tv",
                                                         "params", "iters", iters));
    json_int_t job = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    for (;;) {
        json_t *e = hconn_wait_event(c, "recon.done", 60000);
        if (json_integer_value(json_object_get(e, "job")) == job) {
            json_t *d = json_incref(json_object_get(e, "data"));
            json_decref(e);
            return d;
        }
        json_decref(e);
    }
}

sci_problem *daemon_child_read_capture(const harness *h, const char *id)
{
    char d[600];
    snprintf(d, sizeof d, "%s/captures/%s", h->store, id);
    sci_problem **pp = NULL;
    int k = 0;
    sci_error err = {0};
    if (sci_problem_dir_read(d, &pp, &k, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(k, 1);
    sci_problem *p = pp[0];
    pp[0] = NULL;
    sci_problem_array_free(pp, k);
    return p;
}
