/* Checkpoints of the NeRF trainer (trainer.h) at tiny sizes: a run canceled (or checkpointed) half-way and resumed
 * from its checkpoint ends bitwise equal to an uninterrupted run — frames, losses and poses — for RayFormer with
 * optimised poses, for SCINeRF's two networks and with a moving average of the weights under way; damaged or
 * mismatched checkpoints are refused with a message. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "recon/nerf/rayformer_solve.h"
#include "recon/nerf/scinerf_solve.h"
#include "sim/simulate.h"
#include "tests/helpers/nerf_scene.h"

/* Keeps the newest checkpoint, or the one of step `want` when it is set. */
typedef struct store {
    unsigned char *blob;
    size_t bytes;
    int iter, calls, want;
} store;

static int keep(const void *blob, size_t bytes, int iter, void *user)
{
    store *s = user;
    s->calls++;
    if (s->want && iter != s->want)
        return 0;
    free(s->blob);
    s->blob = malloc(bytes);
    assert_non_null(s->blob);
    memcpy(s->blob, blob, bytes);
    s->bytes = bytes;
    s->iter = iter;
    return 0;
}

static int cancel_at_7(const sci_trace_entry *e, void *user)
{
    (void)user;
    return e->iter >= 7;
}

static void small_rf(sci_rayformer_params *p, unsigned long long seed)
{
    sci_rayformer_params_default(p);
    p->iters = 14;
    p->patch = 4;
    p->patches_per_step = 2;
    p->samples = 8;
    p->log2_table = 12;
    p->finest_res = 64;
    p->metrics_every = 0;
    p->seed = seed;
    p->pose_mode = NERF_POSES_LINEAR; /* the poses' Adam state is part of the checkpoint */
    p->pose_perturb_trans = 0.02;
}

/* The tiny problem of the RayFormer cases, their settings and room for two runs' poses (the caller frees). */
static sci_problem *rf_setup(sci_rayformer_params *prm, double (**pa)[12], double (**pb)[12])
{
    unsigned long long seed = test_seed_env(7);
    sci_problem *p = nerf_tiny_problem(16, seed);
    *pa = malloc((size_t)p->mask->n * sizeof **pa);
    *pb = malloc((size_t)p->mask->n * sizeof **pb);
    assert_true(*pa && *pb);
    small_rf(prm, seed);
    return p;
}

/* The resumed run b (its solver returned rc) from the checkpoint of step `from` equals the uninterrupted run a, poses
 * pb and pa (n each) included; frees both results and both pose arrays. */
static void expect_same_run(int rc, sci_result *a, sci_result *b, int from, double (*pa)[12], double (*pb)[12], int n,
                            size_t ckpt_bytes)
{
    if (rc != 0)
        fail_msg("%s", b->error.msg);
    printf("checkpoint %zu bytes; resumed run: %zu steps, final loss %.9g vs %.9g\n", ckpt_bytes, b->trace.len,
           b->trace.e[b->trace.len - 1].loss, a->trace.e[a->trace.len - 1].loss);
    assert_non_null(a->frames);
    assert_non_null(b->frames);
    assert_memory_equal(a->frames->data, b->frames->data, sci_cube_count(a->frames) * sizeof(float));
    /* b's trace holds the steps after the checkpoint; they are a's, bit for bit */
    assert_int_equal((int)b->trace.len, (int)a->trace.len - from);
    for (size_t i = 0; i < b->trace.len; i++) {
        assert_int_equal(b->trace.e[i].iter, a->trace.e[from + i].iter);
        assert_true(memcmp(&b->trace.e[i].loss, &a->trace.e[from + i].loss, sizeof(double)) == 0);
    }
    assert_memory_equal(pa, pb, (size_t)n * 12 * sizeof(double));
    /* the resumed clock continues the first run's */
    assert_true(b->trace.e[0].wall_s >= 0);
    free(pa), free(pb);
    sci_result_free_contents(a), sci_result_free_contents(b);
}

/* RayFormer, poses optimised: canceled at step 7 (the checkpoint is handed over on cancel), resumed to 14, equals
 * an uninterrupted run of 14 steps. */
static void test_rayformer_cancel_resume(void **state)
{
    (void)state;
    sci_rayformer_params prm;
    double(*poses_a)[12], (*poses_b)[12];
    sci_problem *p = rf_setup(&prm, &poses_a, &poses_b);
    const int n = p->mask->n;
    sci_result a = {0}, half = {0}, b = {0};
    assert_int_equal(sci_rayformer_solve_ex(p, &prm, &a, NULL, NULL, poses_a), 0);

    store st = {0};
    prm.checkpoint_fn = keep;
    prm.checkpoint_user = &st;
    assert_int_equal(sci_rayformer_solve(p, &prm, &half, cancel_at_7, NULL), SCI_ECANCELED);
    assert_int_equal(st.calls, 1);
    assert_int_equal(st.iter, 7);
    int it = -1;
    char method[NERF_CKPT_METHOD_MAX];
    assert_int_equal(nerf_checkpoint_peek(st.blob, st.bytes, &it, method, NULL), 0);
    assert_int_equal(it, 7);
    assert_string_equal(method, "rayformer");

    prm.checkpoint_fn = NULL;
    prm.resume = st.blob;
    prm.resume_bytes = st.bytes;
    int rc = sci_rayformer_solve_ex(p, &prm, &b, NULL, NULL, poses_b);
    expect_same_run(rc, &a, &b, 7, poses_a, poses_b, n, st.bytes);
    free(st.blob);
    sci_result_free_contents(&half);
    sci_problem_free(p);
}

/* SCINeRF with coarse + fine networks (two parameter sets and optimisers in the blob), checkpoints every 5 steps:
 * resuming from the one of step 5 equals the uninterrupted run. */
static void test_scinerf_periodic_resume(void **state)
{
    (void)state;
    unsigned long long seed = test_seed_env(7);
    sci_problem *p = nerf_tiny_problem(16, seed);
    sci_scinerf_params prm;
    sci_scinerf_params_default(&prm);
    prm.iters = 12, prm.rays_per_step = 64, prm.samples = 8, prm.fine_samples = 8, prm.log2_table = 12;
    prm.finest_res = 64, prm.metrics_every = 0, prm.seed = seed;
    const int n = p->mask->n;
    double(*poses_a)[12] = malloc((size_t)n * sizeof *poses_a), (*poses_b)[12] = malloc((size_t)n * sizeof *poses_b);
    store st = {.want = 5};
    sci_result a = {0}, b = {0};
    prm.checkpoint_every = 5;
    prm.checkpoint_fn = keep;
    prm.checkpoint_user = &st;
    assert_int_equal(sci_scinerf_solve_ex(p, &prm, &a, NULL, NULL, poses_a), 0);
    assert_int_equal(st.calls, 3); /* steps 5, 10 and the last (12) */
    assert_int_equal(st.iter, 5);
    prm.checkpoint_fn = NULL;
    prm.resume = st.blob;
    prm.resume_bytes = st.bytes;
    int rc = sci_scinerf_solve_ex(p, &prm, &b, NULL, NULL, poses_b);
    expect_same_run(rc, &a, &b, 5, poses_a, poses_b, n, st.bytes);
    free(st.blob);
    sci_problem_free(p);
}

/* A moving average of the weights (ema_steps 2 over 14 steps: it begins at step 7) renders the frames but never
 * steers training: the losses equal a run without it bit for bit, the frames do not. A checkpoint taken while it
 * runs (step 10) holds it: the resumed run equals the uninterrupted one, and a run without ema_steps refuses it. */
static void test_ema_resume(void **state)
{
    (void)state;
    sci_rayformer_params prm;
    double(*poses_a)[12], (*poses_b)[12];
    sci_problem *p = rf_setup(&prm, &poses_a, &poses_b);
    const int n = p->mask->n;
    sci_result plain = {0}, a = {0}, b = {0}, refused = {0};
    assert_int_equal(sci_rayformer_solve(p, &prm, &plain, NULL, NULL), 0);
    prm.recipe.ema_steps = 2;
    store st = {.want = 10};
    prm.checkpoint_every = 5;
    prm.checkpoint_fn = keep;
    prm.checkpoint_user = &st;
    assert_int_equal(sci_rayformer_solve_ex(p, &prm, &a, NULL, NULL, poses_a), 0);
    assert_int_equal((int)a.trace.len, (int)plain.trace.len);
    for (size_t i = 0; i < a.trace.len; i++)
        assert_true(memcmp(&a.trace.e[i].loss, &plain.trace.e[i].loss, sizeof(double)) == 0);
    const size_t bytes = sci_cube_count(a.frames) * sizeof(float);
    assert_true(memcmp(a.frames->data, plain.frames->data, bytes) != 0);
    sci_result_free_contents(&plain);
    assert_int_equal(st.iter, 10);

    prm.checkpoint_fn = NULL;
    prm.resume = st.blob;
    prm.resume_bytes = st.bytes;
    int rc = sci_rayformer_solve_ex(p, &prm, &b, NULL, NULL, poses_b);
    expect_same_run(rc, &a, &b, 10, poses_a, poses_b, n, st.bytes);
    prm.recipe.ema_steps = 0;
    assert_int_equal(sci_rayformer_solve(p, &prm, &refused, NULL, NULL), -EINVAL);
    printf("without ema_steps: %s\n", refused.error.msg);
    assert_non_null(strstr(refused.error.msg, "ema_steps"));
    assert_null(refused.frames);
    sci_result_free_contents(&refused);
    free(st.blob);
    sci_problem_free(p);
}

/* Damaged or mismatched checkpoints: refused before training, with a message, and no frames. */
static void test_bad_checkpoints(void **state)
{
    (void)state;
    sci_problem *p = nerf_tiny_problem(16, 3);
    sci_rayformer_params prm;
    small_rf(&prm, 3);
    prm.iters = 4;
    store st = {0};
    prm.checkpoint_every = 2;
    prm.checkpoint_fn = keep;
    prm.checkpoint_user = &st;
    sci_result r = {0};
    assert_int_equal(sci_rayformer_solve(p, &prm, &r, NULL, NULL), 0);
    sci_result_free_contents(&r);
    prm.checkpoint_fn = NULL;
    prm.iters = 8;

    struct {
        const char *what;
        size_t bytes;
        size_t flip; /* byte to flip, or SIZE_MAX */
        int code;
        const char *msg;
    } cases[] = {
        {"truncated", st.bytes - 9, SIZE_MAX, SCI_EFORMAT, "checksum"},
        {"too short", 20, SIZE_MAX, SCI_EFORMAT, "too short"},
        {"a flipped byte", st.bytes, st.bytes / 2, SCI_EFORMAT, "checksum"},
        {"bad magic", st.bytes, 0, SCI_EFORMAT, "magic"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        unsigned char *b = malloc(st.bytes);
        memcpy(b, st.blob, st.bytes);
        if (cases[i].flip != SIZE_MAX)
            b[cases[i].flip] ^= 0x5a;
        prm.resume = b;
        prm.resume_bytes = cases[i].bytes;
        r = (sci_result){0};
        int rc = sci_rayformer_solve(p, &prm, &r, NULL, NULL);
        printf("%s: %s\n", cases[i].what, r.error.msg);
        assert_int_equal(rc, cases[i].code);
        assert_non_null(strstr(r.error.msg, cases[i].msg));
        assert_null(r.frames);
        sci_result_free_contents(&r);
        free(b);
    }
    /* another method's checkpoint */
    sci_scinerf_params sp;
    sci_scinerf_params_default(&sp);
    sp.iters = 8, sp.rays_per_step = 64, sp.samples = 8, sp.log2_table = 12, sp.metrics_every = 0;
    sp.resume = st.blob;
    sp.resume_bytes = st.bytes;
    r = (sci_result){0};
    assert_int_equal(sci_scinerf_solve(p, &sp, &r, NULL, NULL), SCI_EFORMAT);
    assert_non_null(strstr(r.error.msg, "rayformer"));
    sci_result_free_contents(&r);
    /* a different network (bigger hash table) */
    prm.resume = st.blob;
    prm.resume_bytes = st.bytes;
    prm.log2_table = 13;
    r = (sci_result){0};
    assert_int_equal(sci_rayformer_solve(p, &prm, &r, NULL, NULL), SCI_ESHAPE);
    assert_non_null(strstr(r.error.msg, "parameters"));
    sci_result_free_contents(&r);
    /* a different problem size */
    prm.log2_table = 12;
    sci_problem *q = nerf_tiny_problem(24, 3);
    r = (sci_result){0};
    assert_int_equal(sci_rayformer_solve(q, &prm, &r, NULL, NULL), SCI_ESHAPE);
    assert_non_null(strstr(r.error.msg, "problem"));
    sci_result_free_contents(&r);
    /* nothing left to do */
    prm.iters = 4;
    r = (sci_result){0};
    assert_int_equal(sci_rayformer_solve(p, &prm, &r, NULL, NULL), -EINVAL);
    sci_result_free_contents(&r);
    sci_problem_free(q);
    free(st.blob);
    sci_problem_free(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rayformer_cancel_resume),
        cmocka_unit_test(test_scinerf_periodic_resume),
        cmocka_unit_test(test_ema_resume),
        cmocka_unit_test(test_bad_checkpoints),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
