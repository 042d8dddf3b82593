/* tests/unit/test_nerf_blocks.c — gradient checks of the elementwise, dense, normalisation, encoding, hash-grid,
 * attention and transformer-block kernels, with their hard cases.
 *
 * Method: loss = Σ w·output with random w; the float kernel's analytic backward is compared with central
 * differences (h = 1e-6) of the double reference (ref.h or a local double formula), as a norm-wise relative
 * error ‖g_analytic − g_fd‖/‖g_fd‖ < 1e-4. Tolerance: the float backward carries float32 rounding (~1e-7 relative
 * per operation, ~1e-6 after the sums here); the double FD is accurate to ~1e-10; a wrong term shows as > 1e-2.
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
#include "recon/nerf/act.h"
#include "recon/nerf/attention.h"
#include "recon/nerf/block.h"
#include "recon/nerf/hashgrid.h"
#include "recon/nerf/layernorm.h"
#include "recon/nerf/linear.h"
#include "recon/nerf/posenc.h"
#include "recon/nerf/ref.h"
#include "recon/nerf/shenc.h"

static sci_rng RNG_; /* per-program test stream, seeded in main (tests run sequentially) */

static uint64_t test_seed(void)
{
    const char *e = getenv("SCICAP_TEST_SEED");
    uint64_t s = e ? strtoull(e, NULL, 0) : 20240606u;
    printf("seed %llu (set SCICAP_TEST_SEED to replay)\n", (unsigned long long)s);
    return s;
}

static double unif(double a, double b) { return a + (b - a) * sci_rng_uniform(&RNG_); }

/* Accumulates a norm-wise relative error. */
typedef struct erracc {
    double num, den;
} erracc;
static void acc(erracc *e, double analytic, double fd) { e->num += (analytic - fd) * (analytic - fd), e->den += fd * fd; }
static double relerr(const erracc *e) { return e->den > 0 ? sqrt(e->num / e->den) : sqrt(e->num); }

typedef double (*lossfn)(void *ctx);
static double central(double *v, lossfn f, void *ctx)
{
    const double h = 1e-6 * (fabs(*v) > 1 ? fabs(*v) : 1), x0 = *v;
    *v = x0 + h;
    double a = f(ctx);
    *v = x0 - h;
    double b = f(ctx);
    *v = x0;
    return (a - b) / (2 * h);
}

/* ------------------------------------------------------------------ activations */

typedef struct actctx {
    nerf_act a;
    int n;
    double *x, *w;
} actctx;

static double act_ref(nerf_act a, double x)
{
    switch (a) {
    case NERF_ACT_RELU: return x > 0 ? x : 0;
    case NERF_ACT_GELU: return nerf_ref_gelu(x);
    case NERF_ACT_SOFTPLUS: return x > 20 ? x : log1p(exp(x));
    case NERF_ACT_TRUNC_EXP: return exp(x);
    case NERF_ACT_SIGMOID: return 1 / (1 + exp(-x));
    default: return x;
    }
}

static double act_loss(void *c)
{
    actctx *k = c;
    double L = 0;
    for (int i = 0; i < k->n; i++) L += k->w[i] * act_ref(k->a, k->x[i]);
    return L;
}

static void check_act(nerf_act a, double lo, double hi)
{
    enum { N = 200 };
    double x[N], w[N];
    float xf[N], yf[N], wf[N], dx[N];
    for (int i = 0; i < N; i++) {
        xf[i] = (float)unif(lo, hi);
        if (a == NERF_ACT_RELU && fabsf(xf[i]) < 1e-3f) xf[i] = 0.5f; /* keep FD off the kink */
        x[i] = xf[i], w[i] = unif(-1, 1), wf[i] = (float)w[i];
    }
    nerf_act_forward(a, N, xf, yf);
    nerf_act_backward(a, N, xf, yf, wf, dx);
    actctx k = {a, N, x, w};
    erracc e = {0}, fe = {0};
    for (int i = 0; i < N; i++) {
        acc(&fe, yf[i], act_ref(a, x[i]));
        acc(&e, dx[i], central(&x[i], act_loss, &k));
    }
    printf("%-9s forward %.2g, gradient %.2g\n", nerf_act_name(a), relerr(&fe), relerr(&e));
    assert_true(relerr(&fe) < 1e-6);
    assert_true(relerr(&e) < 1e-4);
}

static void test_activations(void **s)
{
    (void)s;
    check_act(NERF_ACT_RELU, -3, 3);
    check_act(NERF_ACT_GELU, -6, 6);
    check_act(NERF_ACT_SOFTPLUS, -30, 30);
    check_act(NERF_ACT_TRUNC_EXP, -14, 14);
    check_act(NERF_ACT_SIGMOID, -12, 12);
}

/* The fused GELU pass (value and derivative, used by the block) against the double reference and its derivative
 * by central differences, over [−8, 8] including 0 and the tails, and NaN propagation. */
static void test_gelu_with_grad(void **s)
{
    (void)s;
    enum { N = 1601 };
    float x[N + 1], y[N + 1], g[N + 1];
    for (int i = 0; i < N; i++) x[i] = -8.0f + 16.0f * (float)i / (N - 1);
    x[N] = NAN;
    nerf_act_gelu_with_grad(N + 1, x, y, g);
    double ey = 0, eg = 0;
    for (int i = 0; i < N; i++) {
        double h = 1e-5, r = nerf_ref_gelu(x[i]), rg = (nerf_ref_gelu(x[i] + h) - nerf_ref_gelu(x[i] - h)) / (2 * h);
        ey = fmax(ey, fabs(y[i] - r)), eg = fmax(eg, fabs(g[i] - rg));
    }
    printf("gelu with grad: max |error| value %.2g, derivative %.2g\n", ey, eg);
    assert_true(ey < 1e-6);
    assert_true(eg < 1e-6);
    assert_true(isnan(y[N]) && isnan(g[N]));
}

/* trunc_exp: the backward is clamped at ±15 (finite for any input), the forward saturates at exp(88). */
static void test_trunc_exp_clamp(void **s)
{
    (void)s;
    float x[4] = {-1e30f, -50.0f, 50.0f, 1e30f}, y[4], g[4] = {1, 1, 1, 1}, dx[4];
    nerf_act_forward(NERF_ACT_TRUNC_EXP, 4, x, y);
    nerf_act_backward(NERF_ACT_TRUNC_EXP, 4, x, y, g, dx);
    for (int i = 0; i < 4; i++) assert_true(isfinite(y[i]) && isfinite(dx[i]));
    assert_float_equal(dx[0], expf(-15.0f), 1e-12);
    assert_float_equal(dx[3], expf(15.0f), 1.0);
    assert_float_equal(y[0], 0.0f, 0.0);
}

/* ------------------------------------------------------------------ linear + layer norm */

typedef struct linctx {
    int n, in, out;
    double *W, *b, *x, *w, *g, *be;
} linctx;

static double lin_loss(void *c)
{
    linctx *k = c;
    double *y = malloc((size_t)k->n * k->out * sizeof *y), L = 0;
    nerf_ref_linear(k->n, k->in, k->out, k->W, k->b, k->x, y);
    for (int i = 0; i < k->n * k->out; i++) L += k->w[i] * y[i];
    free(y);
    return L;
}

static void test_linear(void **s)
{
    (void)s;
    enum { n = 7, in = 5, out = 4 };
    float W[out * in], b[out], x[n * in], w[n * out], y[n * out], dx[n * in], dW[out * in] = {0}, db[out] = {0};
    double Wd[out * in], bd[out], xd[n * in], wd[n * out];
    for (int i = 0; i < out * in; i++) Wd[i] = W[i] = (float)unif(-1, 1);
    for (int i = 0; i < out; i++) bd[i] = b[i] = (float)unif(-1, 1);
    for (int i = 0; i < n * in; i++) xd[i] = x[i] = (float)unif(-1, 1);
    for (int i = 0; i < n * out; i++) wd[i] = w[i] = (float)unif(-1, 1);
    nerf_blas_single_thread();
    nerf_linear_forward(n, in, out, W, b, x, in, y, out);
    nerf_linear_backward(n, in, out, W, x, in, w, out, dx, in, 0, dW, db);
    linctx k = {n, in, out, Wd, bd, xd, wd, NULL, NULL};
    erracc e = {0};
    for (int i = 0; i < out * in; i++) acc(&e, dW[i], central(&Wd[i], lin_loss, &k));
    for (int i = 0; i < out; i++) acc(&e, db[i], central(&bd[i], lin_loss, &k));
    for (int i = 0; i < n * in; i++) acc(&e, dx[i], central(&xd[i], lin_loss, &k));
    printf("linear gradient %.2g\n", relerr(&e));
    assert_true(relerr(&e) < 1e-4);
}

static double ln_loss(void *c)
{
    linctx *k = c;
    double *y = malloc((size_t)k->n * k->in * sizeof *y), L = 0;
    nerf_ref_layernorm(k->n, k->in, k->g, k->be, k->x, y);
    for (int i = 0; i < k->n * k->in; i++) L += k->w[i] * y[i];
    free(y);
    return L;
}

static void test_layernorm(void **s)
{
    (void)s;
    enum { n = 6, C = 8 };
    float g[C], be[C], x[n * C], w[n * C], y[n * C], xh[n * C], rs[n], dx[n * C], dg[C] = {0}, db[C] = {0};
    double gd[C], bd[C], xd[n * C], wd[n * C];
    for (int i = 0; i < C; i++) gd[i] = g[i] = (float)unif(0.5, 1.5), bd[i] = be[i] = (float)unif(-1, 1);
    for (int i = 0; i < n * C; i++) xd[i] = x[i] = (float)unif(-2, 2), wd[i] = w[i] = (float)unif(-1, 1);
    /* one row with a large offset: the two-pass double variance must not cancel */
    for (int c = 0; c < C; c++) xd[C + c] = x[C + c] = (float)(1000.0 + unif(-1, 1));
    nerf_layernorm_forward(n, C, g, be, x, C, y, C, xh, rs);
    nerf_layernorm_backward(n, C, g, xh, rs, w, C, dx, C, 0, dg, db);
    linctx k = {.n = n, .in = C, .x = xd, .w = wd, .g = gd, .be = bd};
    erracc e = {0};
    for (int i = 0; i < C; i++) acc(&e, dg[i], central(&gd[i], ln_loss, &k)), acc(&e, db[i], central(&bd[i], ln_loss, &k));
    for (int i = 0; i < n * C; i++) acc(&e, dx[i], central(&xd[i], ln_loss, &k));
    printf("layernorm gradient %.2g\n", relerr(&e));
    assert_true(relerr(&e) < 1e-4);
}

/* ------------------------------------------------------------------ encodings */

typedef struct encctx {
    int n, K, deg;
    double *x, *w;
} encctx;

static double pe_loss(void *c)
{
    encctx *k = c;
    double L = 0;
    int D = nerf_posenc_dim(3, k->K, 1);
    for (int i = 0; i < k->n; i++) {
        const double *x = k->x + 3 * i, *w = k->w + (size_t)i * D;
        int o = 0;
        for (int d = 0; d < 3; d++) L += w[o++] * x[d];
        for (int q = 0; q < k->K; q++) {
            double f = ldexp(1.0, q);
            for (int d = 0; d < 3; d++) L += w[o + d] * sin(f * x[d]) + w[o + 3 + d] * cos(f * x[d]);
            o += 6;
        }
    }
    return L;
}

static void test_posenc(void **s)
{
    (void)s;
    enum { n = 10, K = 10, D = 3 * (1 + 2 * K) };
    float x[n * 3], w[n * D], y[n * D], dx[n * 3];
    double xd[n * 3], wd[n * D];
    for (int i = 0; i < n * 3; i++) xd[i] = x[i] = (float)unif(-1, 1);
    for (int i = 0; i < n * D; i++) wd[i] = w[i] = (float)unif(-1, 1);
    nerf_posenc_forward(n, 3, K, 1, x, y, D);
    nerf_posenc_backward(n, 3, K, 1, x, w, D, dx, 0);
    encctx k = {n, K, 0, xd, wd};
    erracc e = {0};
    for (int i = 0; i < n * 3; i++) acc(&e, dx[i], central(&xd[i], pe_loss, &k));
    double fe = 0; /* forward against libm at every octave (the kernel uses double-angle recurrences) */
    for (int i = 0; i < n; i++)
        for (int q = 0; q < K; q++)
            for (int d = 0; d < 3; d++) {
                double f = ldexp(1.0, q), xv = x[3 * i + d];
                fe = fmax(fe, fabs(y[i * D + 3 + 6 * q + d] - sin(f * xv)));
                fe = fmax(fe, fabs(y[i * D + 3 + 6 * q + 3 + d] - cos(f * xv)));
            }
    printf("posenc forward max |error| %.2g, gradient %.2g\n", fe, relerr(&e));
    assert_true(fe < 1e-6);
    assert_true(relerr(&e) < 1e-4);
}

static double sh_loss(void *c)
{
    encctx *k = c;
    double L = 0;
    for (int i = 0; i < k->n; i++) {
        double v[16], g[16][3];
        nerf_sh_eval(k->x[3 * i], k->x[3 * i + 1], k->x[3 * i + 2], v, g);
        for (int q = 0; q < k->deg * k->deg; q++) L += k->w[16 * i + q] * v[q];
    }
    return L;
}

static void test_sh(void **s)
{
    (void)s;
    enum { n = 12 };
    float d[n * 3], w[n * 16], y[n * 16], dd[n * 3];
    double ddb[n * 3], wd[n * 16];
    for (int i = 0; i < n; i++) {
        double v[3], nn = 0;
        for (int a = 0; a < 3; a++) v[a] = sci_rng_normal(&RNG_), nn += v[a] * v[a];
        for (int a = 0; a < 3; a++) ddb[3 * i + a] = d[3 * i + a] = (float)(v[a] / sqrt(nn));
    }
    for (int i = 0; i < n * 16; i++) wd[i] = w[i] = (float)unif(-1, 1);
    nerf_sh_forward(n, 4, d, y, 16);
    /* a known value: degree-0 constant, and y = 0 gives zero for the odd-in-y basis 1 */
    assert_float_equal(y[0], 0.28209479177387814f, 1e-7);
    nerf_sh_backward(n, 4, d, w, 16, dd, 0);
    encctx k = {n, 0, 4, ddb, wd};
    erracc e = {0};
    for (int i = 0; i < n * 3; i++) acc(&e, dd[i], central(&ddb[i], sh_loss, &k));
    printf("SH gradient %.2g\n", relerr(&e));
    assert_true(relerr(&e) < 1e-4);
}

/* ------------------------------------------------------------------ hash grid */

typedef struct hgctx {
    const nerf_hashgrid *g;
    int n;
    double *tab, *x, *w;
} hgctx;

static double hg_loss(void *c)
{
    hgctx *k = c;
    int D = nerf_hashgrid_out_dim(k->g);
    double *y = malloc((size_t)k->n * D * sizeof *y), L = 0;
    nerf_ref_hashgrid_forward(k->g, k->tab, k->n, k->x, y);
    for (int i = 0; i < k->n * D; i++) L += k->w[i] * y[i];
    free(y);
    return L;
}

typedef struct hgrun {
    nerf_hashgrid *g;
    size_t np;
    int D;
    float *tab, *dtab;
    double *tabd;
} hgrun;

static void hg_setup(hgrun *r)
{
    nerf_hashgrid_config c = {.n_levels = 6, .n_features = 2, .log2_table = 10, .base_res = 3, .finest_res = 60};
    assert_int_equal(nerf_hashgrid_new(&r->g, &c, NULL), 0);
    r->np = nerf_hashgrid_param_count(r->g), r->D = nerf_hashgrid_out_dim(r->g);
    r->tab = malloc(r->np * sizeof(float)), r->dtab = calloc(r->np, sizeof(float)), r->tabd = malloc(r->np * sizeof(double));
    for (size_t j = 0; j < r->np; j++) r->tabd[j] = r->tab[j] = (float)unif(-1, 1);
    int dense = 0, hashed = 0;
    for (int l = 0; l < 6; l++) {
        int dn;
        nerf_hashgrid_level(r->g, l, NULL, NULL, NULL, &dn);
        dense += dn, hashed += !dn;
    }
    assert_true(dense > 0 && hashed > 0); /* both storage kinds are exercised */
}

static void hg_teardown(hgrun *r)
{
    free(r->tab), free(r->dtab), free(r->tabd);
    nerf_hashgrid_free(r->g);
}

/* Gradient check at points x (n×3); table gradients always, position gradient one-sided (`side`: +1 forward FD
 * from above, 0 central) for coordinates on cell borders. */
static void hg_check(hgrun *r, int n, const double *xs, int side, const char *what)
{
    float *x = malloc(3 * n * sizeof *x), *w = malloc((size_t)n * r->D * sizeof *w), *y = malloc((size_t)n * r->D * sizeof *y);
    float *dx = malloc(3 * n * sizeof *dx);
    double *xd = malloc(3 * n * sizeof *xd), *wd = malloc((size_t)n * r->D * sizeof *wd), *yd = malloc((size_t)n * r->D * sizeof *yd);
    for (int i = 0; i < 3 * n; i++) xd[i] = x[i] = (float)xs[i];
    for (int i = 0; i < n * r->D; i++) wd[i] = w[i] = (float)unif(-1, 1);
    memset(r->dtab, 0, r->np * sizeof(float));
    nerf_hashgrid_forward(r->g, r->tab, n, x, y, r->D);
    nerf_hashgrid_backward(r->g, r->tab, n, x, w, r->D, r->dtab, dx);
    nerf_ref_hashgrid_forward(r->g, r->tabd, n, xd, yd);
    erracc fe = {0}, et = {0}, ex = {0};
    for (int i = 0; i < n * r->D; i++) acc(&fe, y[i], yd[i]);
    hgctx k = {r->g, n, r->tabd, xd, wd};
    for (size_t j = 0; j < r->np; j++)
        if (r->dtab[j] != 0.0f || j % 17 == 0) acc(&et, r->dtab[j], central(&r->tabd[j], hg_loss, &k));
    for (int i = 0; i < 3 * n; i++) {
        double g;
        /* at x = 0 and x = 1 the grid is clamped outside: differentiate inwards */
        int sd = xd[i] == 0.0 ? +1 : (xd[i] == 1.0 ? -1 : side);
        if (sd) {
            double x0 = xd[i], h = 1e-7, l0 = hg_loss(&k);
            xd[i] = x0 + sd * h;
            g = (hg_loss(&k) - l0) / (sd * h);
            xd[i] = x0;
            /* one-sided FD of a piecewise-linear-per-cell function is exact up to the curvature inside the cell */
        } else {
            g = central(&xd[i], hg_loss, &k);
        }
        acc(&ex, dx[i], g);
        assert_true(isfinite(dx[i]));
    }
    printf("hash grid %-22s forward %.2g, table gradient %.2g, position gradient %.2g\n", what, relerr(&fe), relerr(&et),
           relerr(&ex));
    assert_true(relerr(&fe) < 1e-6);
    assert_true(relerr(&et) < 1e-4);
    assert_true(relerr(&ex) < 1e-4);
    free(x), free(w), free(y), free(dx), free(xd), free(wd), free(yd);
}

static void test_hashgrid_random(void **s)
{
    (void)s;
    hgrun r;
    hg_setup(&r);
    enum { n = 20 };
    double x[3 * n];
    for (int i = 0; i < 3 * n; i++) x[i] = unif(0.01, 0.99);
    hg_check(&r, n, x, 0, "random points");
    hg_teardown(&r);
}

/* Coordinates on a cell border of level 0 (p = s·x + 0.5 integral), and exactly 0 and 1. */
static void test_hashgrid_borders(void **s)
{
    (void)s;
    hgrun r;
    hg_setup(&r);
    double scale;
    nerf_hashgrid_level(r.g, 0, &scale, NULL, NULL, NULL);
    enum { n = 6 };
    double x[3 * n];
    for (int i = 0; i < 3 * n; i++) x[i] = (floor(unif(1, scale)) - 0.5) / scale; /* exact border of level 0 */
    for (int i = 0; i < 3 * n; i++) x[i] = (double)(float)x[i];
    /* level-0 border: table gradients exact, position gradient = one-sided derivative from above */
    hg_check(&r, n, x, +1, "level-0 cell borders");
    double e[3 * 4] = {0, 0, 0, 1, 1, 1, 0, 1, 0.37, 1, 0, 0.61}; /* 0.37, 0.61: off every level border */
    hg_check(&r, 4, e, 0, "x = 0 and x = 1");
    hg_teardown(&r);
}

static void test_hashgrid_config_errors(void **s)
{
    (void)s;
    nerf_hashgrid *g = NULL;
    sci_error err = {0};
    nerf_hashgrid_config c = {.n_levels = 0, .n_features = 2, .log2_table = 19, .base_res = 16, .finest_res = 2048};
    assert_int_equal(nerf_hashgrid_new(&g, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "n_levels"));
    c.n_levels = 16, c.finest_res = 8;
    assert_int_equal(nerf_hashgrid_new(&g, &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "finest_res"));
    /* tiny-cuda-nn defaults: level 0 (scale 15) dense with 15 + 2 = 17 vertices per side, 17³ = 4913 → 4920
     * entries (multiple of 8); the finest level hashed with T entries */
    c.finest_res = 2048;
    assert_int_equal(nerf_hashgrid_new(&g, &c, &err), 0);
    size_t e;
    int dense;
    nerf_hashgrid_level(g, 0, NULL, NULL, &e, &dense);
    assert_true(dense);
    assert_int_equal(e, 4920);
    nerf_hashgrid_level(g, 15, NULL, NULL, &e, &dense);
    assert_false(dense);
    assert_int_equal(e, 1u << 19);
    nerf_hashgrid_free(g);
}

/* ------------------------------------------------------------------ attention and block */

typedef struct attctx {
    nerf_i2r_shape s;
    nerf_block_shape bs;
    int P;
    double *in, *w, *par;
} attctx;

static double att_loss(void *c)
{
    attctx *k = c;
    size_t N = (size_t)k->P * k->s.R * k->s.L;
    double *o = malloc(N * k->s.C * sizeof *o), L = 0;
    nerf_ref_i2r_forward(&k->s, k->P, k->in, o);
    for (size_t i = 0; i < N * k->s.C; i++) L += k->w[i] * o[i];
    free(o);
    return L;
}

static void att_check_shape(nerf_i2r_shape sh, int P, double logit_scale, const char *what)
{
    const int N = P * sh.R * sh.L, C = sh.C;
    float *qkv = malloc((size_t)N * 3 * C * 4), *o = malloc((size_t)N * C * 4), *lse = malloc((size_t)N * 2 * sh.heads * 4);
    float *w = malloc((size_t)N * C * 4), *dq = malloc((size_t)N * 3 * C * 4), *scr = malloc(nerf_i2r_scratch_floats(&sh) * 4);
    double *qd = malloc((size_t)N * 3 * C * 8), *wd = malloc((size_t)N * C * 8), *od = malloc((size_t)N * C * 8);
    for (int i = 0; i < N * 3 * C; i++) {
        int ch = i % (3 * C);
        double sc = ch < 2 * C ? logit_scale : 1.0; /* Q and K large → logits of ±scale² scale */
        qd[i] = qkv[i] = (float)(sc * unif(-1, 1));
    }
    for (int i = 0; i < N * C; i++) wd[i] = w[i] = (float)unif(-1, 1);
    nerf_i2r_forward(&sh, P, qkv, 3 * C, o, C, lse, scr);
    nerf_i2r_backward(&sh, P, qkv, 3 * C, o, C, lse, w, C, dq, 3 * C, scr);
    nerf_ref_i2r_forward(&sh, P, qd, od);
    erracc fe = {0}, e = {0};
    for (int i = 0; i < N * C; i++) acc(&fe, o[i], od[i]), assert_true(isfinite(o[i]));
    attctx k = {.s = sh, .P = P, .in = qd, .w = wd};
    if (logit_scale > 10) {
        /* saturated softmax: probabilities are one-hot up to e^-(gap); the exact gradient w.r.t. Q and K is
         * ~0 and V receives it all. FD on V only (Q, K gradients must be finite and tiny). */
        for (int i = 0; i < N * 3 * C; i++) {
            int ch = i % (3 * C);
            assert_true(isfinite(dq[i]));
            if (ch >= 2 * C) acc(&e, dq[i], central(&qd[i], att_loss, &k));
            else assert_true(fabsf(dq[i]) < 1e-3f);
        }
    } else {
        for (int i = 0; i < N * 3 * C; i++) acc(&e, dq[i], central(&qd[i], att_loss, &k));
    }
    printf("attention %-18s forward %.2g, gradient %.2g\n", what, relerr(&fe), relerr(&e));
    assert_true(relerr(&fe) < 1e-5);
    assert_true(relerr(&e) < 1e-4);
    free(qkv), free(o), free(lse), free(w), free(dq), free(scr), free(qd), free(wd), free(od);
}

static void att_check(double logit_scale, const char *what)
{
    att_check_shape((nerf_i2r_shape){.C = 8, .heads = 2, .L = 5, .R = 6}, 2, logit_scale, what);
}

static void test_attention(void **s)
{
    (void)s;
    att_check(1.0, "random");
}

/* Head width d = 8 (the RayFormer default, its own unrolled kernel) and d = 4, with 17 samples per ray so that
 * a group spans two 16-lane blocks, the second padded. */
static void test_attention_wide_heads(void **s)
{
    (void)s;
    att_check_shape((nerf_i2r_shape){.C = 32, .heads = 2, .L = 17, .R = 3}, 1, 1.0, "d = 8, L = 17");
    att_check_shape((nerf_i2r_shape){.C = 16, .heads = 2, .L = 3, .R = 18}, 1, 1.0, "d = 4, R = 18");
    att_check_shape((nerf_i2r_shape){.C = 32, .heads = 2, .L = 17, .R = 3}, 1, 100.0, "d = 8, logits ±1e4");
}

/* How far the reference block's output moves from shape a to shape b (same sizes, a bias changed) on one random
 * input: summed |Δ| over path A's channels (the first C/2, intra-ray) into *dA and over path B's into *dB. */
static void att_path_change(const nerf_i2r_shape *a, const nerf_i2r_shape *b, double *dA, double *dB)
{
    const int N = a->R * a->L, C = a->C;
    double *qkv = malloc((size_t)N * 3 * C * sizeof *qkv), *oa = malloc((size_t)N * C * sizeof *oa),
           *ob = malloc((size_t)N * C * sizeof *ob);
    for (int i = 0; i < N * 3 * C; i++) qkv[i] = unif(-1, 1);
    nerf_ref_i2r_forward(a, 1, qkv, oa);
    nerf_ref_i2r_forward(b, 1, qkv, ob);
    *dA = *dB = 0;
    for (int i = 0; i < N; i++)
        for (int c = 0; c < C; c++) *(c < C / 2 ? dA : dB) += fabs(oa[i * C + c] - ob[i * C + c]);
    free(qkv), free(oa), free(ob);
}

/* The intra-ray distance bias: forward and gradient against the reference with the bias, on a ray of 17 samples
 * (two 16-lane blocks: the second block's lanes must see distances from their own sample index), with d = 4 and
 * d = 8, and a steep slope (logits down to −1600 for the farthest sample: the softmax stays exact and finite). */
static void test_attention_intra_slope(void **s)
{
    (void)s;
    att_check_shape((nerf_i2r_shape){.C = 8, .heads = 2, .L = 5, .R = 6, .intra_slope = 0.7f}, 2, 1.0, "slope 0.7");
    att_check_shape((nerf_i2r_shape){.C = 32, .heads = 2, .L = 17, .R = 3, .intra_slope = 0.7f}, 1, 1.0,
                    "slope 0.7, L = 17");
    att_check_shape((nerf_i2r_shape){.C = 16, .heads = 2, .L = 17, .R = 2, .intra_slope = 100.0f}, 1, 1.0,
                    "slope 100, L = 17");
    /* the bias changes the output (the check above would also pass if both ignored it) */
    nerf_i2r_shape a = {.C = 8, .heads = 2, .L = 5, .R = 2}, b = a;
    b.intra_slope = 2.0f;
    double dA, dB;
    att_path_change(&a, &b, &dA, &dB);
    assert_true(dA > 1e-3); /* path A (intra-ray) moved */
    assert_true(dB == 0.0); /* path B (inter-ray) did not */
}

/* The inter-ray distance bias over pixel offsets: windows 2 wide (R = 6: 2 × 3) and 4 wide (R = 16, one full 16-lane
 * block; R = 32 = 4 × 8: two blocks, the second's lanes at rows 4 … 7), a steep slope, and both biases at once; then
 * the bias moves path B only, and a ray's distances are city-block ones (a 2 × 2 window's diagonal neighbour is
 * 2 away: with only the bias, equal q·k, the weights are e^0 : e^−s : e^−s : e^−2s). */
static void test_attention_inter_slope(void **s)
{
    (void)s;
    att_check_shape((nerf_i2r_shape){.C = 8, .heads = 2, .L = 5, .R = 6, .inter_slope = 0.7f, .win_w = 2}, 2, 1.0,
                    "inter 0.7, 2 x 3");
    att_check_shape((nerf_i2r_shape){.C = 32, .heads = 2, .L = 3, .R = 16, .inter_slope = 0.7f, .win_w = 4}, 1, 1.0,
                    "inter 0.7, 4 x 4");
    att_check_shape((nerf_i2r_shape){.C = 16, .heads = 2, .L = 2, .R = 32, .inter_slope = 100.0f, .win_w = 4}, 1,
                    1.0, "inter 100, 4 x 8");
    att_check_shape((nerf_i2r_shape){.C = 8, .heads = 2, .L = 17, .R = 4, .intra_slope = 1.0f, .inter_slope = 2.0f,
                                     .win_w = 2},
                    1, 1.0, "both, 2 x 2");
    nerf_i2r_shape a = {.C = 4, .heads = 1, .L = 1, .R = 4, .win_w = 2}, b = a;
    b.inter_slope = 1.5f;
    const int C = a.C;
    double dA, dB;
    att_path_change(&a, &b, &dA, &dB);
    assert_true(dA == 0.0);
    assert_true(dB > 1e-3);
    /* q = k = 0 on path B: ray 0's output is the bias-weighted mean of the V's, one-hot V picks each weight */
    float q[4 * 12] = {0}, o[4 * 4], lse[4 * 2], *scr = malloc(nerf_i2r_scratch_floats(&b) * sizeof *scr);
    for (int r = 0; r < 4; r++) q[r * 12 + 2 * C + 2] = (float)r; /* path B's first V channel = the ray's index */
    nerf_i2r_forward(&b, 1, q, 12, o, 4, lse, scr);
    const double e1 = exp(-1.5), e2 = exp(-3.0), z = 1 + 2 * e1 + e2;
    assert_float_equal(o[2], (0 * 1 + 1 * e1 + 2 * e1 + 3 * e2) / z, 1e-6);
    assert_float_equal(o[3 * 4 + 2], (0 * e2 + 1 * e1 + 2 * e1 + 3 * 1) / z, 1e-6);
    free(scr);
}

/* Logits of ±1e4: q, k entries ~±100 give q·k/sqrt(2) up to ~1e4. */
static void test_attention_large_logits(void **s)
{
    (void)s;
    att_check(100.0, "logits ±1e4");
}

/* Ablation switches: a switched-off path passes V through exactly (o = v), its Q and K get no gradient, and the
 * other path is unchanged; each combination passes the gradient check. */
static void test_attention_pass_through(void **s)
{
    (void)s;
    for (int mode = 1; mode <= 3; mode++) {
        nerf_i2r_shape sh = {.C = 8, .heads = 2, .L = 5, .R = 6, .intra_off = mode & 1, .inter_off = mode >> 1};
        const int N = 2 * 30, C = 8;
        float *qkv = malloc((size_t)N * 3 * C * 4), *o = malloc((size_t)N * C * 4), *lse = malloc((size_t)N * 4 * 4);
        float *scr = malloc(nerf_i2r_scratch_floats(&sh) * 4);
        for (int i = 0; i < N * 3 * C; i++) qkv[i] = (float)unif(-1, 1);
        nerf_i2r_forward(&sh, 2, qkv, 3 * C, o, C, lse, scr);
        for (int i = 0; i < N; i++)
            for (int c = 0; c < C; c++)
                if (c < C / 2 ? sh.intra_off : sh.inter_off) assert_true(o[i * C + c] == qkv[i * 3 * C + 2 * C + c]);
        free(qkv), free(o), free(lse), free(scr);
        static const char *const what[] = {"", "intra off", "inter off", "both off"};
        att_check_shape(sh, 2, 1.0, what[mode]);
    }
}

static double block_loss(void *c)
{
    attctx *k = c;
    size_t N = (size_t)k->P * k->s.R * k->s.L;
    double *o = malloc(N * k->s.C * sizeof *o), L = 0;
    nerf_ref_block_forward(&k->bs, k->par, k->P, k->in, o);
    for (size_t i = 0; i < N * k->s.C; i++) L += k->w[i] * o[i];
    free(o);
    return L;
}

static void block_check(nerf_block_shape bs);

/* One block against the double reference: forward, and every parameter and input gradient against central
 * differences; with the inter-ray gate (open at random values, so both its terms carry weight) and without. */
static void test_block(void **s)
{
    (void)s;
    for (int gated = 0; gated <= 1; gated++)
        block_check((nerf_block_shape){.att = {.C = 8, .heads = 2, .L = 4, .R = 4, .inter_slope = 0.5f, .win_w = 2},
                                       .hidden = 12, .inter_gate = gated});
}

static void block_check(nerf_block_shape bs)
{
    const int P = 2, N = P * 16, C = 8;
    size_t np = nerf_block_param_count(&bs);
    float *par = malloc(np * 4), *G = calloc(np, 4), *x = malloc(N * C * 4), *y = malloc(N * C * 4), *w = malloc(N * C * 4);
    float *dx = malloc(N * C * 4), *svm = malloc((size_t)N * nerf_block_saved_floats(&bs) * 4);
    float *scr = malloc(nerf_block_scratch_floats(&bs, 16) * 4);
    double *pd = malloc(np * 8), *xd = malloc(N * C * 8), *wd = malloc(N * C * 8), *yd = malloc(N * C * 8);
    nerf_block_init(&bs, par, 2, &RNG_);
    nerf_block_offsets o = nerf_block_layout(&bs);
    for (int c = 0; c < C; c++) par[o.ln1_g + c] = (float)unif(0.5, 1.5), par[o.ln2_b + c] = (float)unif(-.5, .5);
    for (size_t h = o.gate; h < o.total; h++) par[h] = (float)unif(-0.5, 1.0);
    for (size_t j = 0; j < np; j++) pd[j] = par[j];
    for (int i = 0; i < N * C; i++) xd[i] = x[i] = (float)unif(-1, 1), wd[i] = w[i] = (float)unif(-1, 1);
    nerf_block_saved sv;
    nerf_block_saved_bind(&bs, N, svm, &sv);
    nerf_blas_single_thread();
    for (int p = 0; p < P; p++) nerf_block_forward(&bs, par, 1, (size_t)p * 16, x, y, &sv, scr);
    for (int p = P - 1; p >= 0; p--) nerf_block_backward(&bs, par, 1, (size_t)p * 16, &sv, w, dx, G, scr);
    nerf_ref_block_forward(&bs, pd, P, xd, yd);
    erracc fe = {0}, ep = {0}, ex = {0};
    for (int i = 0; i < N * C; i++) acc(&fe, y[i], yd[i]);
    attctx k = {.s = bs.att, .bs = bs, .P = P, .in = xd, .w = wd, .par = pd};
    for (size_t j = 0; j < np; j++) acc(&ep, G[j], central(&pd[j], block_loss, &k));
    for (int i = 0; i < N * C; i++) acc(&ex, dx[i], central(&xd[i], block_loss, &k));
    printf("block%s: forward %.2g, parameter gradient %.2g, input gradient %.2g\n",
           bs.inter_gate ? " (inter gate)" : "", relerr(&fe), relerr(&ep), relerr(&ex));
    assert_true(relerr(&fe) < 1e-5);
    assert_true(relerr(&ep) < 1e-4);
    assert_true(relerr(&ex) < 1e-4);
    free(par), free(G), free(x), free(y), free(w), free(dx), free(svm), free(scr), free(pd), free(xd), free(wd), free(yd);
}

int main(void)
{
    sci_rng_seed(&RNG_, test_seed(), 3);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_activations),       cmocka_unit_test(test_trunc_exp_clamp),
        cmocka_unit_test(test_linear),            cmocka_unit_test(test_layernorm),
        cmocka_unit_test(test_posenc),            cmocka_unit_test(test_sh),
        cmocka_unit_test(test_hashgrid_random),   cmocka_unit_test(test_hashgrid_borders),
        cmocka_unit_test(test_hashgrid_config_errors), cmocka_unit_test(test_attention),
        cmocka_unit_test(test_attention_large_logits),
        cmocka_unit_test(test_attention_wide_heads),
        cmocka_unit_test(test_attention_intra_slope), cmocka_unit_test(test_attention_inter_slope), cmocka_unit_test(test_attention_pass_through),
        cmocka_unit_test(test_gelu_with_grad), cmocka_unit_test(test_block),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
