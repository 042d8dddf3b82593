/* tests/unit/test_nerf_mlp.c — the SCINeRF-style MLP field (mlp.h): gradient check of parameters, positions and
 * directions against double finite differences for both encodings (frequency with the skip connection, ReLU
 * density and frequency directions; hash grid with trunc_exp density and SH directions), bitwise determinism,
 * config errors.
 *
 * Tolerance as in test_nerf_rayformer.c: the float analytic gradient vs central differences (h = 1e-6) of the
 * double reference (ref.h), norm-wise relative error < 1e-4 (a right float backward gives ~1e-6, a wrong term
 * > 1e-2).
 */
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

#include "base/rng.h"
#include "recon/nerf/mlp.h"
#include "recon/nerf/ref.h"
#include "tests/helpers/gradcheck.h"

static uint64_t test_seed(void)
{
    const char *e = getenv("SCICAP_TEST_SEED");
    uint64_t s = e ? strtoull(e, NULL, 0) : 20240607u;
    printf("seed %llu (set SCICAP_TEST_SEED to replay)\n", (unsigned long long)s);
    return s;
}

static nerf_mlp_config small_freq(void)
{
    nerf_mlp_config c = nerf_mlp_config_scinerf();
    c.pos_freqs = 3, c.depth = 3, c.width = 8, c.skip = 2, c.feature_dim = 4, c.dir_freqs = 2, c.color_hidden = 5;
    c.density_bias = 0.5f;
    return c;
}

static nerf_mlp_config small_hash(void)
{
    nerf_mlp_config c = nerf_mlp_config_hash();
    c.grid = (nerf_hashgrid_config){.n_levels = 4, .n_features = 2, .log2_table = 10, .base_res = 4, .finest_res = 40};
    c.depth = 2, c.width = 8, c.feature_dim = 3, c.sh_degree = 3, c.color_hidden = 0;
    c.aabb_min[0] = -2.0f, c.aabb_max[2] = 3.0f;
    return c;
}

typedef struct problem {
    const nerf_mlp *net;
    int n, every, nd;
    double *P, *pos, *dir, *wsig, *wrgb;
} problem;

static double ref_loss(void *ctx)
{
    const problem *p = ctx;
    double *s = malloc(p->n * sizeof *s), *c = malloc(3 * p->n * sizeof *c), L = 0;
    nerf_ref_mlp_forward(p->net, p->P, p->n, p->pos, p->dir, p->every, s, c);
    for (int i = 0; i < p->n; i++) L += p->wsig[i] * s[i];
    for (int i = 0; i < 3 * p->n; i++) L += p->wrgb[i] * c[i];
    free(s), free(c);
    return L;
}


static void gradcheck(const nerf_mlp_config *cfg, const char *what)
{
    sci_rng rng;
    sci_rng_seed(&rng, test_seed(), 11);
    nerf_mlp *net;
    sci_error err = {0};
    assert_int_equal(nerf_mlp_new(&net, cfg, &err), 0);
    const int n = 15, every = 3, nd = 5;
    size_t np = nerf_mlp_param_count(net), nh = nerf_mlp_hash_param_count(net);
    float *P = malloc(np * 4), *G = malloc(np * 4);
    nerf_mlp_init(net, P, 3);
    for (size_t j = 0; j < nh; j++) P[j] = (float)(sci_rng_uniform(&rng) - 0.5);
    nerf_mlp_layout lo = nerf_mlp_layout_of(net);
    for (size_t j = lo.trunk_w[0]; j < np; j++) P[j] += (float)(0.05 * sci_rng_normal(&rng)); /* nonzero biases */
    problem pr = {.net = net, .n = n, .every = every, .nd = nd};
    pr.P = malloc(np * 8), pr.pos = malloc(3 * n * 8), pr.dir = malloc(3 * nd * 8);
    pr.wsig = malloc(n * 8), pr.wrgb = malloc(3 * n * 8);
    float *pos = malloc(3 * n * 4), *dir = malloc(3 * nd * 4), *sig = malloc(n * 4), *rgb = malloc(3 * n * 4);
    float *ws_ = malloc(n * 4), *wr = malloc(3 * n * 4), *dpos = malloc(3 * n * 4), *ddir = malloc(3 * nd * 4);
    const nerf_mlp_config *c = nerf_mlp_config_of(net);
    for (int i = 0; i < n; i++)
        for (int d = 0; d < 3; d++) {
            double lo_ = c->aabb_min[d], hi = c->aabb_max[d];
            pos[3 * i + d] = (float)(lo_ + (hi - lo_) * (0.05 + 0.9 * sci_rng_uniform(&rng)));
            pr.pos[3 * i + d] = pos[3 * i + d];
        }
    for (int r = 0; r < nd; r++) {
        double v[3], s = 0;
        for (int d = 0; d < 3; d++) v[d] = sci_rng_normal(&rng), s += v[d] * v[d];
        for (int d = 0; d < 3; d++) dir[3 * r + d] = (float)(v[d] / sqrt(s)), pr.dir[3 * r + d] = dir[3 * r + d];
    }
    for (int i = 0; i < n; i++) ws_[i] = (float)sci_rng_normal(&rng), pr.wsig[i] = ws_[i];
    for (int i = 0; i < 3 * n; i++) wr[i] = (float)sci_rng_normal(&rng), pr.wrgb[i] = wr[i];
    for (size_t j = 0; j < np; j++) pr.P[j] = P[j];
    nerf_mlp_ws *ws;
    assert_int_equal(nerf_mlp_ws_new(&ws, net, n, 2, &err), 0);
    assert_int_equal(nerf_mlp_forward(net, P, ws, n, pos, dir, every, sig, rgb), 0);
    assert_int_equal(nerf_mlp_backward(net, P, ws, ws_, wr, G, dpos, ddir), 0);

    double *rs = malloc(n * 8), *rc = malloc(3 * n * 8);
    nerf_ref_mlp_forward(net, pr.P, n, pr.pos, pr.dir, every, rs, rc);
    gradcheck_err fwd = {0}, par = {0};
    gradcheck_add_array(&fwd, sig, rs, (size_t)n);
    gradcheck_add_array(&fwd, rgb, rc, 3 * (size_t)n);
    double e_fwd = gradcheck_rel(&fwd);

    int checked = 0;
    for (size_t j = 0; j < np; j++) {
        if (!(j >= nh || G[j] != 0.0f || sci_rng_below(&rng, nh) < 64)) continue;
        gradcheck_add(&par, G[j], gradcheck_fd(&pr.P[j], ref_loss, &pr));
        checked++;
    }
    double e_par = gradcheck_rel(&par);
    double e_pos = gradcheck_inputs(dpos, pr.pos, 3 * (size_t)n, ref_loss, &pr);
    double e_dir = gradcheck_inputs(ddir, pr.dir, 3 * (size_t)nd, ref_loss, &pr);
    printf("mlp %-28s forward %.2g; %d parameters %.3g, positions %.3g, directions %.3g (bound 1e-4)\n", what,
           e_fwd, checked, e_par, e_pos, e_dir);
    assert_true(e_fwd < 1e-5);
    assert_true(e_par < 1e-4);
    assert_true(e_pos < 1e-4);
    assert_true(e_dir < 1e-4);
    free(rs), free(rc), free(pos), free(dir), free(sig), free(rgb), free(ws_), free(wr), free(dpos), free(ddir);
    free(pr.P), free(pr.pos), free(pr.dir), free(pr.wsig), free(pr.wrgb), free(P), free(G);
    nerf_mlp_ws_free(ws);
    nerf_mlp_free(net);
}

static void test_mlp_gradcheck_freq(void **state)
{
    (void)state;
    nerf_mlp_config c = small_freq();
    gradcheck(&c, "freq, skip, relu, freq dirs");
}

static void test_mlp_gradcheck_hash(void **state)
{
    (void)state;
    nerf_mlp_config c = small_hash();
    gradcheck(&c, "hash, trunc_exp, SH, no hidden");
}

/* Same inputs and thread count: bitwise identical outputs and gradients; 3 threads over 1000 points, direction
 * groups of 7 (thread ranges fall on group borders). */
static void test_mlp_deterministic(void **state)
{
    (void)state;
    uint64_t seed = test_seed();
    nerf_mlp_config cfg = nerf_mlp_config_scinerf();
    cfg.width = 64, cfg.feature_dim = 32, cfg.color_hidden = 32;
    nerf_mlp *net;
    sci_error err = {0};
    assert_int_equal(nerf_mlp_new(&net, &cfg, &err), 0);
    const int n = 1000, every = 7, nd = (n + every - 1) / every;
    size_t np = nerf_mlp_param_count(net);
    float *P = malloc(np * 4), *pos = malloc(3 * n * 4), *dir = malloc(3 * nd * 4), *ds = malloc(n * 4);
    float *dc = malloc(3 * n * 4), *out[2][5];
    sci_rng rng;
    sci_rng_seed(&rng, seed, 5);
    nerf_mlp_init(net, P, seed);
    for (int i = 0; i < 3 * n; i++) pos[i] = (float)(2 * sci_rng_uniform(&rng) - 1), dc[i] = (float)sci_rng_normal(&rng);
    for (int i = 0; i < n; i++) ds[i] = (float)sci_rng_normal(&rng);
    for (int r = 0; r < nd; r++) dir[3 * r] = 0.6f, dir[3 * r + 1] = 0.0f, dir[3 * r + 2] = -0.8f;
    for (int run = 0; run < 2; run++) {
        nerf_mlp_ws *ws;
        assert_int_equal(nerf_mlp_ws_new(&ws, net, n, 3, &err), 0);
        out[run][0] = malloc(n * 4), out[run][1] = malloc(3 * n * 4), out[run][2] = malloc(np * 4);
        out[run][3] = malloc(3 * n * 4), out[run][4] = malloc(3 * nd * 4);
        assert_int_equal(nerf_mlp_forward(net, P, ws, n, pos, dir, every, out[run][0], out[run][1]), 0);
        assert_int_equal(nerf_mlp_backward(net, P, ws, ds, dc, out[run][2], out[run][3], out[run][4]), 0);
        nerf_mlp_ws_free(ws);
    }
    assert_memory_equal(out[0][0], out[1][0], n * 4);
    assert_memory_equal(out[0][1], out[1][1], 3 * n * 4);
    assert_memory_equal(out[0][2], out[1][2], np * 4);
    assert_memory_equal(out[0][3], out[1][3], 3 * n * 4);
    assert_memory_equal(out[0][4], out[1][4], 3 * nd * 4);
    int finite = 1;
    for (size_t j = 0; j < np; j++) finite &= isfinite(out[0][2][j]);
    assert_true(finite);
    for (int run = 0; run < 2; run++)
        for (int k = 0; k < 5; k++) free(out[run][k]);
    free(P), free(pos), free(dir), free(ds), free(dc);
    nerf_mlp_free(net);
}

static void test_mlp_config_errors(void **state)
{
    (void)state;
    nerf_mlp *net = NULL;
    sci_error err = {0};
    nerf_mlp_config c = nerf_mlp_config_scinerf();
    c.skip = 8;
    assert_int_equal(nerf_mlp_new(&net, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "skip"));
    c = nerf_mlp_config_scinerf();
    c.density_act = NERF_ACT_GELU;
    assert_int_equal(nerf_mlp_new(&net, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "density_act"));
    c = nerf_mlp_config_hash();
    c.grid.n_levels = 0;
    assert_int_equal(nerf_mlp_new(&net, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "n_levels"));
    c = nerf_mlp_config_scinerf();
    c.aabb_max[2] = c.aabb_min[2];
    assert_int_equal(nerf_mlp_new(&net, &c, &err), SCI_ECONFIG);
    assert_null(net);
    c = nerf_mlp_config_hash();
    assert_int_equal(nerf_mlp_new(&net, &c, &err), 0);
    nerf_mlp_ws *ws = NULL;
    assert_int_equal(nerf_mlp_ws_new(&ws, net, 0, 1, &err), -EINVAL);
    assert_int_equal(nerf_mlp_ws_new(&ws, net, 10, 1, &err), 0);
    float x[3 * 11] = {0}, d[3 * 11] = {0}, s[11], rgb[33], g[1];
    assert_int_equal(nerf_mlp_forward(net, NULL, ws, 11, x, d, 1, s, rgb), -EINVAL);
    assert_int_equal(nerf_mlp_backward(net, NULL, ws, NULL, NULL, g, NULL, NULL), -EINVAL); /* no forward yet */
    nerf_mlp_ws_free(ws);
    nerf_mlp_free(net);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mlp_gradcheck_freq),
        cmocka_unit_test(test_mlp_gradcheck_hash),
        cmocka_unit_test(test_mlp_deterministic),
        cmocka_unit_test(test_mlp_config_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
