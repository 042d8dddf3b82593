/* scicapd reconstructs with the NeRF methods, through its real socket, on a tiny static3d scene with a
 * camera imported as a capture (`scicap capture --from FOLDER`; the simulated bench's own captures are video2d,
 * without a camera):
 *   - rayformer and scinerf runs: progress events, periodic checkpoints (reconstruction.checkpoint_every), a
 *     result folder with a finite PSNR, and no checkpoint left behind once done;
 *   - a cancel mid-run: recon.canceled, nothing written, the saved entry and its checkpoint gone;
 *   - a kill -9 mid-run: the restarted daemon resumes the job from its newest checkpoint (the trace holds only the
 *     steps after it) and ends with frames bitwise equal to an uninterrupted run of the same settings (one thread:
 *     the trainer is deterministic); a SIGTERM mid-run: the same from the checkpoint taken as it stopped;
 *   - a budget: with curves (hand-written here) in which rayformer wins for scenes with a camera, the budget
 *     choice picks rayformer for this capture and gap-tv for a capture without a camera. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <dirent.h>

#include "tests/helpers/daemon_child.h"
#include "io/image.h"
#include "io/problem_dir.h"
#include "tests/helpers/cli_child.h"
#include "tests/helpers/nerf_scene.h"

/* steps of a run that a kill or SIGTERM interrupts after its second checkpoint: with 2^14 tables a step takes
 * ~20 ms, so 50 steps (≥ 1 s) stand between that checkpoint and the end */
#define ITERS 60
#define CKPT_EVERY 5

static harness H;
static char scicap[1024];
static char curves_dir[] = "/tmp/scicapd-nerf-curves-XXXXXX";

/* Hand-written curves (bench/results.csv's columns): on scenes with a camera, rayformer (a small setting) is more
 * accurate than gap-tv within a few seconds; on scenes without one only gap-tv was measured. */
static const char curves[] =
    "scene,method,setting,psnr_db,psnr_peak1_db,ssim,wall_s,cpu_s,peak_rss_mib,pareto,recommended,threads,voxels,"
    "camera\n"
    "static3d,gap-tv,iters=50 tv_iters=5,15.0,15.5,0.4,0.5,0.5,100,1,0,1,131072,1\n"
    "static3d,rayformer,preset=fast iters=20 patch=8 patches_per_step=2 samples=8 metrics_every=0 threads=1 "
    "log2_table=14,"
    "17.0,17.5,0.5,100,100,300,1,1,1,131072,1\n"
    "drop40,gap-tv,iters=20 tv_iters=5,30.0,30.5,0.9,0.5,0.5,100,1,1,1,524288,0\n";
static char cap_a[32], cap_b[32]; /* the same scene imported twice: runs to compare */

/* Small and quick (as test_cli_recon_nerf's): two 8×8 windows per step, 8 samples, one thread (deterministic),
 * hash tables of 2^14 entries a level (the presets' 2^19 make every checkpoint, with its Adam moments, ~100 MB). */
static json_t *small_params(const char *method, int iters)
{
    if (!strcmp(method, "rayformer"))
        return json_pack("{s:i, s:i, s:i, s:i, s:i, s:i, s:i}", "iters", iters, "patch", 8, "patches_per_step", 2,
                         "samples", 8, "metrics_every", 0, "threads", 1, "log2_table", 14);
    return json_pack("{s:i, s:i, s:i, s:i, s:i, s:i}", "iters", iters, "rays", 256, "samples", 8, "metrics_every", 0,
                     "threads", 1, "log2_table", 14);
}

static json_int_t reconstruct_small(hconn *c, const char *cap, const char *method, int iters)
{
    json_t *r = hconn_request(c, "reconstruct", json_pack("{s:s, s:s, s:s, s:o}", "capture", cap, "method", method,
                                                          "preset", "fast", "params", small_params(method, iters)));
    json_int_t id = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    assert_true(id > 0);
    return id;
}

typedef struct followed {
    int progress, first_iter, last_iter; /* recon.progress events and their iterations */
    int checkpoints, last_ckpt;          /* recon.checkpoint events and the newest one's step */
    int resumed;                         /* recon.started said it continues from a checkpoint */
    json_t *end;                         /* the recon.done / .canceled / .failed event (or NULL on timeout) */
} followed;

/* Events of job `job` until it ends, or, when stop_ckpt > 0, until a checkpoint at step >= stop_ckpt. */
static void follow(hconn *c, json_int_t job, int stop_ckpt, int timeout_ms, followed *f)
{
    memset(f, 0, sizeof *f);
    f->first_iter = -1;
    int64_t t0 = h_now_ms();
    for (;;) {
        int left = timeout_ms - (int)(h_now_ms() - t0);
        json_t *m = left > 0 ? hconn_read(c, left) : NULL;
        if (!m)
            return;
        const char *ev = json_string_value(json_object_get(m, "event"));
        json_t *d = json_object_get(m, "data");
        if (!ev || json_integer_value(json_object_get(m, "job")) != job) {
            json_decref(m);
            continue;
        }
        if (!strcmp(ev, "recon.progress")) {
            int it = (int)json_integer_value(json_object_get(d, "iter"));
            if (f->first_iter < 0)
                f->first_iter = it;
            assert_true(it > f->last_iter);
            f->last_iter = it;
            f->progress++;
        } else if (!strcmp(ev, "recon.checkpoint")) {
            f->checkpoints++;
            f->last_ckpt = (int)json_integer_value(json_object_get(d, "iter"));
            assert_true(json_integer_value(json_object_get(d, "bytes")) > 0);
        } else if (!strcmp(ev, "recon.started")) {
            f->resumed = json_object_get(d, "resume_bytes") != NULL;
        } else if (!strcmp(ev, "recon.done") || !strcmp(ev, "recon.canceled") || !strcmp(ev, "recon.failed")) {
            f->end = m;
            return;
        }
        json_decref(m);
        if (stop_ckpt > 0 && f->last_ckpt >= stop_ckpt)
            return;
    }
}

/* Files in the reconstruction queue's folder: entries (*.json) and checkpoints (*.ckpt). */
static void queue_files(int *entries, int *ckpts)
{
    char p[512];
    snprintf(p, sizeof p, "%s/recon-queue", H.store);
    *entries = *ckpts = 0;
    DIR *d = opendir(p);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d))) {
        size_t n = strlen(e->d_name);
        if (e->d_name[0] == '.' || strncmp(e->d_name, "bad-", 4) == 0)
            continue;
        *entries += n > 5 && !strcmp(e->d_name + n - 5, ".json");
        *ckpts += n > 5 && !strcmp(e->d_name + n - 5, ".ckpt");
    }
    closedir(d);
}

/* Data rows of captures/CAP/recon/METHOD/trace.csv (the header line not counted). */
static int trace_rows(const char *cap, const char *method)
{
    char p[700], line[4096];
    snprintf(p, sizeof p, "%s/captures/%s/recon/%s/trace.csv", H.store, cap, method);
    FILE *f = fopen(p, "r");
    if (!f)
        fail_msg("%s: missing", p);
    int n = -1;
    while (fgets(line, sizeof line, f))
        n++;
    fclose(f);
    return n;
}

static sci_cube *frames_of(const char *cap, const char *method)
{
    char p[700];
    snprintf(p, sizeof p, "%s/captures/%s/recon/%s/frame.json", H.store, cap, method);
    sci_cube *c = NULL;
    sci_error err = {0};
    if (sci_stack_read(p, &c, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    return c;
}

/* `scicap capture --from DIR --wait`: the capture id it stored. */
static void import_folder(const char *folder, char *id)
{
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"capture", "--socket", H.sock, "--from", folder, "--wait", NULL},
                  H.dir); /* its stdout and stderr go through files there */
    if (cli_child_exit_code(&c) != 0)
        fail_msg("scicap capture --from failed: %s%s", c.out, c.err);
    const char *st = strstr(c.out, "stored ");
    if (!st || sscanf(st, "stored %31s", id) != 1)
        fail_msg("no capture id in: %s", c.out);
    size_t n = strlen(id);
    while (n > 0 && (id[n - 1] == ',' || id[n - 1] == ')' || id[n - 1] == ':'))
        id[--n] = '\0';
}

static int group_setup(void **state)
{
    (void)state;
    if (!mkdtemp(curves_dir))
        return -1;
    char cpath[300], config[600];
    snprintf(cpath, sizeof cpath, "%s/results.csv", curves_dir);
    FILE *cf = fopen(cpath, "w");
    if (!cf)
        return -1;
    fputs(curves, cf);
    fclose(cf);
    snprintf(config, sizeof config,
             "{\"reconstruction\": {\"workers\": 1, \"threads\": 1, \"checkpoint_every\": %d, \"curves\": \"%s\"}}\n",
             CKPT_EVERY, cpath);
    if (daemon_child_setup(&H, scicap, sizeof scicap, config) < 0)
        return -1;
    /* the scene with a camera, as a problem folder, imported twice */
    char folder[400];
    snprintf(folder, sizeof folder, "%s/scene", H.dir);
    sci_problem *p = nerf_tiny_problem(24, 5);
    sci_error err = {0};
    int rc = sci_problem_dir_write(folder, &p, 1, NULL, 0, &err);
    sci_problem_free(p);
    if (rc < 0)
        fail_msg("%s", err.msg);
    import_folder(folder, cap_a);
    import_folder(folder, cap_b);
    /* the capture kept its camera (what the NeRF methods need) */
    char man[700];
    snprintf(man, sizeof man, "%s/captures/%s/problem.json", H.store, cap_a);
    json_t *m = json_load_file(man, 0, NULL);
    int has_camera = m && json_is_object(json_object_get(m, "camera"));
    json_decref(m);
    print_message("  imported %s and %s (camera kept: %s)\n", cap_a, cap_b, has_camera ? "yes" : "no");
    assert_true(has_camera);
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    daemon_child_teardown(&H);
    cli_child_remove_dir(curves_dir);
    return 0;
}

static void run_method(const char *method)
{
    hconn c;
    hconn_open(&c, &H);
    int64_t t0 = h_now_ms();
    json_int_t job = reconstruct_small(&c, cap_a, method, ITERS);
    followed f;
    follow(&c, job, 0, 300000, &f);
    if (!f.end)
        fail_msg("%s: no end event within 300 s", method);
    const char *ev = json_string_value(json_object_get(f.end, "event"));
    json_t *d = json_object_get(f.end, "data");
    if (strcmp(ev, "recon.done") != 0)
        fail_msg("%s: %s: %s", method, ev, json_string_value(json_object_get(d, "error")));
    double psnr = json_real_value(json_object_get(d, "psnr"));
    int entries, ckpts;
    queue_files(&entries, &ckpts);
    print_message("  %s, %d steps: %d progress events (last iter %d), %d checkpoints, %.2f dB, solve %.2f s, "
                  "total %lld ms; queue files after: %d entries, %d checkpoints\n",
                  method, ITERS, f.progress, f.last_iter, f.checkpoints, psnr,
                  json_real_value(json_object_get(d, "solve_s")), (long long)(h_now_ms() - t0), entries, ckpts);
    assert_int_equal(json_integer_value(json_object_get(d, "iters")), ITERS);
    assert_true(f.progress >= 1);
    assert_int_equal(f.last_iter, ITERS);
    assert_int_equal(f.checkpoints, ITERS / CKPT_EVERY); /* every 5 steps; the last one is the last step */
    assert_int_equal(f.last_ckpt, ITERS);
    assert_true(isfinite(psnr) && psnr > 0);
    assert_true(daemon_child_recon_exists(&H, cap_a, method));
    assert_int_equal(entries + ckpts, 0);
    json_decref(f.end);
    hconn_close(&c);
}

static void rayformer_run(void **state)
{
    (void)state;
    run_method("rayformer");
}

static void scinerf_run(void **state)
{
    (void)state;
    run_method("scinerf");
}

static void cancel_mid_run(void **state)
{
    (void)state;
    hconn c;
    hconn_open(&c, &H);
    json_int_t job = reconstruct_small(&c, cap_b, "scinerf", 100000);
    followed f;
    follow(&c, job, 2 * CKPT_EVERY, 300000, &f); /* running, with checkpoints saved */
    assert_true(f.last_ckpt >= 2 * CKPT_EVERY);
    int entries, ckpts;
    queue_files(&entries, &ckpts);
    assert_int_equal(entries, 1);
    assert_int_equal(ckpts, 1);
    json_decref(hconn_request(&c, "cancel", json_pack("{s:I}", "job", job)));
    followed g;
    follow(&c, job, 0, 60000, &g);
    if (!g.end)
        fail_msg("no end event within 60 s of the cancel");
    const char *ev = json_string_value(json_object_get(g.end, "event"));
    queue_files(&entries, &ckpts);
    print_message("  canceled after a checkpoint at step %d: %s (%s); queue files after: %d entries, %d "
                  "checkpoints; result folder: %s\n", f.last_ckpt, ev,
                  json_string_value(json_object_get(json_object_get(g.end, "data"), "error")), entries, ckpts,
                  daemon_child_recon_exists(&H, cap_b, "scinerf") ? "yes" : "no");
    assert_string_equal(ev, "recon.canceled");
    assert_int_equal(entries + ckpts, 0);
    assert_false(daemon_child_recon_exists(&H, cap_b, "scinerf"));
    json_decref(g.end);
    hconn_close(&c);
}

static void resume_after_kill9(void **state)
{
    (void)state;
    hconn c;
    hconn_open(&c, &H);
    json_int_t job = reconstruct_small(&c, cap_b, "rayformer", ITERS);
    followed f;
    follow(&c, job, 2 * CKPT_EVERY, 300000, &f);
    if (f.end)
        fail_msg("the run ended before its second checkpoint: %s", json_dumps(f.end, JSON_COMPACT));
    harness_kill9(&H);
    hconn_close(&c);
    int entries, ckpts;
    queue_files(&entries, &ckpts);
    assert_int_equal(entries, 1);
    assert_int_equal(ckpts, 1);
    /* and a checkpoint whose entry is gone (a stop between their removals): removed at the start */
    char orphan[600];
    snprintf(orphan, sizeof orphan, "%s/recon-queue/r-00000000000000000001-999.ckpt", H.store);
    FILE *o = fopen(orphan, "w");
    assert_non_null(o);
    fputs("stale", o);
    fclose(o);
    harness_spawn(&H, NULL);
    hconn_open(&c, &H);
    int resumed = daemon_child_resumed(&c);
    hconn_close(&c);
    int ok = daemon_child_wait_recon(&H, cap_b, "rayformer", 300000);
    int rows = ok ? trace_rows(cap_b, "rayformer") : -1;
    /* the log says where it went on from */
    char cmd[700];
    snprintf(cmd, sizeof cmd, "grep -q 'goes on from its checkpoint' %s", H.log);
    int logged = system(cmd) == 0;
    queue_files(&entries, &ckpts);
    print_message("  kill -9 after the checkpoint at step %d of %d: %d resumed at restart, done: %s, trace rows %d "
                  "(steps run after the restart), log says resumed from a checkpoint: %s; queue files after: %d\n",
                  f.last_ckpt, ITERS, resumed, ok ? "yes" : "no", rows, logged ? "yes" : "no", entries + ckpts);
    assert_int_equal(resumed, 1);
    assert_true(ok);
    assert_true(logged);
    assert_true(rows >= 1 && rows <= ITERS - f.last_ckpt);
    assert_int_equal(entries + ckpts, 0);
    /* resumed == uninterrupted: the same frames as capture A's run of the same settings (rayformer_run) */
    sci_cube *a = frames_of(cap_a, "rayformer"), *b = frames_of(cap_b, "rayformer");
    assert_int_equal(a->w * a->h * a->n, b->w * b->h * b->n);
    size_t differ = 0;
    for (size_t i = 0; i < (size_t)a->w * a->h * a->n; i++)
        differ += a->data[i] != b->data[i];
    print_message("  resumed vs uninterrupted frames: %zu of %zu values differ\n", differ,
                  (size_t)a->w * a->h * a->n);
    assert_int_equal(differ, 0);
    sci_cube_free(a);
    sci_cube_free(b);
}

/* An orderly stop (SIGTERM) mid-run: the run hands over a checkpoint at the step it stopped at, and the next start
 * goes on from there (scinerf this time; capture B has no scinerf result: the cancel test wrote none). */
static void resume_after_sigterm(void **state)
{
    (void)state;
    hconn c;
    hconn_open(&c, &H);
    json_int_t job = reconstruct_small(&c, cap_b, "scinerf", ITERS);
    followed f;
    follow(&c, job, CKPT_EVERY, 300000, &f);
    if (f.end)
        fail_msg("the run ended before its first checkpoint: %s", json_dumps(f.end, JSON_COMPACT));
    hconn_close(&c);
    harness_stop(&H); /* SIGTERM; fails unless the daemon exits 0 */
    harness_spawn(&H, NULL);
    hconn_open(&c, &H);
    int resumed = daemon_child_resumed(&c);
    hconn_close(&c);
    int ok = daemon_child_wait_recon(&H, cap_b, "scinerf", 300000);
    int rows = ok ? trace_rows(cap_b, "scinerf") : -1;
    int entries, ckpts;
    queue_files(&entries, &ckpts);
    sci_cube *a = ok ? frames_of(cap_a, "scinerf") : NULL, *b = ok ? frames_of(cap_b, "scinerf") : NULL;
    size_t differ = 0, n = a ? (size_t)a->w * a->h * a->n : 0;
    for (size_t i = 0; i < n; i++)
        differ += a->data[i] != b->data[i];
    print_message("  SIGTERM after the checkpoint at step %d of %d: %d resumed, done: %s, trace rows %d; frames vs "
                  "uninterrupted: %zu of %zu differ; queue files after: %d\n", f.last_ckpt, ITERS, resumed,
                  ok ? "yes" : "no", rows, differ, n, entries + ckpts);
    assert_int_equal(resumed, 1);
    assert_true(ok);
    assert_true(rows >= 1 && rows <= ITERS - f.last_ckpt); /* went on from the stop's checkpoint, not step 0 */
    assert_int_equal(differ, 0);
    assert_int_equal(entries + ckpts, 0);
    sci_cube_free(a);
    sci_cube_free(b);
}

/* The method of the reconstruction a budget chose, from its result.json (which records the budget). */
static void budget_result(const char *cap, const char *method, double *budget_s)
{
    json_t *r = daemon_child_result(&H, cap, method);
    char *text = json_dumps(r, JSON_COMPACT);
    json_t *b = json_object_get(json_object_get(json_object_get(r, "params"), "budget"), "budget_s");
    if (!b)
        fail_msg("%s/%s: result.json has no budget: %s", cap, method, text);
    *budget_s = json_number_value(b);
    free(text);
    json_decref(r);
}

static void budget_picks_nerf(void **state)
{
    (void)state;
    /* `scicap recon --capture ID --budget S` on the capture with a camera */
    cli_child c;
    cli_child_run(&c, scicap,
                  (const char *const[]){"recon", "--socket", H.sock, "--capture", cap_a, "--budget", "5", "--wait",
                                        NULL},
                  H.dir);
    print_message("  scicap recon --capture %s --budget 5: exit %d\n%s%s", cap_a, cli_child_exit_code(&c), c.out,
                  c.err);
    assert_int_equal(cli_child_exit_code(&c), 0);
    double b = 0;
    budget_result(cap_a, "rayformer.2", &b); /* beside rayformer_run's recon/rayformer, which stays */
    assert_true(b == 5);
    assert_non_null(strstr(c.out, "-> "));
    assert_non_null(strstr(strstr(c.out, "-> "), "/recon/rayformer.2"));
    /* a capture of the simulated bench (no camera): the same budget picks among the camera-less curves */
    hconn h;
    hconn_open(&h, &H);
    char cap[32];
    daemon_child_capture(&h, cap, sizeof cap, 30000);
    json_decref(hconn_wait_event(&h, "capture.done", 30000));
    /* a NeRF method on it is refused at the request, with the reason */
    json_t *m = hconn_call(&h, "reconstruct", json_pack("{s:s, s:s}", "capture", cap, "method", "rayformer"));
    const char *code = json_string_value(json_object_get(json_object_get(m, "error"), "code"));
    const char *msg = json_string_value(json_object_get(json_object_get(m, "error"), "message"));
    print_message("  rayformer on %s: %s: %s\n", cap, code ? code : "accepted", msg ? msg : "");
    assert_true(code && !strcmp(code, "bad_arguments") && msg && strstr(msg, "camera"));
    json_decref(m);
    hconn_expect_error(&h, "capture", json_pack("{s:b, s:s}", "reconstruct", 1, "method", "scinerf"), "bad_arguments");
    json_t *r = hconn_request(&h, "reconstruct", json_pack("{s:s, s:f}", "capture", cap, "budget_s", 5.0));
    json_int_t job = json_integer_value(json_object_get(r, "job"));
    json_decref(r);
    followed f;
    follow(&h, job, 0, 120000, &f);
    assert_non_null(f.end);
    const char *method = json_string_value(json_object_get(json_object_get(f.end, "data"), "method"));
    print_message("  budget 5 s: %s (camera) -> rayformer; %s (simulated bench, no camera) -> %s (%s)\n", cap_a, cap,
                  method, json_string_value(json_object_get(f.end, "event")));
    assert_string_equal(json_string_value(json_object_get(f.end, "event")), "recon.done");
    assert_string_equal(method, "gap-tv");
    budget_result(cap, "gap-tv", &b);
    json_decref(f.end);
    hconn_close(&h);
}

/* A configuration that would reconstruct every bench capture with a NeRF method is refused at the start. */
static void config_auto_nerf_refused(void **state)
{
    (void)state;
    char cfg[400], cmd[2400], out[1024] = "";
    snprintf(cfg, sizeof cfg, "%s/auto-nerf.json", curves_dir);
    FILE *f = fopen(cfg, "w");
    assert_non_null(f);
    fputs("{\"reconstruction\": {\"method\": \"scinerf\", \"auto\": true}}\n", f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s --config %s --socket %s/x.sock --storage %s/st --runtime-dir %s/run --allow-root 2>&1",
             H.bin, cfg, curves_dir, curves_dir, curves_dir);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t n = fread(out, 1, sizeof out - 1, p);
    out[n] = '\0';
    int st = pclose(p);
    print_message("  auto + scinerf: exit %d: %s", WIFEXITED(st) ? WEXITSTATUS(st) : -1, out);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) != 0);
    assert_non_null(strstr(out, "reconstruction.auto"));
    assert_non_null(strstr(out, "camera"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rayformer_run),
        cmocka_unit_test(scinerf_run),
        cmocka_unit_test(cancel_mid_run),
        cmocka_unit_test(resume_after_kill9),
        cmocka_unit_test(resume_after_sigterm),
        cmocka_unit_test(budget_picks_nerf),
        cmocka_unit_test(config_auto_nerf_refused),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
