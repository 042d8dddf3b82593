/* `scicap status` and `scicap devices` for people, and --json for programs: against a real scicapd on
 * the simulated bench, the tables carry the values of the daemon's own JSON reply (pid, queues, job counts, each
 * device's backend, state and identity fields, the per-stage timing), no JSON syntax; --json prints
 * the reply as it came (parsed and compared with the one read on the socket).
 * And the rest of the client's output for people: a reconstruction without truth reports the measurement residual
 * (never a PSNR of 0), a budget says what it chose, a capture is named by its number too, events are lines, jobs
 * lists the active and recent ones (--all: every one), a cancel that cancels nothing fails, a refused argument
 * names the option (not the request's JSON position), and `scicap captures` lists the store. */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "io/matfile.h"
#include "recon/sci_ops.h"
#include "tests/helpers/daemon_child.h"
#include "tests/helpers/cli_child.h"

static harness H;
static char scicap[1024];

static void run_client(cli_child *c, const char *cmd, const char *json_flag)
{
    cli_child_run(c, scicap, (const char *const[]){cmd, "--socket", H.sock, json_flag, NULL}, H.dir);
    if (cli_child_exit_code(c) != 0)
        fail_msg("scicap %s exit %d: %s", cmd, cli_child_exit_code(c), c->err);
}

/* `scicap ARGS... --socket SOCK`; returns the exit status. */
static int scicap_run(cli_child *c, const char *const *args)
{
    const char *argv[24];
    int n = 0;
    while (args[n] && n < 20) {
        argv[n] = args[n];
        n++;
    }
    argv[n++] = "--socket";
    argv[n++] = H.sock;
    argv[n] = NULL;
    cli_child_run(c, scicap, argv, H.dir);
    print_message("  scicap %s ...: exit %d\n%s%s", args[0], cli_child_exit_code(c), c->out, c->err);
    return cli_child_exit_code(c);
}

/* Lines of text holding `word`. */
static int count_lines(const char *text, const char *word)
{
    int n = 0;
    for (const char *l = text; l && *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : NULL) {
        const char *end = strchr(l, '\n');
        size_t len = end ? (size_t)(end - l) : strlen(l);
        char line[1024];
        snprintf(line, sizeof line, "%.*s", (int)(len < sizeof line ? len : sizeof line - 1), l);
        n += strstr(line, word) != NULL;
    }
    return n;
}

/* A line of `text` that starts with `head` (after spaces) and contains `value`. */
static void assert_line(const char *text, const char *head, const char *value)
{
    for (const char *l = text; l && *l; l = strchr(l, '\n') ? strchr(l, '\n') + 1 : NULL) {
        const char *p = l;
        while (*p == ' ')
            p++;
        const char *end = strchr(p, '\n');
        size_t n = end ? (size_t)(end - p) : strlen(p);
        char line[512];
        snprintf(line, sizeof line, "%.*s", (int)(n < sizeof line ? n : sizeof line - 1), p);
        if (!strncmp(line, head, strlen(head)) && strstr(line, value))
            return;
    }
    fail_msg("no line starting \"%s\" with \"%s\" in:\n%s", head, value, text);
}

static void test_status_table_and_json(void **state)
{
    hconn c;
    hconn_open(&c, &H);
    /* something in the counters: one capture, reconstructed */
    json_decref(hconn_request(&c, "capture", json_pack("{s:b, s:s}", "reconstruct", 1, "preset", "fast")));
    json_decref(hconn_wait_event(&c, "recon.done", 60000));
    json_t *st = hconn_request(&c, "status", NULL);
    cli_child out;
    run_client(&out, "status", NULL);
    print_message("%s", out.out);
    assert_null(strchr(out.out, '{'));
    char v[64];
    snprintf(v, sizeof v, "pid %lld,", (long long)json_integer_value(json_object_get(st, "pid")));
    assert_line(out.out, "scicapd ", v);
    assert_line(out.out, "state", "ready");
    assert_line(out.out, "storage", H.store);
    json_t *q = json_object_get(json_object_get(st, "queues"), "reconstruction");
    snprintf(v, sizeof v, "reconstruction %lld/%lld", (long long)json_integer_value(json_array_get(q, 0)),
             (long long)json_integer_value(json_array_get(q, 1)));
    assert_line(out.out, "queues", v);
    snprintf(v, sizeof v, "%lld finished", (long long)json_integer_value(json_object_get(json_object_get(st, "jobs"),
                                                                                        "finished")));
    assert_line(out.out, "jobs", v);
    assert_line(out.out, "dmd", "connected");
    assert_line(out.out, "clients", "connected, 0 watching");
    assert_line(out.out, "recon_solve", "ms CPU"); /* the stage counters */
    assert_line(out.out, "store", "runs");
    /* --json: the reply as it came */
    run_client(&out, "status", "--json");
    json_error_t je;
    json_t *j = json_loads(out.out, 0, &je);
    if (!j)
        fail_msg("scicap status --json: %s in:\n%s", je.text, out.out);
    assert_int_equal(json_integer_value(json_object_get(j, "pid")), json_integer_value(json_object_get(st, "pid")));
    assert_true(json_equal(json_object_get(j, "devices"), json_object_get(st, "devices")));
    assert_non_null(json_object_get(json_object_get(j, "timing"), "recon_write"));
    json_decref(j);
    json_decref(st);
    hconn_close(&c);
}

static void test_devices_table_and_json(void **state)
{
    hconn c;
    hconn_open(&c, &H);
    json_t *devs = hconn_request(&c, "devices", NULL);
    hconn_close(&c);
    cli_child out;
    run_client(&out, "devices", NULL);
    print_message("%s", out.out);
    assert_null(strchr(out.out, '{'));
    const char *name;
    json_t *d;
    int n = 0;
    json_object_foreach(devs, name, d) {
        assert_line(out.out, name, json_string_value(json_object_get(d, "backend")));
        n++;
    }
    assert_int_equal(n, 3);
    /* identities, flattened: every string field of the DMD and the camera's identity shows with its value */
    assert_line(out.out, "serial", json_string_value(json_object_get(json_object_get(devs, "dmd"), "serial")));
    assert_line(out.out, "model", json_string_value(json_object_get(json_object_get(devs, "dmd"), "model")));
    assert_line(out.out, "identity.card", json_string_value(json_object_get(
                                              json_object_get(json_object_get(devs, "camera"), "identity"), "card")));
    run_client(&out, "devices", "--json");
    json_error_t je;
    json_t *j = json_loads(out.out, 0, &je);
    if (!j)
        fail_msg("scicap devices --json: %s in:\n%s", je.text, out.out);
    assert_true(json_equal(j, devs));
    json_decref(j);
    json_decref(devs);
    /* jobs --json too */
    run_client(&out, "jobs", "--json");
    j = json_loads(out.out, 0, &je);
    assert_non_null(j);
    assert_true(json_is_array(json_object_get(j, "jobs")));
    json_decref(j);
}

/* The number of capture id "c000042" as text ("42"). */
static const char *bare(const char *id, char *buf, size_t n)
{
    snprintf(buf, n, "%lu", strtoul(id + 1, NULL, 10));
    return buf;
}

/* A .mat of one 64×64×8 snapshot without a truth variable, in the test's folder. */
static void write_mat_without_truth(char *path, size_t n)
{
    snprintf(path, n, "%s/notruth.mat", H.dir);
    sci_problem *p = calloc(1, sizeof *p);
    sci_cube *x = NULL;
    sci_error err = {0};
    assert_int_equal(sci_cube_new(&p->mask, 64, 64, 8, &err), 0);
    assert_int_equal(sci_cube_new(&p->meas, 64, 64, 1, &err), 0);
    assert_int_equal(sci_cube_new(&x, 64, 64, 8, &err), 0);
    unsigned seed = 7;
    for (size_t i = 0; i < sci_cube_count(x); i++) {
        p->mask->data[i] = rand_r(&seed) % 2;
        x->data[i] = (float)((i / 64 + i % 64) % 50) / 100.0f; /* diagonal stripes, white 0.5 */
    }
    sci_op_forward(p->mask, x, p->meas);
    for (size_t i = 0; i < sci_cube_count(p->meas); i++)
        p->meas->data[i] /= 8; /* on the scale of one frame: a .mat's measurement stays below white */
    p->peak = 1;
    snprintf(p->name, sizeof p->name, "notruth");
    if (sci_mat_write(path, &p, 1, 255, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube_free(x);
    sci_problem_free(p);
}

/* Without truth there is no PSNR to report: the measurement residual is (the store's listing too). */
static void test_no_truth_reports_residual(void **state)
{
    char mat[400];
    write_mat_without_truth(mat, sizeof mat);
    cli_child c;
    assert_int_equal(scicap_run(&c, (const char *const[]){"capture", "--from", mat, "--recon", "gap-tv", "--preset",
                                                           "fast", "--wait", NULL}), 0);
    assert_non_null(strstr(c.out, "relative residual"));
    assert_null(strstr(c.out, "PSNR"));
    assert_null(strstr(c.err, "PSNR"));
    assert_null(strchr(c.out, '{'));
}

/* --budget says what it chose, as result.json records it, before the job runs. */
static void test_budget_says_its_choice(void **state)
{
    hconn h;
    hconn_open(&h, &H);
    char cap[32], num[16];
    daemon_child_capture(&h, cap, sizeof cap, 30000);
    hconn_close(&h);
    cli_child c;
    assert_int_equal(scicap_run(&c, (const char *const[]){"recon", "--capture", bare(cap, num, sizeof num), "--budget",
                                                           "5", "--wait", NULL}), 0);
    const char *dir = strstr(c.out, "-> ");
    assert_non_null(dir);
    char path[700];
    snprintf(path, sizeof path, "%.*s/result.json", (int)strcspn(dir + 3, "\n"), dir + 3);
    json_t *r = json_load_file(path, 0, NULL);
    assert_non_null(r);
    json_t *b = json_object_get(json_object_get(r, "params"), "budget");
    assert_non_null(b);
    char want[300];
    snprintf(want, sizeof want, "budget 5 s: %s %s, predicted %.3g s, expected PSNR %.2f dB",
             json_string_value(json_object_get(b, "method")), json_string_value(json_object_get(b, "setting")),
             json_number_value(json_object_get(b, "predicted_s")),
             json_number_value(json_object_get(b, "expected_psnr_db")));
    if (!strstr(c.out, want))
        fail_msg("no \"%s\" in:\n%s", want, c.out);
    json_decref(r);
}

/* A capture is named by its id, by c and its number, or by its number alone. */
static void test_capture_id_forms(void **state)
{
    hconn h;
    hconn_open(&h, &H);
    char cap[32], num[16], cnum[20], want[64];
    daemon_child_capture(&h, cap, sizeof cap, 30000);
    hconn_close(&h);
    snprintf(cnum, sizeof cnum, "c%s", bare(cap, num, sizeof num));
    snprintf(want, sizeof want, "gap-tv (fast) of %s", cap);
    const char *forms[] = {num, cnum, cap};
    for (int i = 0; i < 3; i++) {
        cli_child c;
        assert_int_equal(scicap_run(&c, (const char *const[]){"recon", "--capture", forms[i], "--method", "gap-tv",
                                                               "--preset", "fast", "--iters", "3", "--wait", NULL}), 0);
        assert_non_null(strstr(c.out, want));
    }
}

/* Until the daemon says `n` connections watch (its status), so a capture started next is seen from its first event;
 * fails the test after 10 s. */
static void wait_watchers(int n)
{
    hconn h;
    hconn_open(&h, &H);
    int now = -1;
    for (int waited = 0; waited < 10000 && now != n; waited += 20) {
        json_t *st = hconn_request(&h, "status", NULL);
        now = (int)json_integer_value(json_object_get(st, "watchers"));
        json_decref(st);
        if (now != n)
            usleep(20000);
    }
    hconn_close(&h);
    assert_int_equal(now, n);
}

/* --wait and watch print lines, not the events' JSON; watch ends on Ctrl-C at once. */
static void test_events_are_lines(void **state)
{
    cli_child w, c;
    cli_child_start(&w, scicap, (const char *const[]){"watch", "--socket", H.sock, NULL}, H.dir);
    wait_watchers(1);
    assert_int_equal(scicap_run(&c, (const char *const[]){"capture", "--recon", "--preset", "fast", "--wait", NULL}), 0);
    /* the events it must have printed before it stops */
    assert_int_equal(cli_child_wait_stdout(&w, "capture done: 1 of 1", 30000), 0);
    assert_int_equal(cli_child_wait_stdout(&w, " PSNR ", 30000), 0);
    kill(w.pid, SIGINT);
    cli_child_finish(&w);
    print_message("  watch: exit %d\n%s%s", cli_child_exit_code(&w), w.out, w.err);
    assert_int_equal(cli_child_exit_code(&w), 0);
    const char *outs[] = {c.out, w.out};
    for (int i = 0; i < 2; i++) {
        assert_null(strchr(outs[i], '{'));
        assert_non_null(strstr(outs[i], "capture done: 1 of 1 snapshot(s) stored (c"));
        assert_non_null(strstr(outs[i], "snapshot 1 of 1 taken, sync ok"));
        assert_non_null(strstr(outs[i], " PSNR "));
    }
    /* --json keeps the events as the daemon sent them */
    wait_watchers(0); /* the first watch gone, so the count below is the new one's */
    cli_child_start(&w, scicap, (const char *const[]){"watch", "--socket", H.sock, "--json", NULL}, H.dir);
    wait_watchers(1);
    assert_int_equal(scicap_run(&c, (const char *const[]){"capture", "--wait", NULL}), 0);
    assert_int_equal(cli_child_wait_stdout(&w, "\"capture.done\"", 30000), 0);
    kill(w.pid, SIGINT);
    cli_child_finish(&w);
    json_t *first = json_loadb(w.out, strcspn(w.out, "\n"), 0, NULL);
    assert_non_null(first);
    assert_string_equal(json_string_value(json_object_get(first, "event")), "capture.started");
    json_decref(first);
}

/* Finished jobs the daemon keeps, from its own list. */
static int finished_jobs(void)
{
    hconn h;
    hconn_open(&h, &H);
    json_t *r = hconn_request(&h, "jobs", NULL);
    hconn_close(&h);
    size_t i;
    json_t *j;
    int n = 0;
    json_array_foreach(json_object_get(r, "jobs"), i, j) {
        const char *s = json_string_value(json_object_get(j, "state"));
        n += !strcmp(s, "done") || !strcmp(s, "failed") || !strcmp(s, "canceled");
    }
    json_decref(r);
    return n;
}

/* jobs: the active ones and the 10 newest finished, saying how many are hidden; --all: every one. */
static void test_jobs_recent_and_all(void **state)
{
    hconn h;
    hconn_open(&h, &H);
    char cap[32];
    daemon_child_capture(&h, cap, sizeof cap, 30000);
    for (int i = 0; i < 12; i++) {
        json_decref(hconn_request(&h, "reconstruct", json_pack("{s:s, s:{s:i}}", "capture", cap, "params", "iters", 1)));
        json_decref(hconn_wait_event(&h, "recon.done", 30000));
    }
    hconn_close(&h);
    int finished = finished_jobs();
    assert_true(finished >= 13);
    cli_child c;
    assert_int_equal(scicap_run(&c, (const char *const[]){"jobs", NULL}), 0);
    char want[96];
    snprintf(want, sizeof want, "(%d older finished jobs hidden; scicap jobs --all lists them)", finished - 10);
    assert_non_null(strstr(c.out, want));
    assert_int_equal(count_lines(c.out, "  done  ") + count_lines(c.out, "  failed  ") +
                     count_lines(c.out, "  canceled  "), 10);
    assert_int_equal(scicap_run(&c, (const char *const[]){"jobs", "--all", NULL}), 0);
    assert_null(strstr(c.out, "hidden"));
    assert_int_equal(count_lines(c.out, "  done  ") + count_lines(c.out, "  failed  ") +
                     count_lines(c.out, "  canceled  "), finished);
}

/* cancel exits 1 when there was nothing to cancel: a finished job (its state said), an unknown one. */
static void test_cancel_exit_status(void **state)
{
    hconn h;
    hconn_open(&h, &H);
    char cap[32], job[32];
    daemon_child_capture(&h, cap, sizeof cap, 30000);
    json_t *r = hconn_request(&h, "reconstruct", json_pack("{s:s, s:{s:i}}", "capture", cap, "params", "iters", 2));
    snprintf(job, sizeof job, "%lld", (long long)json_integer_value(json_object_get(r, "job")));
    json_decref(r);
    json_decref(hconn_wait_event(&h, "recon.done", 30000));
    cli_child c;
    assert_int_equal(scicap_run(&c, (const char *const[]){"cancel", job, NULL}), 1);
    assert_non_null(strstr(c.err, "already finished (done)"));
    assert_int_equal(scicap_run(&c, (const char *const[]){"cancel", "999999", NULL}), 1);
    assert_non_null(strstr(c.err, "no job 999999"));
    /* a running one: canceled, exit 0 */
    r = hconn_request(&h, "reconstruct", json_pack("{s:s, s:{s:i}}", "capture", cap, "params", "iters", 1000000));
    snprintf(job, sizeof job, "%lld", (long long)json_integer_value(json_object_get(r, "job")));
    json_decref(r);
    json_decref(hconn_wait_event(&h, "recon.started", 30000));
    assert_int_equal(scicap_run(&c, (const char *const[]){"cancel", job, NULL}), 0);
    assert_non_null(strstr(c.out, "cancel requested"));
    json_decref(hconn_wait_event_ex(&h, "recon.canceled", 30000, 1));
    hconn_close(&h);
}

/* A refused argument is named by the option the user typed, with the daemon's reason; the request's JSON path and
 * position only in --json output. */
static void test_errors_name_the_option(void **state)
{
    hconn h;
    hconn_open(&h, &H);
    char cap[32];
    daemon_child_capture(&h, cap, sizeof cap, 30000);
    hconn_close(&h);
    static const struct { const char *args[8], *says; } cases[] = {
        {{"recon", "--capture", NULL, "--method", "x"}, "scicap recon: --method: unknown method 'x' (gap-tv, admm-tv"},
        {{"recon", "--capture", NULL, "--iters", "0"}, "scicap recon: --iters: "},
        {{"capture", "--count", "5000"}, "scicap capture: --count: must be in [1, 1000] (got 5000)"},
        {{"capture", "--mask-set", "nope"}, "scicap capture: --mask-set: no mask set \"nope\""},
    };
    const char *leaks[] = {"request:", "args.", "bad_arguments"};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *args[8];
        memcpy(args, cases[i].args, sizeof args);
        if (!args[2])
            args[2] = cap;
        cli_child c;
        assert_int_equal(scicap_run(&c, args), 1);
        if (!strstr(c.err, cases[i].says))
            fail_msg("no \"%s\" in: %s", cases[i].says, c.err);
        for (int k = 0; k < 3; k++)
            assert_null(strstr(c.err, leaks[k]));
    }
    cli_child c;
    /* the details stay in --json */
    assert_int_equal(scicap_run(&c, (const char *const[]){"cancel", "999999", "--json", NULL}), 1);
    assert_non_null(strstr(c.err, "\"code\""));
    assert_non_null(strstr(c.err, "not_found"));
}

/* `scicap captures`: each capture with its reconstructions, folder and PSNR (or residual, without truth); --json
 * is the daemon's list. */
static void test_captures_listed(void **state)
{
    hconn h;
    hconn_open(&h, &H);
    json_t *all = hconn_request(&h, "captures", NULL);
    json_t *one = hconn_request(&h, "captures", json_pack("{s:i}", "limit", 1));
    hconn_close(&h);
    long long total = json_integer_value(json_object_get(all, "total"));
    json_t *list = json_object_get(all, "captures");
    assert_int_equal((long long)json_array_size(list), total);
    assert_true(total >= 6 && total <= 20);
    assert_int_equal(json_array_size(json_object_get(one, "captures")), 1);
    assert_true(json_equal(json_array_get(json_object_get(one, "captures"), 0), json_array_get(list, total - 1)));
    cli_child c;
    assert_int_equal(scicap_run(&c, (const char *const[]){"captures", NULL}), 0);
    assert_null(strchr(c.out, '{'));
    assert_null(strstr(c.out, "hidden"));
    size_t i, k;
    json_t *e, *r;
    int recons = 0;
    json_array_foreach(list, i, e) {
        char line[160];
        snprintf(line, sizeof line, "%s  ", json_string_value(json_object_get(e, "capture")));
        assert_int_equal(count_lines(c.out, line), 1);
        json_array_foreach(json_object_get(e, "recons"), k, r) {
            const char *folder = json_string_value(json_object_get(r, "folder"));
            const char *method = json_string_value(json_object_get(r, "method"));
            if (json_object_get(r, "psnr"))
                snprintf(line, sizeof line, "recon/%-16s %s PSNR %.2f dB", folder, method,
                         json_number_value(json_object_get(r, "psnr")));
            else
                snprintf(line, sizeof line, "recon/%-16s %s relative residual %.2e", folder, method,
                         json_number_value(json_object_get(r, "residual")));
            if (!strstr(c.out, line))
                fail_msg("no \"%s\" in:\n%s", line, c.out);
            recons++;
        }
    }
    assert_true(recons >= 12); /* test_jobs_recent_and_all's gap-tv, gap-tv.2, ... gap-tv.12 among them */
    assert_non_null(strstr(c.out, "recon/gap-tv.12 "));
    assert_non_null(strstr(c.out, "relative residual")); /* the import without truth */
    assert_int_equal(scicap_run(&c, (const char *const[]){"captures", "--json", NULL}), 0);
    json_t *j = json_loads(c.out, 0, NULL);
    assert_non_null(j);
    assert_true(json_equal(j, all));
    json_decref(j);
    json_decref(one);
    json_decref(all);
}

/* Without --all, the newest 20 and how many are hidden. */
static void test_captures_newest_20(void **state)
{
    hconn h;
    hconn_open(&h, &H);
    json_decref(hconn_request(&h, "capture", json_pack("{s:i}", "count", 21)));
    json_decref(hconn_wait_event(&h, "capture.done", 120000));
    json_t *all = hconn_request(&h, "captures", NULL);
    hconn_close(&h);
    long long total = json_integer_value(json_object_get(all, "total"));
    json_decref(all);
    cli_child c;
    assert_int_equal(scicap_run(&c, (const char *const[]){"captures", NULL}), 0);
    char want[128];
    snprintf(want, sizeof want, "(%lld older captures hidden; scicap captures --all lists them)", total - 20);
    assert_non_null(strstr(c.out, want));
    assert_int_equal(count_lines(c.out, " bench"), 20); /* the 21 just taken have no reconstructions */
    assert_int_equal(scicap_run(&c, (const char *const[]){"captures", "--all", NULL}), 0);
    assert_null(strstr(c.out, "hidden"));
    assert_int_equal(count_lines(c.out, " bench (") + count_lines(c.out, " import,"), total);
}

static int setup(void **state) { return daemon_child_setup(&H, scicap, sizeof scicap, NULL); }
static int teardown(void **state) { return daemon_child_teardown(&H); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_status_table_and_json),
        cmocka_unit_test(test_devices_table_and_json),
        cmocka_unit_test(test_no_truth_reports_residual),
        cmocka_unit_test(test_budget_says_its_choice),
        cmocka_unit_test(test_capture_id_forms),
        cmocka_unit_test(test_events_are_lines),
        cmocka_unit_test(test_jobs_recent_and_all),
        cmocka_unit_test(test_cancel_exit_status),
        cmocka_unit_test(test_errors_name_the_option),
        cmocka_unit_test(test_captures_listed),
        cmocka_unit_test(test_captures_newest_20),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
