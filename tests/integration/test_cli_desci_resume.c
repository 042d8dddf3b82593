/* `scicap recon --method desci --checkpoint FILE` interrupted by Ctrl-C (SIGINT) after its first checkpoint, then
 * `--resume FILE`, writes the same frames, bit for bit, as an uninterrupted run with the same options and thread
 * count (the pixels: the files' DateTime differs) — through the real binary on a 64×64×8 video2d problem from `scicap sim`. The interrupted run dies of
 * SIGINT (as a shell expects), leaves no output folder and says at which step its checkpoint is. */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "base/cube.h"
#include "base/error.h"
#include "io/image.h"
#include "tests/helpers/cli_child.h"

static char dir[] = "/tmp/scicap-test-cli-desci-resume-XXXXXX";
static char scicap[1024];

#if defined(__SANITIZE_ADDRESS__)
#define SIDE "32" /* AddressSanitizer: a smaller problem */
#else
#define SIDE "64"
#endif

static const char scene[] =
    "{\"version\": 1, \"kind\": \"video2d\", \"name\": \"small\", \"width\": " SIDE ", \"height\": " SIDE ","
    " \"frames\": 8, \"snapshots\": 1, \"bit_depth\": 12, \"seed\": 3, \"supersample\": 1, \"background\": 0.1,"
    " \"layers\": [{\"texture\": {\"type\": \"noise\", \"cell\": 16, \"octaves\": 3, \"values\": [0.1, 0.7]}},"
    "  {\"shape\": \"rect\", \"size\": [24, 24], \"position\": [20, 20], \"velocity\": [1.5, 0.5],"
    "   \"texture\": {\"type\": \"checkerboard\", \"cell\": 4, \"values\": [0.05, 0.95]}}],"
    " \"masks\": {\"type\": \"random\", \"density\": 0.5}}";

/* The fast preset over 6 iterations on 2 threads: about a second per iteration here. */
#define ITERS 6
#define OPTS "--method desci --preset fast --iters 6 -j 2"

static int setup(void **state)
{
    if (cli_child_setup(scicap, sizeof scicap, "scicap", dir) < 0)
        return -1;
#if defined(__SANITIZE_ADDRESS__)
    printf("AddressSanitizer build: a " SIDE "x" SIDE "x8 problem instead of 64x64x8\n");
#endif
    return cli_child_sim(scicap, dir, "small.json", scene);
}

static int teardown(void **state) { return cli_child_remove_dir(dir); }

/* The stored floats of an image file (a 1-frame cube the caller frees). */
static sci_cube *read_frame(const char *path)
{
    sci_cube *c = NULL;
    sci_error err = {0};
    if (sci_image_read(path, &c, NULL, &err) < 0)
        fail_msg("%s: %s", path, err.msg);
    return c;
}

static void test_interrupt_and_resume_is_bitwise(void **state)
{
    (void)state;
    char prob[2048], ck[2048], out[2048], log[2048];
    snprintf(prob, sizeof prob, "%s/prob", dir);
    snprintf(ck, sizeof ck, "%s/ck", dir);
    snprintf(out, sizeof out, "%s/int", dir);
    snprintf(log, sizeof log, "%s/int.log", dir);

    /* uninterrupted */
    assert_int_equal(cli_child_shell("%s recon " OPTS " -q %s -o %s/full >%s/full.log 2>&1", scicap, prob, dir, dir), 0);

    /* interrupted after its first checkpoint (one per iteration) */
    pid_t pid = cli_child_spawn_logged(
        log, scicap, (const char *const[]){scicap, "recon", "--method", "desci", "--preset", "fast", "--iters", "6",
                                           "-j", "2", "--checkpoint", ck, "--checkpoint-every", "1", "-q", prob,
                                           "-o", out, NULL});
    int ready = 0;
    for (int i = 0; i < 2000 && !ready; i++) { /* at most 20 s */
        ready = access(ck, R_OK) == 0;
        if (!ready)
            nanosleep(&(struct timespec){0, 10000000}, NULL);
    }
    kill(pid, SIGINT);
    int ws;
    assert_int_equal(waitpid(pid, &ws, 0), pid);
    if (!ready)
        fail_msg("no checkpoint %s within 20 s", ck);
    if (!WIFSIGNALED(ws) || WTERMSIG(ws) != SIGINT) {
        cli_child_shell("cat %s >&2", log);
        fail_msg("interrupted run: expected death by SIGINT, got status %#x (finished before the signal?)", ws);
    }
    assert_int_not_equal(access(out, F_OK), 0);
    const int step = cli_child_checkpoint_step(log);
    printf("interrupted: checkpoint of step %d of %d\n", step, ITERS);
    assert_true(step >= 1 && step < ITERS);

    /* resumed to the end */
    assert_int_equal(cli_child_shell("%s recon " OPTS " --resume %s -q %s -o %s >%s/res.log 2>&1", scicap, ck, prob, out, dir), 0);
    json_t *res = cli_child_load_json(out, "result.json");
    assert_true(json_is_true(json_object_get(json_object_get(res, "params"), "resumed")));
    json_decref(res);

    /* the frames' pixels, bit for bit */
    int frames = 0;
    for (int k = 0; k < 64; k++) {
        char a[2048], b[2048];
        snprintf(a, sizeof a, "%s/full/frame_%03d.exr", dir, k);
        snprintf(b, sizeof b, "%s/frame_%03d.exr", out, k);
        if (access(a, R_OK) != 0)
            break;
        sci_cube *x = read_frame(a), *y = read_frame(b);
        assert_true(x->w == y->w && x->h == y->h && x->n == y->n);
        const size_t count = (size_t)x->w * x->h * x->n;
        size_t differ = 0;
        for (size_t i = 0; i < count; i++)
            differ += memcmp(&x->data[i], &y->data[i], sizeof(float)) != 0;
        sci_cube_free(x);
        sci_cube_free(y);
        if (differ)
            fail_msg("frame %d: %zu of %zu pixels of the resumed run differ from the uninterrupted run's", k, differ,
                     count);
        frames++;
    }
    printf("%d frames bitwise equal\n", frames);
    assert_int_equal(frames, 8);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_interrupt_and_resume_is_bitwise)};
    return cmocka_run_group_tests(tests, setup, teardown);
}
