/* recon/cnn/conv.c — 3×3 convolution by Winograd F(4×4, 3×3) (see conv.h). */
#include "recon/cnn/conv.h"

#include <cblas.h>
#include <errno.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

/* Tiles per block: a block's transformed input and products (36 × c × TB floats each) stay in L2 for c ≤ 96. */
#define TB 64

struct cnn_conv {
    int cin, cout, relu;
    float *weight; /* cout × cin × 9 */
    float *bias;   /* cout */
    float *u;      /* 36 × cout × cin: G g Gᵀ of every filter, position ξ major */
};

struct cnn_conv_ws {
    int cmax, threads;
    int portable; /* 1: products through cblas_sgemm even where AVX-512 is there (tests of both paths) */
    float *buf; /* per thread: d[36·TB], v[36·cmax·TB], m[36·cmax·TB] */
    size_t per_thread;
};

size_t cnn_act_floats(int c, int h, int w)
{
    return (size_t)c * (size_t)(4 * ((h + 3) / 4) + 2) * (size_t)(4 * ((w + 3) / 4) + 2);
}

void cnn_act_init(cnn_act *a, int c, int h, int w, float *data)
{
    a->c = c, a->h = h, a->w = w;
    a->hs = 4 * ((h + 3) / 4) + 2;
    a->ws = 4 * ((w + 3) / 4) + 2;
    a->plane = (size_t)a->hs * a->ws;
    a->data = data;
}

void cnn_blas_single_thread(void) { openblas_set_num_threads(1); }

/* U = G g Gᵀ for one 3×3 filter g (row-major), in double. */
static void weight_transform(const float *g, float *u, size_t stride)
{
    static const double G[6][3] = {{1.0 / 4, 0, 0},           {-1.0 / 6, -1.0 / 6, -1.0 / 6},
                                   {-1.0 / 6, 1.0 / 6, -1.0 / 6}, {1.0 / 24, 1.0 / 12, 1.0 / 6},
                                   {1.0 / 24, -1.0 / 12, 1.0 / 6}, {0, 0, 1}};
    double t[6][3];
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 3; j++)
            t[i][j] = G[i][0] * g[0 * 3 + j] + G[i][1] * g[1 * 3 + j] + G[i][2] * g[2 * 3 + j];
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 6; j++)
            u[(size_t)(i * 6 + j) * stride] = (float)(t[i][0] * G[j][0] + t[i][1] * G[j][1] + t[i][2] * G[j][2]);
}

int cnn_conv_new(int cin, int cout, const float *weight, const float *bias, int activation, cnn_conv **out,
                 sci_error *err)
{
    *out = NULL;
    if (cin < 1 || cout < 1 || cin > 4096 || cout > 4096)
        return sci_error_set(err, -EINVAL, "conv 3x3: bad channel counts %d -> %d", cin, cout);
    cnn_conv *c = calloc(1, sizeof *c);
    const size_t nw = (size_t)cout * cin * 9;
    if (!c || !(c->weight = malloc(nw * sizeof *c->weight)) || !(c->bias = calloc((size_t)cout, sizeof *c->bias)) ||
        !(c->u = malloc((size_t)36 * cout * cin * sizeof *c->u))) {
        cnn_conv_free(c);
        return sci_error_set(err, -ENOMEM, "conv 3x3 %d -> %d: out of memory", cin, cout);
    }
    c->cin = cin, c->cout = cout, c->relu = activation == CNN_RELU;
    memcpy(c->weight, weight, nw * sizeof *c->weight);
    if (bias)
        memcpy(c->bias, bias, (size_t)cout * sizeof *c->bias);
    const size_t xi = (size_t)cout * cin;
    for (int k = 0; k < cout; k++)
        for (int j = 0; j < cin; j++)
            weight_transform(weight + ((size_t)k * cin + j) * 9, c->u + (size_t)k * cin + j, xi);
    *out = c;
    return 0;
}

void cnn_conv_free(cnn_conv *c)
{
    if (!c)
        return;
    free(c->weight);
    free(c->bias);
    free(c->u);
    free(c);
}

int cnn_conv_cin(const cnn_conv *c) { return c->cin; }
int cnn_conv_cout(const cnn_conv *c) { return c->cout; }

cnn_conv_ws *cnn_conv_ws_new(int cmax, int threads)
{
    cnn_conv_ws *ws = calloc(1, sizeof *ws);
    if (!ws)
        return NULL;
    ws->cmax = cmax, ws->threads = threads < 1 ? 1 : threads;
    /* rounded to 16 floats so each thread's part starts on its own cache line */
    ws->per_thread = ((size_t)36 * TB + 2 * (size_t)36 * cmax * TB + 15) & ~(size_t)15;
    if (!(ws->buf = aligned_alloc(64, ws->per_thread * ws->threads * sizeof(float)))) {
        free(ws);
        return NULL;
    }
    /* zeroed so the scratch columns past a short block hold numbers, not whatever the allocator left */
    memset(ws->buf, 0, ws->per_thread * ws->threads * sizeof(float));
    return ws;
}

void cnn_conv_ws_portable(cnn_conv_ws *ws, int on) { ws->portable = on; }

void cnn_conv_ws_free(cnn_conv_ws *ws)
{
    if (!ws)
        return;
    free(ws->buf);
    free(ws);
}

/* The 1-D input transform Bᵀ d over six rows of n values each (row stride s), into six rows of o (stride so). */
static inline void bt_rows(const float *d, size_t s, float *o, size_t so, int n)
{
#pragma omp simd
    for (int t = 0; t < n; t++) {
        const float d0 = d[t], d1 = d[s + t], d2 = d[2 * s + t], d3 = d[3 * s + t], d4 = d[4 * s + t],
                    d5 = d[5 * s + t];
        o[t] = 4 * d0 - 5 * d2 + d4;
        o[so + t] = -4 * d1 - 4 * d2 + d3 + d4;
        o[2 * so + t] = 4 * d1 - 4 * d2 - d3 + d4;
        o[3 * so + t] = -2 * d1 - d2 + 2 * d3 + d4;
        o[4 * so + t] = 2 * d1 - d2 - 2 * d3 + d4;
        o[5 * so + t] = 4 * d1 - 5 * d3 + d5;
    }
}

/* The 1-D output transform Aᵀ m over six rows into four. */
static inline void at_rows(const float *m, size_t s, float *o, size_t so, int n)
{
#pragma omp simd
    for (int t = 0; t < n; t++) {
        const float m0 = m[t], m1 = m[s + t], m2 = m[2 * s + t], m3 = m[3 * s + t], m4 = m[4 * s + t],
                    m5 = m[5 * s + t];
        const float a = m1 + m2, b = m1 - m2, c = m3 + m4, e = m3 - m4;
        o[t] = m0 + a + c;
        o[so + t] = b + 2 * e;
        o[2 * so + t] = a + 4 * c;
        o[3 * so + t] = b + 8 * e + m5;
    }
}

/* m (cout × TB) = u (cout × cin) · v (cin × TB), all TB columns (those past a block's tiles are scratch). Portable
 * path: cblas_sgemm. */
static void product_blas(int cout, int cin, const float *u, const float *v, float *m)
{
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, cout, TB, cin, 1.0f, u, cin, v, TB, 0.0f, m, TB);
}

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
/* AVX-512 path: 4 rows × 64 columns of m in 16 registers, v's rows streamed from L1 (a block's v is cin × 64
 * floats, 16 KiB at cin = 64), u's values broadcast. FMA-bound: 16 FMAs per 4 loads and 4 broadcasts. */
__attribute__((target("avx512f"))) static void product_avx512(int cout, int cin, const float *u, const float *v,
                                                               float *m)
{
    int k = 0;
    for (; k + 4 <= cout; k += 4) {
        __m512 a[4][4];
        for (int r = 0; r < 4; r++)
            for (int q = 0; q < 4; q++)
                a[r][q] = _mm512_setzero_ps();
        const float *u0 = u + (size_t)k * cin;
        for (int j = 0; j < cin; j++) {
            const float *vj = v + (size_t)j * TB;
            const __m512 v0 = _mm512_load_ps(vj), v1 = _mm512_load_ps(vj + 16), v2 = _mm512_load_ps(vj + 32),
                         v3 = _mm512_load_ps(vj + 48);
            for (int r = 0; r < 4; r++) {
                const __m512 b = _mm512_set1_ps(u0[(size_t)r * cin + j]);
                a[r][0] = _mm512_fmadd_ps(b, v0, a[r][0]);
                a[r][1] = _mm512_fmadd_ps(b, v1, a[r][1]);
                a[r][2] = _mm512_fmadd_ps(b, v2, a[r][2]);
                a[r][3] = _mm512_fmadd_ps(b, v3, a[r][3]);
            }
        }
        for (int r = 0; r < 4; r++)
            for (int q = 0; q < 4; q++)
                _mm512_store_ps(m + (size_t)(k + r) * TB + 16 * q, a[r][q]);
    }
    for (; k < cout; k++)
        for (int t = 0; t < TB; t++) {
            float s = 0;
            for (int j = 0; j < cin; j++)
                s += u[(size_t)k * cin + j] * v[(size_t)j * TB + t];
            m[(size_t)k * TB + t] = s;
        }
}
#endif

typedef void (*product_fn)(int cout, int cin, const float *u, const float *v, float *m);

static product_fn product_pick(void)
{
#if defined(__x86_64__) && defined(__GNUC__)
    if (__builtin_cpu_supports("avx512f"))
        return product_avx512;
#endif
    return product_blas;
}

/* One block of tiles [t0, t0 + nb): transform, 36 products, inverse transform. */
static inline __attribute__((always_inline)) void run_block(const cnn_conv *c, const cnn_act *in, cnn_act *out,
                                                            float *scratch, int tw, int t0, int nb, product_fn product)
{
    const int cin = c->cin, cout = c->cout;
    float *d = scratch;                       /* 36 × TB: the patches of one channel, then Bᵀ d */
    float *v = d + (size_t)36 * TB;           /* 36 × cin × TB */
    float *m = v + (size_t)36 * cin * TB;     /* 36 × cout × TB */
    float e[36 * TB];                         /* (Bᵀ d) B, or the output tiles */
    for (int j = 0; j < cin; j++) {
        const float *plane = in->data + (size_t)j * in->plane;
        for (int t = 0; t < nb; t++) {
            const int ty = (t0 + t) / tw, tx = (t0 + t) % tw;
            const float *p = plane + (size_t)(4 * ty) * in->ws + 4 * tx;
            for (int r = 0; r < 6; r++)
                for (int s = 0; s < 6; s++)
                    e[(r * 6 + s) * TB + t] = p[(size_t)r * in->ws + s];
        }
        /* rows: for each patch column s, Bᵀ over the 6 rows r → d[(i*6+s)] */
        for (int s = 0; s < 6; s++)
            bt_rows(e + s * TB, 6 * TB, d + s * TB, 6 * TB, nb);
        /* columns: for each i, Bᵀ over the 6 values s → v[ξ = i*6+k][j] */
        for (int i = 0; i < 6; i++)
            bt_rows(d + (size_t)i * 6 * TB, TB, v + ((size_t)(i * 6) * cin + j) * TB, (size_t)cin * TB, nb);
    }
    for (int xi = 0; xi < 36; xi++)
        product(cout, cin, c->u + (size_t)xi * cout * cin, v + (size_t)xi * cin * TB, m + (size_t)xi * cout * TB);
    for (int k = 0; k < cout; k++) {
        /* rows: Aᵀ over i for each column q → d[(a*6+q)] (4 × 6) */
        for (int q = 0; q < 6; q++)
            at_rows(m + ((size_t)q * cout + k) * TB, (size_t)6 * cout * TB, d + q * TB, 6 * TB, nb);
        /* columns: Aᵀ over q for each row a → e[a*4+b] (4 × 4) */
        for (int a = 0; a < 4; a++)
            at_rows(d + (size_t)a * 6 * TB, TB, e + (size_t)a * 4 * TB, TB, nb);
        const float bias = c->bias[k];
        float *plane = out->data + (size_t)k * out->plane;
        for (int t = 0; t < nb; t++) {
            const int ty = (t0 + t) / tw, tx = (t0 + t) % tw;
            const int ny = out->h - 4 * ty < 4 ? out->h - 4 * ty : 4, nx = out->w - 4 * tx < 4 ? out->w - 4 * tx : 4;
            float *o = plane + (size_t)(4 * ty + 1) * out->ws + 4 * tx + 1;
            for (int a = 0; a < ny; a++)
                for (int b = 0; b < nx; b++) {
                    float val = e[(a * 4 + b) * TB + t] + bias;
                    o[(size_t)a * out->ws + b] = c->relu && !(val > 0) ? 0.0f : val;
                }
        }
    }
}

/* The transforms are half of a layer's time: compiled once more for AVX-512 where the CPU has it. */
typedef void (*block_fn)(const cnn_conv *c, const cnn_act *in, cnn_act *out, float *scratch, int tw, int t0, int nb,
                         product_fn product);
static void block_generic(const cnn_conv *c, const cnn_act *in, cnn_act *out, float *scratch, int tw, int t0, int nb,
                          product_fn product)
{
    run_block(c, in, out, scratch, tw, t0, nb, product);
}
#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx512f"))) static void block_avx512(const cnn_conv *c, const cnn_act *in, cnn_act *out,
                                                             float *scratch, int tw, int t0, int nb, product_fn product)
{
    run_block(c, in, out, scratch, tw, t0, nb, product);
}
#endif

void cnn_conv_run(const cnn_conv *c, const cnn_act *in, cnn_act *out, cnn_conv_ws *ws)
{
    const int th = (in->h + 3) / 4, tw = (in->w + 3) / 4, tiles = th * tw;
    const int blocks = (tiles + TB - 1) / TB;
    const product_fn product = ws->portable ? product_blas : product_pick();
    block_fn block = block_generic;
#if defined(__x86_64__) && defined(__GNUC__)
    if (!ws->portable && product == product_avx512)
        block = block_avx512;
#endif
#pragma omp parallel for schedule(static) num_threads(ws->threads) if (blocks > 1)
    for (int b = 0; b < blocks; b++) {
        float *scratch = ws->buf + ws->per_thread * (size_t)omp_get_thread_num();
        const int t0 = b * TB, nb = tiles - t0 < TB ? tiles - t0 : TB;
        block(c, in, out, scratch, tw, t0, nb, product);
    }
}

void cnn_conv_reference(const cnn_conv *c, const cnn_act *in, cnn_act *out)
{
    for (int k = 0; k < c->cout; k++)
        for (int y = 0; y < in->h; y++)
            for (int x = 0; x < in->w; x++) {
                double s = c->bias[k];
                for (int j = 0; j < c->cin; j++)
                    for (int dy = -1; dy <= 1; dy++)
                        for (int dx = -1; dx <= 1; dx++) {
                            if (y + dy < 0 || y + dy >= in->h || x + dx < 0 || x + dx >= in->w)
                                continue;
                            s += (double)c->weight[(((size_t)k * c->cin + j) * 3 + dy + 1) * 3 + dx + 1] *
                                 *cnn_act_at(in, j, y + dy, x + dx);
                        }
                *cnn_act_at(out, k, y, x) = c->relu && !(s > 0) ? 0.0f : (float)s;
            }
}

const char *cnn_conv_kernel(const cnn_conv_ws *ws)
{
    return ws->portable || product_pick() == product_blas ? "winograd f(4x4,3x3) + openblas sgemm"
                                                           : "winograd f(4x4,3x3) + avx-512 products";
}
