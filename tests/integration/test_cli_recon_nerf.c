/* `scicap recon --method rayformer|scinerf` as a user runs it, through the real binary on a tiny static3d scene
 * from `scicap sim`: periodic checkpoints, Ctrl-C (SIGINT) mid-training leaves a checkpoint and no output folder
 * (the process dies of SIGINT, as a shell expects), --resume continues from it to a full result, and the ablation
 * switches and --set reach the solver (they are recorded in result.json). Correctness of resume itself (resumed == uninterrupted) is test_nerf_checkpoint's. */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "tests/helpers/cli_child.h"

static char dir[] = "/tmp/scicap-test-cli-nerf-XXXXXX";
static char scicap[1024];

static const char scene[] =
    "{\"kind\": \"static3d\", \"width\": 24, \"height\": 24, \"frames\": 4, \"seed\": 5,"
    " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, -3], \"radius\": 0.8,"
    "   \"texture\": {\"type\": \"checkerboard\", \"cell\": 12}},"
    "  {\"type\": \"plane\", \"center\": [0, 0, -5], \"size\": [8, 8], \"texture\": {\"type\": \"noise\", \"cell\": 24}}],"
    " \"camera\": {\"fx\": 24, \"cx\": 12, \"cy\": 12, \"near\": 1.5, \"far\": 6,"
    "   \"start\": {\"position\": [-0.15, 0, 0], \"look_at\": [0, 0, -3]},"
    "   \"end\": {\"position\": [0.15, 0.05, 0], \"look_at\": [0, 0, -3]}}}";

/* Small and quick: 2 windows of 8×8 per step, 8 samples. */
#define SMALL "--patch 8 --patches-per-step 2 --samples 8 --metrics-every 0 -j 1"

static int exists(const char *fmt, const char *name)
{
    char path[2048];
    snprintf(path, sizeof path, fmt, dir, name);
    return access(path, F_OK) == 0;
}

/* `scicap recon ARGS` on the test's problem must be refused (exit 2) with `pattern` (a grep regex) in its stderr;
 * the stderr stays in dir/refused.err for a further look. */
static void refused(const char *args, const char *pattern)
{
    assert_int_equal(cli_child_shell("%s recon %s %s/prob -o %s/x 2>%s/refused.err", scicap, args, dir, dir, dir), 2);
    if (cli_child_shell("grep -q -e '%s' %s/refused.err", pattern, dir) != 0)
        fail_msg("scicap recon %s: stderr lacks '%s'", args, pattern);
}

/* The params of dir/OUT/result.json (the caller's reference). */
static json_t *result_params(const char *out)
{
    char name[1024];
    snprintf(name, sizeof name, "%s/result.json", out);
    json_t *j = cli_child_load_json(dir, name);
    json_t *p = json_object_get(j, "params");
    if (!p)
        fail_msg("%s/%s has no params", dir, name);
    json_incref(p);
    json_decref(j);
    return p;
}

/* `scicap recon ARGS` on the test's problem into dir/OUT must succeed; returns result_params(OUT). */
static json_t *recon_params(const char *args, const char *out)
{
    assert_int_equal(cli_child_shell("%s recon %s -q %s/prob -o %s/%s >/dev/null 2>&1", scicap, args, dir, dir, out), 0);
    return result_params(out);
}

static int setup(void **state)
{
    if (cli_child_setup(scicap, sizeof scicap, "scicap", dir) < 0)
        return -1;
    return cli_child_sim(scicap, dir, "tiny.json", scene);
}

static int teardown(void **state) { return cli_child_remove_dir(dir); }

/* Periodic checkpoints, then a resumed run to more steps. */
static void test_checkpoint_then_resume(void **state)
{
    (void)state;
    assert_int_equal(cli_child_shell("%s recon --method rayformer " SMALL " --iters 8 --checkpoint %s/ck --checkpoint-every 4 -q "
                         "%s/prob -o %s/a >%s/a.log 2>&1",
                         scicap, dir, dir, dir, dir),
                     0);
    assert_true(exists("%s/%s", "a/result.json"));
    assert_true(exists("%s/%s", "ck"));
    assert_false(exists("%s/%s", "ck.tmp"));
    assert_int_equal(cli_child_shell("%s recon --method rayformer " SMALL " --iters 12 --resume %s/ck -q %s/prob -o %s/b >%s/b.log "
                         "2>&1",
                         scicap, dir, dir, dir, dir),
                     0);
    json_t *p = result_params("b");
    assert_true(json_is_true(json_object_get(p, "resumed")));
    json_decref(p);
    /* 12 steps in all: the trace of the resumed run ends at step 12 */
    assert_int_equal(cli_child_shell("grep -q '^  12 iterations' %s/b.log", dir), 0);
    /* a damaged checkpoint is refused with a message, not trained from */
    assert_int_equal(cli_child_shell("head -c 100 %s/ck > %s/bad && %s recon --method rayformer " SMALL " --iters 12 --resume %s/bad "
                         "-q %s/prob -o %s/c >%s/c.log 2>&1",
                         dir, dir, scicap, dir, dir, dir, dir),
                     1);
    assert_int_equal(cli_child_shell("grep -qi 'checkpoint' %s/c.log", dir), 0);
    assert_false(exists("%s/%s", "c"));
}

/* Ctrl-C mid-training: killed by SIGINT after writing a checkpoint, no output folder; resuming finishes the run. */
static void test_interrupt_and_resume(void **state)
{
    (void)state;
    char out[2048], ck[2048], log[2048];
    snprintf(out, sizeof out, "%s/int", dir);
    snprintf(ck, sizeof ck, "%s/ck_int", dir);
    snprintf(log, sizeof log, "%s/int.log", dir);
    char prob[2048];
    snprintf(prob, sizeof prob, "%s/prob", dir);
    pid_t pid = cli_child_spawn_logged(
        log, scicap, (const char *const[]){scicap, "recon", "--method", "scinerf", "--samples", "8", "--metrics-every",
                                           "0", "-j", "1", "--iters", "1000000", "--checkpoint", ck,
                                           "--checkpoint-every", "1000000", "-q", prob, "-o", out, NULL});
    /* wait until it has installed its SIGINT handler (SigCgt bit 1), then give it a few steps */
    char status[64];
    snprintf(status, sizeof status, "/proc/%d/status", (int)pid);
    int caught = 0;
    for (int i = 0; i < 3000 && !caught; i++) {
        FILE *f = fopen(status, "r");
        char line[256];
        while (f && fgets(line, sizeof line, f))
            if (strncmp(line, "SigCgt:", 7) == 0)
                caught = (strtoull(line + 7, NULL, 16) >> (SIGINT - 1)) & 1;
        if (f)
            fclose(f);
        if (!caught)
            nanosleep(&(struct timespec){0, 10000000}, NULL);
    }
    assert_true(caught);
    nanosleep(&(struct timespec){0, 500000000}, NULL);
    kill(pid, SIGINT);
    int ws;
    assert_int_equal(waitpid(pid, &ws, 0), pid);
    if (!WIFSIGNALED(ws) || WTERMSIG(ws) != SIGINT) {
        cli_child_shell("cat %s >&2", log);
        fail_msg("interrupted run: expected death by SIGINT, got status %#x", ws);
    }
    assert_int_equal(access(ck, R_OK), 0);
    assert_int_not_equal(access(out, F_OK), 0);
    int step = cli_child_checkpoint_step(log);
    printf("interrupted at step %d\n", step);
    assert_true(step >= 1);
    /* resume to 3 steps past the interruption */
    assert_int_equal(cli_child_shell("%s recon --method scinerf --samples 8 --metrics-every 0 -j 1 --iters %d --resume %s -q %s -o "
                         "%s >%s/res.log 2>&1",
                         scicap, step + 3, ck, prob, out, dir),
                     0);
    assert_int_equal(access(out, F_OK), 0);
}

/* --ablation reaches the solver; the classical methods refuse the NeRF-only options. */
static void test_ablation_and_usage(void **state)
{
    (void)state;
    json_t *p = recon_params("--method rayformer " SMALL " --iters 2 --ablation baseline", "abl");
    assert_true(json_is_false(json_object_get(p, "patch_sampling")));
    assert_true(json_is_false(json_object_get(p, "inter_ray")));
    assert_true(json_is_false(json_object_get(p, "intra_ray")));
    assert_true(json_is_real(json_object_get(p, "tv_weight")));
    assert_true(json_real_value(json_object_get(p, "tv_weight")) == 0);
    json_decref(p);
    p = recon_params("--method rayformer --ablation +inter --iters 2 " SMALL, "abl2");
    assert_true(json_is_true(json_object_get(p, "patch_sampling")));
    assert_true(json_is_true(json_object_get(p, "inter_ray")));
    assert_true(json_is_false(json_object_get(p, "intra_ray")));
    json_decref(p);
    refused("--method rayformer --ablation sideways", "ablation wants baseline");
    char args[1100];
    snprintf(args, sizeof args, "--method gap-tv --checkpoint %s/ck2", dir);
    refused(args, "checkpoint and --resume are for");
    refused("--method scinerf --ablation tv", "ablation is for rayformer");
}

/* --set KEY=VALUE reaches any setting through the method's table (values as JSON, else strings); an unknown key is
 * refused with the method's keys, an out-of-range value with its range. */
static void test_set_any_setting(void **state)
{
    (void)state;
    json_t *p = recon_params("--method rayformer " SMALL " --iters 2 --set inter_gate=false --set inter_slope=2 "
                             "--set spacing=log",
                             "set");
    assert_true(json_is_false(json_object_get(p, "inter_gate")));
    assert_true(json_number_value(json_object_get(p, "inter_slope")) == 2);
    assert_string_equal(json_string_value(json_object_get(p, "spacing")), "log");
    json_decref(p);
    refused("--method rayformer --set bogus=1", "bogus: rayformer has no such setting");
    assert_int_equal(cli_child_shell("grep -q '^  inter_gate ' %s/refused.err", dir), 0); /* the list of the method's keys */
    refused("--method rayformer --set inter_slope=-1", "inter_slope: must be a number in");
    refused("--set iters", "set wants KEY=VALUE");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_checkpoint_then_resume),
        cmocka_unit_test(test_interrupt_and_resume),
        cmocka_unit_test(test_ablation_and_usage),
        cmocka_unit_test(test_set_any_setting),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
