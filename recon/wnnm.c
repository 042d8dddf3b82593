/* recon/wnnm.c — the WNNM video denoiser (see wnnm.h). */
#include "recon/wnnm.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "recon/blockmatch.h"

/* LAPACK's ssterf (every eigenvalue of a symmetric tridiagonal matrix, root-free QR) and sstein (eigenvectors of
 * given eigenvalues, inverse iteration), from OpenBLAS's bundled LAPACK: Debian ships no LAPACKE header with
 * libopenblas-dev, and the Fortran symbols are all that is needed. The rest of the eigensolver is ours (below):
 * LAPACK's ssytrd is level-2 BLAS calls, which at these sizes cost more in call overhead than in arithmetic (160 us
 * for 81 × 81 here against about 40), and ssyevr's bisection (sstebz) was the slowest step of all. Which
 * eigenvalues lie above the threshold a Sturm count says (usually a few, often none); bisection on eight shifts at
 * a time finds them when they are few, ssterf when they are many (27 us at m = 36 in this OpenBLAS). */
extern void ssterf_(const int *n, float *d, float *e, int *info);
extern void sstein_(const int *n, const float *d, const float *e, const int *m, const float *w, const int *iblock,
                    const int *isplit, float *z, const int *ldz, float *work, int *iwork, int *ifail, int *info);

/* clang before 16 exports a target_clones function as NAME.ifunc, which other files' calls do not link to
 * (the fuzzers are built with clang): a single version there */
#if defined(__clang__) && __clang_major__ < 16
#define CLONES
#else
#define CLONES __attribute__((target_clones("avx2", "default")))
#endif

/* MATLAB's eps (wnnm.m adds it to the singular values): double precision's, so it only tells exact zeros apart. */
#define WNNM_EPS DBL_EPSILON

void sci_wnnm_params_for_sigma(sci_wnnm_params *p, double sigma255)
{
    /* vparaconfig.m: larger noise, larger patches and groups */
    static const struct { double upto; int patch, group; } rows[] = {
        {20, 6, 70}, {40, 7, 90}, {60, 8, 120}, {INFINITY, 9, 140}};
    int i = 0;
    while (!(sigma255 <= rows[i].upto) && i < 3)
        i++;
    p->patch = rows[i].patch;
    p->group = rows[i].group;
    p->step = sci_wnnm_step_for_patch(p->patch);
    p->window = 30;
    p->c = sqrt(2.0);
}

int sci_wnnm_step_for_patch(int patch)
{
    const int s = (int)floor(patch / 2.0 - 1.0);
    return s < 1 ? 1 : s;
}

/* --- one group -------------------------------------------------------------------------------------------- */

/* 8 floats: one AVX2 register, two SSE ones in the baseline clone (a macro loads it, so that no function passes or
 * returns one: gcc would warn about the ABI of the baseline clone) */
typedef float v8 __attribute__((vector_size(32)));
#define V8_LOAD(v, p) memcpy(&(v), (p), sizeof(v8))

/* Rows of a group in memory: d rounded up to 8 floats, the padding zero, so that the Gram kernel runs whole
 * vectors. */
static int padded(int d) { return (d + 7) & ~7; }

struct sci_wnnm_ws {
    int d_max, n_max, m_max; /* m: the Gram matrix's side, min(d, n) */
    float *yc;               /* padded(d) × n, the deviations from the mean patch (padding zero) */
    double *mean;            /* d */
    float *g;                /* padded(m)²: the Gram matrix, then the Householder vectors of its reduction */
    float *tau, *diag, *off; /* m each: reflector factors, the tridiagonal matrix */
    float *ev, *u;           /* the eigenvalues kept (m) and their vectors (m × m) */
    double *r;               /* m: ŝ/s of each kept value */
    float *t, *p, *w;        /* d: one product; m each: reduction scratch */
    float *work;             /* sstein: 5m */
    int *iblock, *isplit, *iwork, *ifail; /* sstein: m each */
    double *off2, *lo, *hi;  /* m each: squared off-diagonal; brackets of the eigenvalues sought */
};

void sci_wnnm_ws_free(sci_wnnm_ws *ws)
{
    if (!ws)
        return;
    free(ws->yc);
    free(ws->mean);
    free(ws->g);
    free(ws->tau);
    free(ws->diag);
    free(ws->off);
    free(ws->ev);
    free(ws->u);
    free(ws->r);
    free(ws->t);
    free(ws->p);
    free(ws->w);
    free(ws->work);
    free(ws->iblock);
    free(ws->isplit);
    free(ws->iwork);
    free(ws->ifail);
    free(ws->off2);
    free(ws->lo);
    free(ws->hi);
    free(ws);
}

int sci_wnnm_ws_new(sci_wnnm_ws **out, int d_max, int n_max, sci_error *err)
{
    *out = NULL;
    if (d_max < 1 || n_max < 1 || d_max > 65536 || n_max > 65536 || (double)d_max * n_max > 1e8)
        return sci_error_set(err, -EINVAL, "wnnm: groups of %d pixels x %d patches", d_max, n_max);
    sci_wnnm_ws *ws = calloc(1, sizeof *ws);
    if (!ws)
        return sci_error_set(err, -ENOMEM, "wnnm: out of memory");
    const int m = d_max < n_max ? d_max : n_max, mp = padded(m);
    ws->d_max = d_max, ws->n_max = n_max, ws->m_max = m;
    const size_t mm = (size_t)m * m;
    ws->yc = calloc((size_t)padded(d_max) * n_max, sizeof *ws->yc);
    ws->mean = malloc((size_t)d_max * sizeof *ws->mean);
    ws->g = malloc((size_t)mp * mp * sizeof *ws->g);
    ws->tau = malloc((size_t)m * sizeof *ws->tau);
    ws->diag = malloc((size_t)m * sizeof *ws->diag);
    ws->off = malloc((size_t)m * sizeof *ws->off);
    ws->ev = malloc((size_t)m * sizeof *ws->ev);
    ws->u = malloc(mm * sizeof *ws->u);
    ws->r = malloc((size_t)m * sizeof *ws->r);
    ws->t = malloc((size_t)d_max * sizeof *ws->t);
    ws->p = malloc((size_t)m * sizeof *ws->p);
    ws->w = malloc((size_t)m * sizeof *ws->w);
    ws->work = malloc(5 * (size_t)m * sizeof *ws->work);
    ws->iblock = malloc((size_t)m * sizeof *ws->iblock);
    ws->isplit = malloc((size_t)m * sizeof *ws->isplit);
    ws->iwork = malloc((size_t)m * sizeof *ws->iwork);
    ws->ifail = malloc((size_t)m * sizeof *ws->ifail);
    ws->off2 = malloc((size_t)m * sizeof *ws->off2);
    ws->lo = malloc((size_t)m * sizeof *ws->lo);
    ws->hi = malloc((size_t)m * sizeof *ws->hi);
    if (!ws->yc || !ws->mean || !ws->g || !ws->tau || !ws->diag || !ws->off || !ws->ev || !ws->u ||
        !ws->r || !ws->t || !ws->p || !ws->w || !ws->work || !ws->iblock || !ws->isplit || !ws->iwork ||
        !ws->ifail || !ws->off2 || !ws->lo || !ws->hi) {
        sci_wnnm_ws_free(ws);
        return sci_error_set(err, -ENOMEM, "wnnm: out of memory");
    }
    *out = ws;
    return 0;
}

/* g (d × d, row stride ld, lower triangle and diagonal) = Σ_t y_t y_tᵀ over the n columns of yc (stride ld, a
 * multiple of 8, padding rows zero): 4 × 8 register blocks accumulated over t, whole vectors thanks to the
 * padding. */
CLONES static void gram_rows(const float *restrict yc, int ld, int d, int n, float *restrict g)
{
    for (int i0 = 0; i0 < d; i0 += 4)
        for (int j0 = 0; j0 <= i0 + 3 && j0 < d; j0 += 8) {
            v8 acc0 = {0}, acc1 = {0}, acc2 = {0}, acc3 = {0};
            const int i1 = i0 + 1 < ld ? i0 + 1 : i0, i2 = i0 + 2 < ld ? i0 + 2 : i0, i3 = i0 + 3 < ld ? i0 + 3 : i0;
            for (int t = 0; t < n; t++) {
                const float *y = yc + (size_t)t * ld;
                v8 b;
                V8_LOAD(b, y + j0);
                acc0 += y[i0] * b;
                acc1 += y[i1] * b;
                acc2 += y[i2] * b;
                acc3 += y[i3] * b;
            }
            float out[4][8];
            memcpy(out[0], &acc0, sizeof acc0);
            memcpy(out[1], &acc1, sizeof acc1);
            memcpy(out[2], &acc2, sizeof acc2);
            memcpy(out[3], &acc3, sizeof acc3);
            for (int a = 0; a < 4 && i0 + a < d; a++)
                for (int b = 0; b < 8 && j0 + b <= i0 + a; b++)
                    g[(size_t)(i0 + a) * ld + j0 + b] = out[a][b];
        }
}

/* g (n × n, stride ld, lower) = the column dot products of yc, for groups of fewer patches than pixels. */
static void gram_cols(const float *restrict yc, int ldy, int d, int n, int ld, float *restrict g)
{
    for (int s = 0; s < n; s++)
        for (int t = 0; t <= s; t++) {
            const float *a = yc + (size_t)s * ldy, *b = yc + (size_t)t * ldy;
            float acc = 0;
#pragma omp simd reduction(+ : acc)
            for (int i = 0; i < d; i++)
                acc += a[i] * b[i];
            g[(size_t)s * ld + t] = acc;
        }
}

/* Householder reduction of the symmetric m × m matrix a (row stride ld; the lower triangle is read, the full
 * matrix used as scratch) to tridiagonal diag/off, as LAPACK's ssytd2 but with full-storage updates, which
 * vectorise: a = Q T Qᵀ, Q = H_0 … H_{m−3}, H_k = I − tau_k v_k v_kᵀ acting on indices k+1 …, v_k kept in row k
 * of a from column k+1 on (its first element 1 implied). p, w: m floats of scratch. */
CLONES static void tridiagonalize(float *restrict a, int m, int ld, float *restrict diag, float *restrict off,
                                  float *restrict tau, float *restrict p, float *restrict w)
{
    for (int i = 0; i < m; i++)
        for (int j = 0; j < i; j++)
            a[(size_t)j * ld + i] = a[(size_t)i * ld + j];
    for (int k = 0; k + 2 < m; k++) {
        float *x = a + (size_t)k * ld + k + 1; /* row k right of the diagonal = column k below it */
        const int len = m - k - 1;
        double xn = 0;
        for (int i = 1; i < len; i++)
            xn += (double)x[i] * x[i];
        const double alpha = x[0];
        diag[k] = a[(size_t)k * ld + k];
        if (xn == 0) { /* already reduced: H = I */
            tau[k] = 0;
            off[k] = (float)alpha;
            continue;
        }
        const double beta = -copysign(sqrt(alpha * alpha + xn), alpha);
        const float tk = (float)((beta - alpha) / beta), scale = (float)(1.0 / (alpha - beta));
        x[0] = 1;
        for (int i = 1; i < len; i++)
            x[i] *= scale;
        tau[k] = tk, off[k] = (float)beta;
        /* a22 ← H a22 H: p = τ a22 v, w = p − (τ/2)(pᵀv) v, a22 −= v wᵀ + w vᵀ */
        float *a22 = a + (size_t)(k + 1) * ld + k + 1;
        for (int i = 0; i < len; i++)
            p[i] = 0;
        for (int j = 0; j < len; j++) {
            const float vj = tk * x[j];
            const float *row = a22 + (size_t)j * ld;
            for (int i = 0; i < len; i++)
                p[i] += vj * row[i];
        }
        float pv = 0;
        for (int i = 0; i < len; i++)
            pv += p[i] * x[i];
        const float kk = 0.5f * tk * pv;
        for (int i = 0; i < len; i++)
            w[i] = p[i] - kk * x[i];
        for (int i = 0; i < len; i++) {
            float *row = a22 + (size_t)i * ld;
            const float vi = x[i], wi = w[i];
            for (int j = 0; j < len; j++)
                row[j] -= vi * w[j] + wi * x[j];
        }
    }
    if (m >= 2) {
        diag[m - 2] = a[(size_t)(m - 2) * ld + m - 2];
        off[m - 2] = a[(size_t)(m - 1) * ld + m - 2];
        tau[m - 2] = 0;
    }
    diag[m - 1] = a[(size_t)(m - 1) * ld + m - 1];
}

/* z ← Q z for one vector of the tridiagonal basis (Q = H_0 … H_{m−3}, reflectors in a, stride ld). */
static void back_transform(const float *a, int ld, const float *tau, int m, float *z)
{
    for (int k = m - 3; k >= 0; k--) {
        if (tau[k] == 0)
            continue;
        const float *v = a + (size_t)k * ld + k + 1;
        float *zk = z + k + 1;
        const int len = m - k - 1;
        float s = zk[0];
        for (int i = 1; i < len; i++)
            s += v[i] * zk[i];
        s *= tau[k];
        zk[0] -= s;
        for (int i = 1; i < len; i++)
            zk[i] -= s * v[i];
    }
}

/* ŝ/s for singular value s (wnnm.m's closed form), 0 where Δ ≤ 0. */
static double shrink_ratio(double lambda, double c0)
{
    const double s = sqrt(lambda > 0 ? lambda : 0), delta = (s + WNNM_EPS) * (s + WNNM_EPS) - 4 * c0;
    if (!(delta > 0) || !(s > 0))
        return 0;
    const double sh = (s - WNNM_EPS + sqrt(delta)) / 2;
    return sh > 0 ? sh / s : 0;
}

/* The eigenpairs of the m × m Gram matrix g (stride ld, lower) with λ > vl, into ws->ev (ascending) and ws->u
 * (m × k, the Gram basis), and their ratios ŝ/s into ws->r. Returns k, or -EIO when inverse iteration failed. */
/* Eigenvalues of the tridiagonal matrix (diag, off²) below each of 8 shifts x: the negative pivots of T − xI
 * (Sturm; pivmin keeps a zero pivot finite, as LAPACK's slaebz). The 8 chains of divisions are independent, so
 * they run side by side in vector registers instead of waiting on one another. */
#define STURM_LANES 8
CLONES static void sturm_counts(const float *restrict diag, const double *restrict off2, int m,
                                const double *restrict x, double pivmin, int *restrict count)
{
    double q[STURM_LANES];
    int c[STURM_LANES];
    for (int l = 0; l < STURM_LANES; l++) {
        const double t = diag[0] - x[l];
        q[l] = fabs(t) < pivmin ? -pivmin : t;
        c[l] = q[l] < 0;
    }
    for (int i = 1; i < m; i++) {
        const double di = diag[i], e2 = off2[i - 1];
        for (int l = 0; l < STURM_LANES; l++) {
            const double t = di - x[l] - e2 / q[l];
            q[l] = fabs(t) < pivmin ? -pivmin : t;
            c[l] += q[l] < 0;
        }
    }
    for (int l = 0; l < STURM_LANES; l++)
        count[l] = c[l];
}

/* Above this many eigenvalues to find, ssterf (all of them) is cheaper than bisection for each. */
#define WNNM_BISECT_MAX 12

static int top_eigenpairs(sci_wnnm_ws *ws, int m, int ld, double vl, double c0)
{
    tridiagonalize(ws->g, m, ld, ws->diag, ws->off, ws->tau, ws->p, ws->w);
    double e2max = 0, lo = ws->diag[0], hi = ws->diag[0];
    for (int i = 0; i < m; i++) {
        const double ea = i > 0 ? fabs(ws->off[i - 1]) : 0, eb = i + 1 < m ? fabs(ws->off[i]) : 0;
        lo = fmin(lo, ws->diag[i] - ea - eb), hi = fmax(hi, ws->diag[i] + ea + eb); /* Gershgorin */
        if (i + 1 < m) {
            ws->off2[i] = (double)ws->off[i] * ws->off[i];
            e2max = fmax(e2max, ws->off2[i]);
        }
    }
    const double pivmin = DBL_MIN * fmax(1.0, e2max);
    if (vl >= hi)
        return 0;
    int below = 0;
    if (vl >= lo) {
        double x[STURM_LANES];
        int cnt[STURM_LANES];
        for (int l = 0; l < STURM_LANES; l++)
            x[l] = vl;
        sturm_counts(ws->diag, ws->off2, m, x, pivmin, cnt);
        below = cnt[0];
    }
    const int k = m - below;
    if (k <= 0)
        return 0;
    float *ev = ws->ev;
    int info = 0;
    if (k <= WNNM_BISECT_MAX) {
        /* multisection for λ_(below + j), j < k (ascending): 8 shifts a pass cut a bracket ninefold, and every
         * count narrows every bracket (as sstebz) */
        const double tol = 1e-6 * fmax(fabs(lo), fabs(hi)) + pivmin;
        for (int j = 0; j < k; j++)
            ws->lo[j] = fmax(vl, lo), ws->hi[j] = hi + tol;
        for (int j = k - 1; j >= 0; j--)
            for (int pass = 0; pass < 64 && ws->hi[j] - ws->lo[j] > tol; pass++) {
                double x[STURM_LANES];
                int cnt[STURM_LANES];
                const double a = ws->lo[j], step = (ws->hi[j] - a) / (STURM_LANES + 1);
                for (int l = 0; l < STURM_LANES; l++)
                    x[l] = a + step * (l + 1);
                sturm_counts(ws->diag, ws->off2, m, x, pivmin, cnt);
                for (int l = 0; l < STURM_LANES; l++) {
                    const int c = cnt[l] - below; /* of ours below x[l] */
                    for (int i = 0; i < k; i++) {
                        if (c <= i)
                            ws->lo[i] = fmax(ws->lo[i], x[l]);
                        else
                            ws->hi[i] = fmin(ws->hi[i], x[l]);
                    }
                }
            }
        for (int j = 0; j < k; j++) /* ascending even where a cluster's brackets met, as sstein wants */
            ev[j] = fmaxf((float)(0.5 * (ws->lo[j] + ws->hi[j])), j ? ev[j - 1] : -INFINITY);
    } else {
        /* all of them (ascending) from copies: sstein wants the tridiagonal matrix itself */
        float *e = ws->work;
        memcpy(ev, ws->diag, (size_t)m * sizeof *ev);
        memcpy(e, ws->off, (size_t)m * sizeof *e);
        ssterf_(&m, ev, e, &info);
        if (info != 0)
            return -EIO;
        memmove(ev, ev + below, (size_t)k * sizeof *ev);
    }
    for (int j = 0; j < k; j++)
        ws->iblock[j] = 1;
    ws->isplit[0] = m;
    sstein_(&m, ws->diag, ws->off, &k, ev, ws->iblock, ws->isplit, ws->u, &m, ws->work, ws->iwork, ws->ifail, &info);
    if (info != 0)
        return -EIO;
    int kept = 0;
    for (int j = 0; j < k; j++) {
        const double r = shrink_ratio(ev[j], c0);
        if (!(r > 0))
            continue;
        float *u = ws->u + (size_t)kept * m;
        if (kept != j)
            memcpy(u, ws->u + (size_t)j * m, (size_t)m * sizeof *u);
        back_transform(ws->g, ld, ws->tau, m, u);
        ws->r[kept++] = r;
    }
    return kept;
}

/* mean = the mean column of y (d × n), yc = y − mean (stride ld, padding zero); returns ‖yc‖². */
CLONES static double center(const float *restrict y, int d, int n, int ld, double *restrict mean, float *restrict yc)
{
    for (int i = 0; i < d; i++)
        mean[i] = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < d; i++)
            mean[i] += y[(size_t)j * d + i];
    for (int i = 0; i < d; i++)
        mean[i] /= n;
    float sq[8] = {0};
    for (int j = 0; j < n; j++) {
        float *ycj = yc + (size_t)j * ld;
        for (int i = 0; i < d; i++)
            ycj[i] = y[(size_t)j * d + i] - (float)mean[i];
        for (int i = d; i < ld; i++)
            ycj[i] = 0;
        for (int i = 0; i < ld; i += 8)
            for (int l = 0; l < 8; l++)
                sq[l] += ycj[i + l] * ycj[i + l];
    }
    double trace = 0;
    for (int l = 0; l < 8; l++)
        trace += sq[l];
    return trace;
}

int sci_wnnm_group(sci_wnnm_ws *ws, const float *y, int d, int n, double c, double sigma, float *x)
{
    const int ldy = padded(d);
    float *yc = ws->yc;
    double *mean = ws->mean;
    const double trace = center(y, d, n, ldy, mean, yc);
    const int rows = d <= n; /* (Y − Ȳ)(Y − Ȳ)ᵀ, d × d; else (Y − Ȳ)ᵀ(Y − Ȳ), n × n: the same nonzero spectrum */
    const int m = rows ? d : n, ldg = padded(m);
    const double c0 = c * sqrt((double)n) * 2 * sigma * sigma;
    /* kept: Δ > 0 ⇔ s > 2√C0 − ε, i.e. λ = s² > vl; every λ ≤ the trace */
    const double edge = 2 * sqrt(c0) - WNNM_EPS, vl = edge > 0 ? edge * edge : -1.0;
    int kept = 0;
    if (trace > 0 && trace > vl) {
        if (rows)
            gram_rows(yc, ldy, d, n, ws->g);
        else
            gram_cols(yc, ldy, d, n, ldg, ws->g);
        kept = top_eigenpairs(ws, m, ldg, vl, c0);
        if (kept < 0) {
            if (x != y)
                memcpy(x, y, (size_t)d * n * sizeof *x);
            return kept;
        }
    }
    /* x = Ȳ + U_k diag(ŝ/s) U_kᵀ (Y − Ȳ), or (Y − Ȳ) V_k diag(ŝ/s) V_kᵀ */
    for (int j = 0; j < n; j++)
        for (int i = 0; i < d; i++)
            x[(size_t)j * d + i] = (float)mean[i];
    if (rows) {
        for (int j = 0; j < n; j++) {
            const float *yj = yc + (size_t)j * ldy;
            float *xj = x + (size_t)j * d;
            for (int k = 0; k < kept; k++) {
                const float *u = ws->u + (size_t)k * d;
                float s = 0;
#pragma omp simd reduction(+ : s)
                for (int i = 0; i < d; i++)
                    s += u[i] * yj[i];
                s *= (float)ws->r[k];
                for (int i = 0; i < d; i++)
                    xj[i] += s * u[i];
            }
        }
    } else {
        float *t = ws->t;
        for (int k = 0; k < kept; k++) {
            const float *v = ws->u + (size_t)k * n;
            for (int i = 0; i < d; i++)
                t[i] = 0;
            for (int j = 0; j < n; j++) {
                const float vj = v[j] * (float)ws->r[k];
                const float *yj = yc + (size_t)j * ldy;
                for (int i = 0; i < d; i++)
                    t[i] += vj * yj[i];
            }
            for (int j = 0; j < n; j++) {
                float *xj = x + (size_t)j * d;
                for (int i = 0; i < d; i++)
                    xj[i] += t[i] * v[j];
            }
        }
    }
    return kept;
}

/* --- the video denoiser ----------------------------------------------------------------------------------- */

struct sci_wnnm {
    int w, h, n, threads;
    sci_wnnm_params p;
    sci_blockmatch *bm;
    int matched;
    sci_wnnm_ws **ws;   /* per thread */
    float **grp;        /* per thread: one group, d × n */
    double **acc;       /* per thread: the sum of the estimates covering each pixel */
    float *count;       /* patches covering each pixel (0: none), from the last match */
};

void sci_wnnm_free(sci_wnnm *wn)
{
    if (!wn)
        return;
    sci_blockmatch_free(wn->bm);
    for (int t = 0; t < wn->threads; t++) {
        if (wn->ws)
            sci_wnnm_ws_free(wn->ws[t]);
        if (wn->grp)
            free(wn->grp[t]);
        if (wn->acc)
            free(wn->acc[t]);
    }
    free(wn->ws);
    free(wn->grp);
    free(wn->acc);
    free(wn->count);
    free(wn);
}

int sci_wnnm_new(sci_wnnm **out, int w, int h, int n, const sci_wnnm_params *p, int threads, sci_error *err)
{
    *out = NULL;
    if (!(p->c > 0) || !isfinite(p->c))
        return sci_error_set(err, -EINVAL, "wnnm: c must be > 0 (got %g)", p->c);
    if (threads < 0)
        return sci_error_set(err, -EINVAL, "wnnm: threads must be >= 0 (got %d)", threads);
    sci_wnnm *wn = calloc(1, sizeof *wn);
    if (!wn)
        return sci_error_set(err, -ENOMEM, "wnnm: out of memory");
    wn->w = w, wn->h = h, wn->n = n, wn->p = *p;
    wn->threads = threads > 0 ? threads : omp_get_max_threads();
    if (wn->threads < 1)
        wn->threads = 1;
    const sci_blockmatch_params bp = {.patch = p->patch, .group = p->group, .step = p->step, .window = p->window};
    int rc = sci_blockmatch_new(&wn->bm, w, h, n, &bp, err);
    if (rc < 0) {
        sci_wnnm_free(wn);
        return rc;
    }
    wn->p.group = sci_blockmatch_group_size(wn->bm);
    const int d = p->patch * p->patch, k = wn->p.group;
    const size_t count = (size_t)w * h * n;
    wn->ws = calloc((size_t)wn->threads, sizeof *wn->ws);
    wn->grp = calloc((size_t)wn->threads, sizeof *wn->grp);
    wn->acc = calloc((size_t)wn->threads, sizeof *wn->acc);
    wn->count = malloc(count * sizeof *wn->count);
    if (!wn->ws || !wn->grp || !wn->acc || !wn->count)
        rc = -ENOMEM;
    for (int t = 0; rc == 0 && t < wn->threads; t++) {
        if ((rc = sci_wnnm_ws_new(&wn->ws[t], d, k, err)) < 0)
            break;
        wn->grp[t] = malloc((size_t)d * k * sizeof *wn->grp[t]);
        wn->acc[t] = malloc(count * sizeof *wn->acc[t]);
        if (!wn->grp[t] || !wn->acc[t])
            rc = -ENOMEM;
    }
    if (rc < 0) {
        sci_wnnm_free(wn);
        return rc == -ENOMEM ? sci_error_set(err, rc, "wnnm: out of memory (%d threads, %dx%dx%d)", threads, w, h, n)
                             : rc;
    }
    *out = wn;
    return 0;
}

sci_wnnm_params sci_wnnm_params_of(const sci_wnnm *wn) { return wn->p; }

int sci_wnnm_match(sci_wnnm *wn, const float *frames, const atomic_int *cancel)
{
    int rc = sci_blockmatch_run(wn->bm, frames, wn->threads, cancel);
    wn->matched = 0;
    if (rc < 0)
        return rc;
    /* how many member patches cover each pixel: fixed until the next match */
    const int groups = sci_blockmatch_keys(wn->bm), k = wn->p.group, p = wn->p.patch, w = wn->w;
    const size_t count = (size_t)wn->w * wn->h * wn->n;
#pragma omp parallel num_threads(wn->threads)
    {
        double *acc = wn->acc[omp_get_thread_num()];
        memset(acc, 0, count * sizeof *acc);
#pragma omp for schedule(static)
        for (int g = 0; g < groups; g++) {
            const uint32_t *m = sci_blockmatch_group(wn->bm, g);
            for (int j = 0; j < k; j++)
                for (int r = 0; r < p; r++) {
                    double *a = acc + m[j] + (size_t)r * w;
                    for (int c = 0; c < p; c++)
                        a[c] += 1.0;
                }
        }
#pragma omp for schedule(static)
        for (size_t i = 0; i < count; i++) {
            double s = 0;
            for (int t = 0; t < wn->threads; t++)
                s += wn->acc[t][i];
            wn->count[i] = (float)s;
        }
    }
    wn->matched = 1;
    return 0;
}

int sci_wnnm_denoise(sci_wnnm *wn, const float *in, double sigma, float *out, const atomic_int *cancel)
{
    int rc;
    if (!wn->matched && (rc = sci_wnnm_match(wn, in, cancel)) < 0)
        return rc;
    const int groups = sci_blockmatch_keys(wn->bm), k = wn->p.group, p = wn->p.patch, d = p * p, w = wn->w;
    const size_t count = (size_t)wn->w * wn->h * wn->n;
    const double c = wn->p.c;
    atomic_int stop = 0, failed = 0;
#pragma omp parallel num_threads(wn->threads)
    {
        const int t = omp_get_thread_num();
        double *acc = wn->acc[t];
        float *grp = wn->grp[t];
        memset(acc, 0, count * sizeof *acc);
#pragma omp for schedule(static, 16)
        for (int g = 0; g < groups; g++) {
            if (atomic_load_explicit(&stop, memory_order_relaxed))
                continue;
            if ((g & 63) == 0 && cancel && atomic_load(cancel))
                atomic_store(&stop, 1);
            const uint32_t *m = sci_blockmatch_group(wn->bm, g);
            for (int j = 0; j < k; j++)
                for (int r = 0; r < p; r++)
                    memcpy(grp + (size_t)j * d + (size_t)r * p, in + m[j] + (size_t)r * w, (size_t)p * sizeof *grp);
            if (sci_wnnm_group(wn->ws[t], grp, d, k, c, sigma, grp) < 0)
                atomic_store(&failed, 1);
            for (int j = 0; j < k; j++)
                for (int r = 0; r < p; r++) {
                    double *a = acc + m[j] + (size_t)r * w;
                    const float *e = grp + (size_t)j * d + (size_t)r * p;
                    for (int cc = 0; cc < p; cc++)
                        a[cc] += e[cc];
                }
        }
        if (!atomic_load(&stop)) {
#pragma omp for schedule(static)
            for (size_t i = 0; i < count; i++) {
                double s = 0;
                for (int u = 0; u < wn->threads; u++)
                    s += wn->acc[u][i];
                out[i] = wn->count[i] > 0 ? (float)(s / wn->count[i]) : in[i];
            }
        }
    }
    if (stop)
        return SCI_ECANCELED;
    return failed ? -EIO : 0;
}
