/* tests/unit/test_nerf_rayformer.c — the whole RayFormer network (hash grid, two I²R blocks, heads, SH colour):
 * gradient check of parameters, sample positions and directions against double finite differences, and bitwise
 * determinism.
 *
 * Tolerance: the network runs in float32, so its analytic gradient carries float rounding (~1e-7 per operation,
 * grown by the sums of a few hundred terms); it is compared with central differences (h = 1e-6) of the double
 * reference path (ref.h), whose own error is ~1e-10. A float backward that is right gives a norm-wise relative
 * error near 1e-6; any wrong term gives > 1e-2. The bound 1e-4 of the issue separates the two by two decades.
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "base/rng.h"
#include "recon/nerf/block.h"
#include "recon/nerf/rayformer.h"
#include "recon/nerf/ref.h"
#include "tests/helpers/gradcheck.h"

static uint64_t test_seed(void)
{
    const char *e = getenv("SCICAP_TEST_SEED");
    uint64_t s = e ? strtoull(e, NULL, 0) : 20240605u;
    printf("seed %llu (set SCICAP_TEST_SEED to replay)\n", (unsigned long long)s);
    return s;
}

static nerf_rayformer_config small_config(void)
{
    nerf_rayformer_config c = nerf_rayformer_config_default();
    c.grid = (nerf_hashgrid_config){.n_levels = 4, .n_features = 2, .log2_table = 10, .base_res = 4, .finest_res = 40};
    c.width = 8, c.heads = 2, c.ffn_hidden = 8, c.geo_dim = 3, c.sh_degree = 4, c.color_hidden = 4;
    c.patch_w = 2, c.patch_h = 2, c.samples = 3;
    return c;
}

typedef struct problem {
    int P, N, R;
    double *pos, *dir, *wsig, *wrgb;
} problem;

static void make_problem(problem *p, const nerf_rayformer_config *c, int P, sci_rng *rng)
{
    p->P = P, p->R = c->patch_w * c->patch_h, p->N = P * p->R * c->samples;
    p->pos = malloc(3 * p->N * sizeof(double));
    p->dir = malloc(3 * P * p->R * sizeof(double));
    p->wsig = malloc(p->N * sizeof(double));
    p->wrgb = malloc(3 * p->N * sizeof(double));
    for (int i = 0; i < 3 * p->N; i++) p->pos[i] = (float)(1.8 * sci_rng_uniform(rng) - 0.9);
    for (int r = 0; r < P * p->R; r++) {
        double v[3], n = 0;
        for (int d = 0; d < 3; d++) v[d] = sci_rng_normal(rng), n += v[d] * v[d];
        for (int d = 0; d < 3; d++) p->dir[3 * r + d] = (float)(v[d] / sqrt(n));
    }
    for (int i = 0; i < p->N; i++) p->wsig[i] = sci_rng_normal(rng);
    for (int i = 0; i < 3 * p->N; i++) p->wrgb[i] = sci_rng_normal(rng);
}

static void free_problem(problem *p) { free(p->pos), free(p->dir), free(p->wsig), free(p->wrgb); }

/* What the double reference loss reads: the network, its parameters in double, the problem's inputs. */
typedef struct loss_ctx {
    const nerf_rayformer *net;
    const double *P;
    const problem *pr;
} loss_ctx;

static double ref_loss(void *ctx)
{
    const loss_ctx *x = ctx;
    const problem *pr = x->pr;
    double *s = malloc(pr->N * sizeof *s), *c = malloc(3 * pr->N * sizeof *c), L = 0;
    nerf_ref_rayformer_forward(x->net, x->P, pr->P, pr->pos, pr->dir, s, c);
    for (int i = 0; i < pr->N; i++) L += pr->wsig[i] * s[i];
    for (int i = 0; i < 3 * pr->N; i++) L += pr->wrgb[i] * c[i];
    free(s), free(c);
    return L;
}

static void gradcheck(const nerf_rayformer_config *cfg_in, const char *what)
{
    sci_rng rng;
    sci_rng_seed(&rng, test_seed(), 1);
    nerf_rayformer_config cfg = *cfg_in;
    nerf_rayformer *net;
    sci_error err = {0};
    assert_int_equal(nerf_rayformer_new(&net, &cfg, &err), 0);
    problem pr;
    make_problem(&pr, &cfg, 2, &rng);
    size_t np = nerf_rayformer_param_count(net), nh = nerf_rayformer_hash_param_count(net);
    float *P = malloc(np * sizeof *P), *G = malloc(np * sizeof *G);
    nerf_rayformer_init(net, P, 7);
    /* larger hash features than the ±1e-4 init so the grid matters in the check */
    for (size_t j = 0; j < nh; j++) P[j] = (float)(sci_rng_uniform(&rng) - 0.5);
    /* LN affine away from identity to exercise γ, β */
    nerf_rayformer_layout lo = nerf_rayformer_layout_of(net);
    for (size_t j = lo.lnf_g; j < lo.lnf_b + (size_t)cfg.width; j++) P[j] = (float)(1.0 + 0.3 * sci_rng_normal(&rng));
    if (cfg.inter_gate && cfg.inter_ray) { /* gates open (0 at init would cut the attention's own gradients) */
        nerf_block_shape bs = {.att = {.C = cfg.width, .heads = cfg.heads}, .hidden = cfg.ffn_hidden, .inter_gate = 1};
        nerf_block_offsets bo = nerf_block_layout(&bs);
        for (int b = 0; b < cfg.n_blocks; b++)
            for (int h = 0; h < cfg.heads; h++)
                P[lo.block[b] + bo.gate + h] = 0.7f - 0.5f * h;
    }
    nerf_rayformer_ws *ws;
    assert_int_equal(nerf_rayformer_ws_new(&ws, net, pr.P, 2, &err), 0);
    int N = pr.N, nr = pr.P * pr.R;
    float *pos = malloc(3 * N * sizeof *pos), *dir = malloc(3 * nr * sizeof *dir), *sig = malloc(N * sizeof *sig);
    float *rgb = malloc(3 * N * sizeof *rgb), *ws_ = malloc(N * sizeof *ws_), *wr = malloc(3 * N * sizeof *wr);
    float *dpos = malloc(3 * N * sizeof *dpos), *ddir = malloc(3 * nr * sizeof *ddir);
    for (int i = 0; i < 3 * N; i++) pos[i] = (float)pr.pos[i], wr[i] = (float)pr.wrgb[i];
    for (int i = 0; i < N; i++) ws_[i] = (float)pr.wsig[i];
    for (int i = 0; i < 3 * nr; i++) dir[i] = (float)pr.dir[i];
    assert_int_equal(nerf_rayformer_forward(net, P, ws, pr.P, pos, dir, sig, rgb), 0);
    assert_int_equal(nerf_rayformer_backward(net, P, ws, ws_, wr, G, dpos, ddir), 0);

    double *Pd = malloc(np * sizeof *Pd);
    for (size_t j = 0; j < np; j++) Pd[j] = P[j];
    /* forward agreement */
    double *rs = malloc(N * sizeof *rs), *rc = malloc(3 * N * sizeof *rc);
    nerf_ref_rayformer_forward(net, Pd, pr.P, pr.pos, pr.dir, rs, rc);
    gradcheck_err fwd = {0}, par = {0};
    gradcheck_add_array(&fwd, sig, rs, (size_t)N);
    gradcheck_add_array(&fwd, rgb, rc, 3 * (size_t)N);
    printf("forward: relative difference float vs double %.3g\n", gradcheck_rel(&fwd));
    assert_true(gradcheck_rel(&fwd) < 1e-5);

    /* parameters: every non-hash parameter, every hash entry with a gradient, 64 random hash entries */
    loss_ctx lc = {.net = net, .P = Pd, .pr = &pr};
    int checked = 0;
    for (size_t j = 0; j < np; j++) {
        int pick = j >= nh || G[j] != 0.0f || sci_rng_below(&rng, nh) < 64;
        if (!pick) continue;
        gradcheck_add(&par, G[j], gradcheck_fd(&Pd[j], ref_loss, &lc));
        checked++;
    }
    double e_par = gradcheck_rel(&par);
    double e_pos = gradcheck_inputs(dpos, pr.pos, 3 * (size_t)N, ref_loss, &lc);
    double e_dir = gradcheck_inputs(ddir, pr.dir, 3 * (size_t)nr, ref_loss, &lc);
    printf("gradcheck (%s): %d parameters rel err %.3g; positions %.3g; directions %.3g (bound 1e-4)\n", what,
           checked, e_par, e_pos, e_dir);
    assert_true(e_par < 1e-4);
    assert_true(e_pos < 1e-4);
    assert_true(e_dir < 1e-4);
    free(rs), free(rc), free(Pd), free(pos), free(dir), free(sig), free(rgb), free(ws_), free(wr), free(dpos), free(ddir);
    free(P), free(G);
    free_problem(&pr);
    nerf_rayformer_ws_free(ws);
    nerf_rayformer_free(net);
}

static void test_rayformer_gradcheck(void **state)
{
    (void)state;
    nerf_rayformer_config c = small_config();
    gradcheck(&c, "both paths");
}

/* The ablation switches: with one attention path passed through, the network is still exactly differentiable. */
static void test_rayformer_gradcheck_ablation(void **state)
{
    (void)state;
    nerf_rayformer_config c = small_config();
    c.intra_ray = 0;
    gradcheck(&c, "intra-ray off");
    c = small_config();
    c.inter_ray = 0;
    gradcheck(&c, "inter-ray off");
    c = small_config();
    c.intra_slope = 0.8f; /* the intra-ray distance bias: a fixed term in the logits, still exact */
    gradcheck(&c, "intra-ray slope 0.8");
    c = small_config();
    c.inter_gate = 1; /* the inter-ray path behind its learned gate, with the solver's city-block bias */
    c.inter_slope = 1;
    gradcheck(&c, "inter-ray gate");
}

/* The inter-ray gate closed (its value at init) makes the path exactly the ablation's pass-through: the gated
 * network's outputs are bitwise those of the network without inter-ray attention, for the same other parameters
 * (random here, so the attention's output projections are not the zero-init's zeros); an open gate changes them. */
static void test_rayformer_gate_closed_is_pass_through(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, test_seed(), 3);
    nerf_rayformer_config c_off = small_config(), c_on = small_config();
    c_off.inter_ray = 0, c_off.inter_gate = 0;
    c_on.inter_ray = 1, c_on.inter_gate = 1;
    nerf_rayformer *off, *on;
    sci_error err = {0};
    assert_int_equal(nerf_rayformer_new(&off, &c_off, &err), 0);
    assert_int_equal(nerf_rayformer_new(&on, &c_on, &err), 0);
    const size_t n_off = nerf_rayformer_param_count(off), n_on = nerf_rayformer_param_count(on);
    const size_t nh = nerf_rayformer_hash_param_count(off);
    assert_int_equal(n_on, n_off + (size_t)c_on.n_blocks * c_on.heads); /* one gate per head and block, nothing else */
    float *p_off = malloc(n_off * sizeof *p_off), *p_on = malloc(n_on * sizeof *p_on);
    nerf_rayformer_init(off, p_off, 7);
    for (size_t j = 0; j < n_off; j++)
        p_off[j] += (float)(j < nh ? sci_rng_uniform(&rng) - 0.5 : 0.2 * sci_rng_normal(&rng));
    /* the same parameters in the gated layout: each block's gates follow its other parameters (block.h) */
    const nerf_rayformer_layout lf = nerf_rayformer_layout_of(off), ln = nerf_rayformer_layout_of(on);
    const size_t blk = lf.block[1] - lf.block[0];
    memcpy(p_on, p_off, lf.block[0] * sizeof *p_on);
    for (int b = 0; b < c_on.n_blocks; b++) {
        memcpy(p_on + ln.block[b], p_off + lf.block[b], blk * sizeof *p_on);
        memset(p_on + ln.block[b] + blk, 0, (size_t)c_on.heads * sizeof *p_on);
    }
    memcpy(p_on + ln.lnf_g, p_off + lf.lnf_g, (n_off - lf.lnf_g) * sizeof *p_on);
    problem pr;
    make_problem(&pr, &c_on, 3, &rng);
    const int N = pr.N, nr = pr.P * pr.R;
    float *pos = malloc(3 * N * sizeof *pos), *dir = malloc(3 * nr * sizeof *dir);
    float *sig[2], *rgb[2];
    for (int i = 0; i < 3 * N; i++) pos[i] = (float)pr.pos[i];
    for (int i = 0; i < 3 * nr; i++) dir[i] = (float)pr.dir[i];
    for (int k = 0; k < 2; k++) sig[k] = malloc(N * sizeof(float)), rgb[k] = malloc(3 * N * sizeof(float));
    nerf_rayformer_ws *ws_off, *ws_on;
    assert_int_equal(nerf_rayformer_ws_new(&ws_off, off, pr.P, 2, &err), 0);
    assert_int_equal(nerf_rayformer_ws_new(&ws_on, on, pr.P, 2, &err), 0);
    assert_int_equal(nerf_rayformer_forward(off, p_off, ws_off, pr.P, pos, dir, sig[0], rgb[0]), 0);
    assert_int_equal(nerf_rayformer_forward(on, p_on, ws_on, pr.P, pos, dir, sig[1], rgb[1]), 0);
    assert_memory_equal(sig[0], sig[1], N * sizeof(float));
    assert_memory_equal(rgb[0], rgb[1], 3 * N * sizeof(float));
    for (int b = 0; b < c_on.n_blocks; b++)
        for (int h = 0; h < c_on.heads; h++) p_on[ln.block[b] + blk + h] = 0.5f;
    assert_int_equal(nerf_rayformer_forward(on, p_on, ws_on, pr.P, pos, dir, sig[1], rgb[1]), 0);
    assert_true(memcmp(sig[0], sig[1], N * sizeof(float)) != 0);
    printf("gate closed: outputs bitwise the pass-through's; gate 0.5: they differ\n");
    for (int k = 0; k < 2; k++) free(sig[k]), free(rgb[k]);
    free(pos), free(dir), free(p_off), free(p_on);
    free_problem(&pr);
    nerf_rayformer_ws_free(ws_off), nerf_rayformer_ws_free(ws_on);
    nerf_rayformer_free(off), nerf_rayformer_free(on);
}

/* The density/geometry head with a hidden ReLU layer (head_hidden > 0) instead of the paper's single FC layer. */
static void test_rayformer_gradcheck_head_hidden(void **state)
{
    (void)state;
    nerf_rayformer_config c = small_config();
    c.head_hidden = 6;
    gradcheck(&c, "hidden head layer");
    c = small_config();
    c.final_norm = 0;
    gradcheck(&c, "no final layer norm");
}

/* Same seed: bitwise identical outputs and gradients on 2 threads and on 3 (patches and hash levels are scheduled
 * dynamically and the sums never depend on which thread did what). */
static void deterministic_check(const nerf_rayformer_config *c, int Pn)
{
    sci_rng rng;
    uint64_t seed = test_seed();
    const nerf_rayformer_config cfg = *c;
    nerf_rayformer *net;
    sci_error err = {0};
    assert_int_equal(nerf_rayformer_new(&net, &cfg, &err), 0);
    const int R = cfg.patch_w * cfg.patch_h, N = Pn * R * cfg.samples;
    size_t np = nerf_rayformer_param_count(net);
    float *P = malloc(np * 4), *out[2][6];
    float *pos = malloc(3 * N * 4), *dir = malloc(3 * Pn * R * 4), *ds = malloc(N * 4), *dc = malloc(3 * N * 4);
    for (int run = 0; run < 2; run++) {
        sci_rng_seed(&rng, seed, 2);
        nerf_rayformer_init(net, P, seed);
        for (int i = 0; i < 3 * N; i++) pos[i] = (float)(2 * sci_rng_uniform(&rng) - 1), dc[i] = (float)sci_rng_normal(&rng);
        for (int i = 0; i < N; i++) ds[i] = (float)sci_rng_normal(&rng);
        for (int r = 0; r < Pn * R; r++) dir[3 * r] = 0.6f, dir[3 * r + 1] = 0.0f, dir[3 * r + 2] = -0.8f;
        nerf_rayformer_ws *ws;
        assert_int_equal(nerf_rayformer_ws_new(&ws, net, Pn, run == 0 ? 2 : 3, &err), 0);
        out[run][0] = malloc(N * 4), out[run][1] = malloc(3 * N * 4), out[run][2] = malloc(np * 4);
        out[run][3] = malloc(3 * N * 4), out[run][4] = malloc(3 * Pn * R * 4), out[run][5] = NULL;
        assert_int_equal(nerf_rayformer_forward(net, P, ws, Pn, pos, dir, out[run][0], out[run][1]), 0);
        assert_int_equal(nerf_rayformer_backward(net, P, ws, ds, dc, out[run][2], out[run][3], out[run][4]), 0);
        nerf_rayformer_ws_free(ws);
    }
    assert_memory_equal(out[0][0], out[1][0], N * 4);
    assert_memory_equal(out[0][1], out[1][1], 3 * N * 4);
    assert_memory_equal(out[0][2], out[1][2], np * 4);
    assert_memory_equal(out[0][3], out[1][3], 3 * N * 4);
    assert_memory_equal(out[0][4], out[1][4], 3 * Pn * R * 4);
    int finite = 1;
    for (size_t j = 0; j < np; j++) finite &= isfinite(out[0][2][j]);
    assert_true(finite);
    for (int run = 0; run < 2; run++)
        for (int k = 0; k < 5; k++) free(out[run][k]);
    free(P), free(pos), free(dir), free(ds), free(dc);
    nerf_rayformer_free(net);
}

/* Full-size 8×8×32 patches, and the default 2×2×16 ones (40 small patches shared out dynamically). */
static void test_rayformer_deterministic(void **state)
{
    (void)state;
    nerf_rayformer_config cfg = nerf_rayformer_config_default();
    deterministic_check(&cfg, 4);
    cfg.patch_w = cfg.patch_h = 2, cfg.samples = 16;
    deterministic_check(&cfg, 40);
}

/* Patches are taken in groups of about 1024 rows (rayformer.c): 2 full groups and a partial one in one call give
 * the outputs of one call per patch, and the gradient of their sum (float rounding only: the sums' order
 * differs). A group that ran a wrong number of patches, or wrote another group's rows, fails by O(1). */
static double rel_diff(const float *a, const double *b, size_t n)
{
    double d = 0.0, s = 0.0;
    for (size_t i = 0; i < n; i++) d += (a[i] - b[i]) * (a[i] - b[i]), s += b[i] * b[i];
    return sqrt(d / (s > 0 ? s : 1));
}

static void test_rayformer_groups(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, test_seed(), 3);
    nerf_rayformer_config cfg = small_config();
    nerf_rayformer *net;
    sci_error err = {0};
    assert_int_equal(nerf_rayformer_new(&net, &cfg, &err), 0);
    const int R = cfg.patch_w * cfg.patch_h, L = cfg.samples, group = 1024 / (R * L), Pn = 2 * group + 7;
    const int N = Pn * R * L;
    const size_t np = nerf_rayformer_param_count(net);
    float *P = malloc(np * 4), *pos = malloc(3 * (size_t)N * 4), *dir = malloc(3 * (size_t)Pn * R * 4);
    float *ds = malloc((size_t)N * 4), *dc = malloc(3 * (size_t)N * 4), *sig = malloc((size_t)N * 4);
    float *rgb = malloc(3 * (size_t)N * 4), *G = malloc(np * 4), *dpos = malloc(3 * (size_t)N * 4);
    float *ddir = malloc(3 * (size_t)Pn * R * 4), *G1 = malloc(np * 4);
    double *sig1 = malloc((size_t)N * 8), *rgb1 = malloc(3 * (size_t)N * 8), *Gs = calloc(np, 8);
    double *dpos1 = malloc(3 * (size_t)N * 8), *ddir1 = malloc(3 * (size_t)Pn * R * 8);
    nerf_rayformer_init(net, P, 11);
    for (size_t j = 0; j < nerf_rayformer_hash_param_count(net); j++) P[j] = (float)(sci_rng_uniform(&rng) - 0.5);
    for (int i = 0; i < 3 * N; i++) pos[i] = (float)(2 * sci_rng_uniform(&rng) - 1), dc[i] = (float)sci_rng_normal(&rng);
    for (int i = 0; i < N; i++) ds[i] = (float)sci_rng_normal(&rng);
    for (int r = 0; r < Pn * R; r++) dir[3 * r] = 0.6f, dir[3 * r + 1] = 0.0f, dir[3 * r + 2] = -0.8f;

    nerf_rayformer_ws *ws;
    assert_int_equal(nerf_rayformer_ws_new(&ws, net, Pn, 2, &err), 0);
    assert_int_equal(nerf_rayformer_forward(net, P, ws, Pn, pos, dir, sig, rgb), 0);
    assert_int_equal(nerf_rayformer_backward(net, P, ws, ds, dc, G, dpos, ddir), 0);
    nerf_rayformer_ws_free(ws);

    assert_int_equal(nerf_rayformer_ws_new(&ws, net, 1, 1, &err), 0);
    for (int p = 0; p < Pn; p++) {
        const size_t r0 = (size_t)p * R * L;
        float s1[64], c1[192], dp1[192], dd1[12];
        assert_true(R * L <= 64 && R <= 4);
        assert_int_equal(nerf_rayformer_forward(net, P, ws, 1, pos + 3 * r0, dir + 3 * (size_t)p * R, s1, c1), 0);
        assert_int_equal(nerf_rayformer_backward(net, P, ws, ds + r0, dc + 3 * r0, G1, dp1, dd1), 0);
        for (int i = 0; i < R * L; i++) {
            sig1[r0 + i] = s1[i], dpos1[3 * (r0 + i)] = dp1[3 * i];
            dpos1[3 * (r0 + i) + 1] = dp1[3 * i + 1], dpos1[3 * (r0 + i) + 2] = dp1[3 * i + 2];
            for (int c = 0; c < 3; c++) rgb1[3 * (r0 + i) + c] = c1[3 * i + c];
        }
        for (int i = 0; i < 3 * R; i++) ddir1[3 * (size_t)p * R + i] = dd1[i];
        for (size_t j = 0; j < np; j++) Gs[j] += G1[j];
    }
    nerf_rayformer_ws_free(ws);
    printf("%d patches in groups of %d against one call each: sigma %.2g, rgb %.2g, gradient %.2g, positions %.2g, "
           "directions %.2g\n", Pn, group, rel_diff(sig, sig1, (size_t)N), rel_diff(rgb, rgb1, 3 * (size_t)N),
           rel_diff(G, Gs, np), rel_diff(dpos, dpos1, 3 * (size_t)N), rel_diff(ddir, ddir1, 3 * (size_t)Pn * R));
    assert_true(rel_diff(sig, sig1, (size_t)N) < 1e-6);
    assert_true(rel_diff(rgb, rgb1, 3 * (size_t)N) < 1e-6);
    assert_true(rel_diff(G, Gs, np) < 1e-5);
    assert_true(rel_diff(dpos, dpos1, 3 * (size_t)N) < 1e-6);
    assert_true(rel_diff(ddir, ddir1, 3 * (size_t)Pn * R) < 1e-6);
    free(P), free(pos), free(dir), free(ds), free(dc), free(sig), free(rgb), free(G), free(dpos), free(ddir);
    free(G1), free(sig1), free(rgb1), free(Gs), free(dpos1), free(ddir1);
    nerf_rayformer_free(net);
}

static void test_rayformer_config_errors(void **state)
{
    (void)state;
    nerf_rayformer_config c = nerf_rayformer_config_default();
    nerf_rayformer *net = NULL;
    sci_error err = {0};
    c.width = 30;
    assert_int_equal(nerf_rayformer_new(&net, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "width"));
    c = nerf_rayformer_config_default();
    c.heads = 3;
    assert_int_equal(nerf_rayformer_new(&net, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "heads"));
    c = nerf_rayformer_config_default();
    c.head_hidden = -1;
    assert_int_equal(nerf_rayformer_new(&net, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "head_hidden"));
    c = nerf_rayformer_config_default();
    c.intra_slope = -1.0f;
    assert_int_equal(nerf_rayformer_new(&net, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "intra_slope"));
    c = nerf_rayformer_config_default();
    c.aabb_max[1] = c.aabb_min[1];
    assert_int_equal(nerf_rayformer_new(&net, &c, &err), SCI_ECONFIG);
    assert_null(net);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rayformer_gradcheck),
        cmocka_unit_test(test_rayformer_gradcheck_ablation),
        cmocka_unit_test(test_rayformer_gate_closed_is_pass_through),
        cmocka_unit_test(test_rayformer_gradcheck_head_hidden),
        cmocka_unit_test(test_rayformer_deterministic),
        cmocka_unit_test(test_rayformer_groups),
        cmocka_unit_test(test_rayformer_config_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
