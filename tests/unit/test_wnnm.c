/* recon/wnnm and recon/blockmatch: one group's WNNM estimate against a double-precision one-sided Jacobi SVD of
 * the same group (wnnm.m's closed form written out directly, both Gram orientations); block matching against a
 * brute-force search (every member within the window, no candidate left out that is nearer than the farthest
 * member, the key first); the denoiser's PSNR gain on noisy frames of drop40 and on a synthetic video; and the hard
 * cases: flat and all-zero frames, σ far above the data, σ = 0, a frame smaller than the window — finite output,
 * no crash. Random inputs come from a seeded generator whose seed is printed. */
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

#include "base/clock.h"
#include "io/matfile.h"
#include "recon/blockmatch.h"
#include "recon/wnnm.h"
#include "tests/helpers/testdata.h"

#define SEED 20190101u

#include "tests/helpers/sanitized.h"

/* xorshift64*, and Gaussians by Box–Muller: the same numbers on every machine. */
static uint64_t rng_state;
static void rng_seed(uint64_t s) { rng_state = s * 2654435761u + 1; }
static double rng_uniform(void)
{
    rng_state ^= rng_state >> 12, rng_state ^= rng_state << 25, rng_state ^= rng_state >> 27;
    return ((rng_state * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}
static double rng_gauss(void)
{
    double u = rng_uniform(), v = rng_uniform();
    return sqrt(-2 * log(u > 1e-300 ? u : 1e-300)) * cos(2 * M_PI * v);
}

/* --- the reference: wnnm.m on a d × n group, in double, SVD by one-sided Jacobi --------------------------- */

/* One-sided Jacobi on the r × c column-major matrix a (overwritten with A·V, orthogonal columns); v: c × c. */
static void jacobi_svd(double *a, int r, int c, double *v)
{
    for (int i = 0; i < c * c; i++)
        v[i] = i % (c + 1) == 0;
    for (int sweep = 0; sweep < 60; sweep++) {
        double off = 0;
        for (int p = 0; p < c - 1; p++)
            for (int q = p + 1; q < c; q++) {
                double al = 0, be = 0, ga = 0;
                for (int i = 0; i < r; i++) {
                    al += a[p * r + i] * a[p * r + i];
                    be += a[q * r + i] * a[q * r + i];
                    ga += a[p * r + i] * a[q * r + i];
                }
                if (fabs(ga) <= 1e-300 || fabs(ga) <= 1e-15 * sqrt(al * be))
                    continue;
                off = fmax(off, fabs(ga) / sqrt(al * be));
                const double zeta = (be - al) / (2 * ga);
                const double t = (zeta >= 0 ? 1 : -1) / (fabs(zeta) + sqrt(1 + zeta * zeta));
                const double cs = 1 / sqrt(1 + t * t), sn = cs * t;
                for (int i = 0; i < r; i++) {
                    const double x = a[p * r + i], y = a[q * r + i];
                    a[p * r + i] = cs * x - sn * y, a[q * r + i] = sn * x + cs * y;
                }
                for (int i = 0; i < c; i++) {
                    const double x = v[p * c + i], y = v[q * c + i];
                    v[p * c + i] = cs * x - sn * y, v[q * c + i] = sn * x + cs * y;
                }
            }
        if (off < 1e-14)
            break;
    }
}

/* The WNNM estimate of group y (d × n), as vpatchestimate.m and wnnm.m compute it; returns the rank kept. */
static int wnnm_reference(const float *y, int d, int n, double c, double sigma, double *x)
{
    double *mean = calloc((size_t)d, sizeof *mean), *b = malloc((size_t)d * n * sizeof *b);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < d; i++)
            mean[i] += y[j * d + i] / (double)n;
    /* b = (Y − Ȳ)ᵀ: n × d, so the Jacobi rotates d columns of length n (any orientation gives the same SVD) */
    for (int j = 0; j < n; j++)
        for (int i = 0; i < d; i++)
            b[i * n + j] = y[j * d + i] - mean[i];
    double *v = malloc((size_t)d * d * sizeof *v);
    jacobi_svd(b, n, d, v);
    const double c0 = c * sqrt((double)n) * 2 * sigma * sigma, eps = 2.220446049250313e-16;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < d; i++)
            x[j * d + i] = mean[i];
    int kept = 0;
    for (int k = 0; k < d; k++) {
        /* b's column k = s_k · u_k (u_k: n-vector), v's column k = the d-vector; Y − Ȳ = Σ s_k v_k u_kᵀ */
        double s = 0;
        for (int j = 0; j < n; j++)
            s += b[k * n + j] * b[k * n + j];
        s = sqrt(s);
        const double delta = (s + eps) * (s + eps) - 4 * c0;
        if (!(delta > 0))
            continue;
        const double sh = fmax((s - eps + sqrt(delta)) / 2, 0);
        if (!(s > 0) || !(sh > 0))
            continue;
        kept++;
        for (int j = 0; j < n; j++)
            for (int i = 0; i < d; i++)
                x[j * d + i] += sh / s * v[k * d + i] * b[k * n + j];
    }
    free(mean);
    free(b);
    free(v);
    return kept;
}

/* A group of n noisy copies of a few patterns (rank r) plus an offset: what block matching hands WNNM. */
static void make_group(float *y, int d, int n, int r, double noise)
{
    double *basis = malloc((size_t)d * r * sizeof *basis), coef[16];
    for (int i = 0; i < d * r; i++)
        basis[i] = rng_gauss() * 0.2;
    for (int j = 0; j < n; j++) {
        for (int k = 0; k < r; k++)
            coef[k] = rng_gauss();
        for (int i = 0; i < d; i++) {
            double v = 0.5 + noise * rng_gauss();
            for (int k = 0; k < r; k++)
                v += basis[k * d + i] * coef[k];
            y[j * d + i] = (float)v;
        }
    }
    free(basis);
}

static void test_group_against_svd(void **state)
{
    (void)state;
    printf("seed %u\n", SEED);
    rng_seed(SEED);
    /* the DeSCI sizes (p², n) of each σ band, and a group with fewer patches than pixels (the other Gram side);
     * noise at σ keeps many singular values (all found at once), noise at σ/4 only the rank-4 signal's (found one by
     * one: the two routes of the eigensolver) */
    static const struct { int d, n; double sigma, noise; } cases[] = {
        {36, 70, 6 / 255.0, 1},    {36, 70, 12 / 255.0, 1},   {49, 90, 25 / 255.0, 1},   {64, 120, 50 / 255.0, 1},
        {81, 140, 100 / 255.0, 1}, {49, 20, 12 / 255.0, 1},   {36, 70, 0.0, 1},          {36, 70, 12 / 255.0, 0.25},
        {49, 90, 25 / 255.0, 0.25}, {81, 140, 100 / 255.0, 0.25}, {49, 20, 12 / 255.0, 0.25}};
    sci_wnnm_ws *ws = NULL;
    assert_int_equal(sci_wnnm_ws_new(&ws, 81, 140, NULL), 0);
    for (size_t t = 0; t < sizeof cases / sizeof cases[0]; t++) {
        const int d = cases[t].d, n = cases[t].n;
        float *y = malloc((size_t)d * n * sizeof *y), *x = malloc((size_t)d * n * sizeof *x);
        double *ref = malloc((size_t)d * n * sizeof *ref);
        make_group(y, d, n, 4, cases[t].sigma * cases[t].noise);
        const int kref = wnnm_reference(y, d, n, sqrt(2.0), cases[t].sigma, ref);
        const int k = sci_wnnm_group(ws, y, d, n, sqrt(2.0), cases[t].sigma, x);
        double err = 0, scale = 0, moved = 0;
        for (int i = 0; i < d * n; i++) {
            err = fmax(err, fabs(x[i] - ref[i]));
            scale = fmax(scale, fabs(ref[i]));
            moved = fmax(moved, fabs(ref[i] - y[i]));
        }
        printf("  d %2d n %3d sigma %5.1f/255, noise x%.2f: rank kept %2d (reference %2d), max |x - ref| %.2e of %.2f "
               "(the estimate moved the group by up to %.3f)\n",
               d, n, cases[t].sigma * 255, cases[t].noise, k, kref, err, scale, moved);
        /* σ = 0 keeps every nonzero singular value: the reference's double SVD resolves ones that the float Gram
         * matrix cannot (below √ε_float of the largest), which changes the count but not the estimate */
        if (cases[t].sigma > 0)
            assert_int_equal(k, kref);
        assert_true(err < 2e-4 * scale);
        if (cases[t].sigma > 0)
            assert_true(moved > 100 * err); /* the comparison is not trivially the identity */
        else
            assert_true(moved < 2e-4 * scale); /* σ = 0 keeps every singular value: the group itself */
        /* in place */
        memcpy(x, y, (size_t)d * n * sizeof *x);
        assert_int_equal(sci_wnnm_group(ws, x, d, n, sqrt(2.0), cases[t].sigma, x), k);
        free(y);
        free(x);
        free(ref);
    }
    sci_wnnm_ws_free(ws);
}

/* Flat, zero and far-too-noisy groups: the mean patch comes back, no NaN. */
static void test_group_hard_cases(void **state)
{
    (void)state;
    const int d = 36, n = 70;
    sci_wnnm_ws *ws = NULL;
    assert_int_equal(sci_wnnm_ws_new(&ws, d, n, NULL), 0);
    float y[36 * 70], x[36 * 70];
    for (int i = 0; i < d * n; i++)
        y[i] = 0.25f;
    assert_int_equal(sci_wnnm_group(ws, y, d, n, sqrt(2.0), 25 / 255.0, x), 0);
    for (int i = 0; i < d * n; i++)
        assert_true(x[i] == 0.25f);
    assert_int_equal(sci_wnnm_group(ws, y, d, n, sqrt(2.0), 0.0, x), 0); /* zero variance and σ = 0 */
    for (int i = 0; i < d * n; i++)
        assert_true(x[i] == 0.25f);
    memset(y, 0, sizeof y);
    assert_int_equal(sci_wnnm_group(ws, y, d, n, sqrt(2.0), 0.0, x), 0);
    for (int i = 0; i < d * n; i++)
        assert_true(x[i] == 0.0f);
    rng_seed(SEED + 1);
    make_group(y, d, n, 3, 0.05);
    assert_int_equal(sci_wnnm_group(ws, y, d, n, sqrt(2.0), 1e3, x), 0); /* σ far above the data: the mean */
    double mean0 = 0;
    for (int j = 0; j < n; j++)
        mean0 += y[j * d] / (double)n;
    for (int j = 0; j < n; j++)
        assert_true(fabs(x[j * d] - mean0) < 1e-5);
    sci_wnnm_ws_free(ws);
}

/* --- block matching against brute force ------------------------------------------------------------------ */

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void test_blockmatch_bruteforce(void **state)
{
    (void)state;
    const int w = 29, h = 23, n = 3;
    const sci_blockmatch_params bp = {.patch = 5, .group = 12, .step = 2, .window = 6};
    rng_seed(SEED + 2);
    float *v = malloc((size_t)w * h * n * sizeof *v);
    for (int i = 0; i < w * h * n; i++)
        v[i] = (float)rng_uniform();
    /* a few exact repeats, so that ties at distance 0 besides the key exist */
    for (int r = 0; r < 5; r++)
        for (int c = 0; c < 5; c++)
            v[(size_t)2 * w * h + (3 + r) * w + 4 + c] = v[(size_t)(3 + r) * w + 4 + c];
    sci_blockmatch *bm = NULL;
    assert_int_equal(sci_blockmatch_new(&bm, w, h, n, &bp, NULL), 0);
    assert_int_equal(sci_blockmatch_run(bm, v, 2, NULL), 0);
    const int keys = sci_blockmatch_keys(bm), k = sci_blockmatch_group_size(bm), p = bp.patch;
    const int rows = h - p + 1, cols = w - p + 1;
    /* grid 0, 2, …, plus the residual positions: rows 0..18 → 10, cols 0..24 → 13 */
    assert_int_equal(keys, n * 10 * 13);
    assert_int_equal(k, 12);
    double *all = malloc((size_t)n * rows * cols * sizeof *all);
    int checked = 0;
    for (int g = 0; g < keys; g++) {
        const uint32_t key = sci_blockmatch_key(bm, g);
        const uint32_t *m = sci_blockmatch_group(bm, g);
        const float *dist = sci_blockmatch_distances(bm, g);
        const int kx = (int)(key % w), ky = (int)(key / w % h);
        assert_int_equal(m[0], key);
        assert_true(dist[0] == 0.0f);
        int na = 0;
        for (int f = 0; f < n; f++)
            for (int y = ky - bp.window; y <= ky + bp.window; y++)
                for (int x = kx - bp.window; x <= kx + bp.window; x++) {
                    if (y < 0 || x < 0 || y >= rows || x >= cols)
                        continue;
                    double s = 0;
                    for (int r = 0; r < p; r++)
                        for (int c = 0; c < p; c++) {
                            const double dd = (double)v[key + r * w + c] - v[(size_t)f * w * h + (y + r) * w + x + c];
                            s += dd * dd;
                        }
                    all[na++] = s;
                }
        qsort(all, (size_t)na, sizeof *all, cmp_double);
        const double kth = all[k - 1];
        for (int i = 0; i < k; i++) {
            const int f = (int)(m[i] / (w * h)), y = (int)(m[i] / w % h), x = (int)(m[i] % w);
            assert_true(abs(y - ky) <= bp.window && abs(x - kx) <= bp.window && y < rows && x < cols);
            for (int j = 0; j < i; j++)
                assert_true(m[j] != m[i]);
            double s = 0;
            for (int r = 0; r < p; r++)
                for (int c = 0; c < p; c++) {
                    const double dd = (double)v[key + r * w + c] - v[(size_t)f * w * h + (y + r) * w + x + c];
                    s += dd * dd;
                }
            assert_true(fabs(s - dist[i]) <= 1e-5 * (1 + s));
            assert_true(s <= kth + 1e-5 * (1 + kth)); /* nothing nearer was left out */
        }
        checked++;
    }
    printf("blockmatch: %d groups of %d checked against brute force\n", checked, k);
    /* a window larger than the frame: the group is clamped to the candidates */
    sci_blockmatch_free(bm);
    const sci_blockmatch_params big = {.patch = 5, .group = 5000, .step = 3, .window = 40};
    assert_int_equal(sci_blockmatch_new(&bm, w, h, n, &big, NULL), 0);
    assert_int_equal(sci_blockmatch_group_size(bm), n * rows * cols);
    assert_int_equal(sci_blockmatch_run(bm, v, 0, NULL), 0);
    sci_blockmatch_free(bm);
    /* refusals */
    sci_error err = {0};
    const sci_blockmatch_params huge = {.patch = 30, .group = 10, .step = 1, .window = 3};
    assert_int_equal(sci_blockmatch_new(&bm, w, h, n, &huge, &err), -EINVAL);
    printf("  %s\n", err.msg);
    assert_null(bm);
    free(all);
    free(v);
}

/* --- the denoiser ---------------------------------------------------------------------------------------- */

static double psnr1(const float *x, const float *ref, size_t count)
{
    double se = 0;
    for (size_t i = 0; i < count; i++)
        se += ((double)x[i] - ref[i]) * ((double)x[i] - ref[i]);
    return 10 * log10(1.0 / (se / count));
}

static double denoise_gain(const char *what, const float *clean, int w, int h, int n, double sigma255,
                           double *out_psnr)
{
    const size_t count = (size_t)w * h * n;
    float *noisy = malloc(count * sizeof *noisy), *den = malloc(count * sizeof *den);
    for (size_t i = 0; i < count; i++)
        noisy[i] = clean[i] + (float)(sigma255 / 255 * rng_gauss());
    sci_wnnm_params q;
    sci_wnnm_params_for_sigma(&q, sigma255);
    sci_wnnm *wn = NULL;
    sci_error err = {0};
    if (sci_wnnm_new(&wn, w, h, n, &q, 2, &err) < 0)
        fail_msg("%s", err.msg);
    const int64_t t0 = sci_clock_mono_ns();
    assert_int_equal(sci_wnnm_match(wn, noisy, NULL), 0);
    const int64_t t1 = sci_clock_mono_ns();
    assert_int_equal(sci_wnnm_denoise(wn, noisy, sigma255 / 255, den, NULL), 0);
    const int64_t t2 = sci_clock_mono_ns();
    const double pn = psnr1(noisy, clean, count), pd = psnr1(den, clean, count);
    for (size_t i = 0; i < count; i++)
        assert_true(isfinite(den[i]));
    printf("  %s %dx%dx%d, sigma %g/255 (patch %d, %d patches, step %d): noisy %.2f dB -> denoised %.2f dB "
           "(+%.2f); match %.2f s, denoise %.2f s at 2 threads\n",
           what, w, h, n, sigma255, q.patch, q.group, q.step, pn, pd, pd - pn, (t1 - t0) * 1e-9, (t2 - t1) * 1e-9);
    sci_wnnm_free(wn);
    free(noisy);
    free(den);
    if (out_psnr)
        *out_psnr = pd;
    return pd - pn;
}

/* The truth frames of drop40's first snapshot, cropped to cw × ch from (x0, y0). */
static float *drop_crop(int x0, int y0, int cw, int ch, int *n)
{
    int k = 0;
    sci_problem **p = testdata_read_mat("drop40_cacti.mat", &k);
    const sci_cube *t = p[0]->truth;
    *n = t->n;
    float *c = malloc((size_t)cw * ch * t->n * sizeof *c);
    for (int f = 0; f < t->n; f++)
        for (int y = 0; y < ch; y++)
            memcpy(c + ((size_t)f * ch + y) * cw, sci_cube_frame(t, f) + (size_t)(y0 + y) * t->w + x0,
                   (size_t)cw * sizeof *c);
    sci_problem_array_free(p, k);
    return c;
}

static void test_denoise_gain(void **state)
{
    (void)state;
    rng_seed(SEED + 3);
    int n = 0;
    /* AddressSanitizer (about 10× slower): a 48×48 crop and a weaker bound, said when it runs */
    const int cs = SANITIZED ? 48 : 96;
    const double lo25 = SANITIZED ? 3 : 5.5, lo50 = SANITIZED ? 3 : 4.5;
    if (SANITIZED)
        printf("  (AddressSanitizer build: a 48x48 crop, gains checked against 3 dB)\n");
    float *drop = drop_crop(64, 64, cs, cs, &n);
    /* measured: +6.22 dB at σ 25, +5.41 at σ 50, +7.38 on the synthetic video at σ 12: one pass, as DeSCI runs it
     * inside GAP, is a mild denoiser (the closed form keeps at least half of every singular value above its
     * threshold, and noise singular values up to σ(√n + √d) pass a threshold of 2σ√(2c√n)) */
    assert_true(denoise_gain("drop40 truth", drop, cs, cs, n, 25, NULL) > lo25);
    assert_true(denoise_gain("drop40 truth", drop, cs, cs, n, 50, NULL) > lo50);
    free(drop);
    /* a synthetic video: a bright disc moving over a gradient */
    const int w = 64, h = 48, fn = 4;
    float *v = malloc((size_t)w * h * fn * sizeof *v);
    for (int f = 0; f < fn; f++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const double dx = x - 20 - 4 * f, dy = y - 24;
                v[((size_t)f * h + y) * w + x] = (float)(0.2 + 0.4 * x / w + (dx * dx + dy * dy < 100 ? 0.3 : 0));
            }
    assert_true(denoise_gain("synthetic", v, w, h, fn, 12, NULL) > 6.5);
    free(v);
}

/* Hard cases through the whole denoiser: flat frames, all-zero frames, σ far above the data, σ = 0, frames barely
 * larger than a patch; the output is finite and where the answer is known, it is that answer. */
static void test_denoise_hard_cases(void **state)
{
    (void)state;
    const int w = 40, h = 36, n = 3;
    const size_t count = (size_t)w * h * n;
    float *x = malloc(count * sizeof *x), *y = malloc(count * sizeof *y);
    sci_wnnm_params q;
    sci_wnnm_params_for_sigma(&q, 100);
    sci_wnnm *wn = NULL;
    assert_int_equal(sci_wnnm_new(&wn, w, h, n, &q, 2, NULL), 0);
    for (size_t i = 0; i < count; i++)
        x[i] = 0.375f;
    assert_int_equal(sci_wnnm_denoise(wn, x, 100 / 255.0, y, NULL), 0); /* matches on first use */
    for (size_t i = 0; i < count; i++)
        assert_true(fabsf(y[i] - 0.375f) < 1e-6f);
    memset(x, 0, count * sizeof *x);
    assert_int_equal(sci_wnnm_match(wn, x, NULL), 0);
    assert_int_equal(sci_wnnm_denoise(wn, x, 0.0, y, NULL), 0);
    for (size_t i = 0; i < count; i++)
        assert_true(y[i] == 0.0f);
    rng_seed(SEED + 4);
    for (size_t i = 0; i < count; i++)
        x[i] = (float)rng_uniform();
    assert_int_equal(sci_wnnm_match(wn, x, NULL), 0);
    assert_int_equal(sci_wnnm_denoise(wn, x, 1e4, y, NULL), 0); /* every group becomes its mean patch */
    double lo = 1, hi = 0;
    for (size_t i = 0; i < count; i++) {
        assert_true(isfinite(y[i]));
        lo = fmin(lo, y[i]), hi = fmax(hi, y[i]);
    }
    assert_true(lo >= 0 && hi <= 1);
    assert_int_equal(sci_wnnm_denoise(wn, x, 0.0, y, NULL), 0); /* σ = 0: every group kept whole */
    for (size_t i = 0; i < count; i++)
        assert_true(fabsf(y[i] - x[i]) < 1e-4f);
    /* in place, and canceled before it starts: untouched */
    atomic_int cancel = 1;
    memcpy(y, x, count * sizeof *y);
    assert_int_equal(sci_wnnm_denoise(wn, y, 0.1, y, &cancel), SCI_ECANCELED);
    assert_memory_equal(x, y, count * sizeof *y);
    sci_wnnm_free(wn);
    /* frames just one patch wide: one position each way, the group clamped to the n candidates */
    sci_wnnm_params tiny = q;
    assert_int_equal(sci_wnnm_new(&wn, 9, 9, n, &tiny, 1, NULL), 0);
    assert_int_equal(sci_wnnm_params_of(wn).group, n);
    assert_int_equal(sci_wnnm_denoise(wn, x, 0.05, y, NULL), 0);
    for (int i = 0; i < 9 * 9 * n; i++)
        assert_true(isfinite(y[i]));
    sci_wnnm_free(wn);
    sci_error err = {0};
    assert_int_equal(sci_wnnm_new(&wn, 8, 8, n, &tiny, 1, &err), -EINVAL);
    printf("  %s\n", err.msg);
    tiny.c = 0;
    assert_int_equal(sci_wnnm_new(&wn, 40, 40, n, &tiny, 1, &err), -EINVAL);
    printf("  %s\n", err.msg);
    free(x);
    free(y);
}

/* vparaconfig.m's table. */
static void test_params_for_sigma(void **state)
{
    (void)state;
    static const struct { double s; int p, n, step; } t[] = {{6, 6, 70, 2},    {12, 6, 70, 2},  {20, 6, 70, 2},
                                                             {20.5, 7, 90, 2}, {25, 7, 90, 2},  {40, 7, 90, 2},
                                                             {50, 8, 120, 3},  {60, 8, 120, 3}, {61, 9, 140, 3},
                                                             {100, 9, 140, 3}};
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++) {
        sci_wnnm_params q;
        sci_wnnm_params_for_sigma(&q, t[i].s);
        assert_int_equal(q.patch, t[i].p);
        assert_int_equal(q.group, t[i].n);
        assert_int_equal(q.step, t[i].step);
        assert_int_equal(q.window, 30);
        assert_true(fabs(q.c - sqrt(2.0)) < 1e-15);
    }
    assert_int_equal(sci_wnnm_step_for_patch(3), 1);
    assert_int_equal(sci_wnnm_step_for_patch(12), 5);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_params_for_sigma),
        cmocka_unit_test(test_group_against_svd),
        cmocka_unit_test(test_group_hard_cases),
        cmocka_unit_test(test_blockmatch_bruteforce),
        cmocka_unit_test(test_denoise_hard_cases),
        cmocka_unit_test(test_denoise_gain),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
