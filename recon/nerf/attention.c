/* recon/nerf/attention.c — I²R-MSA core (see attention.h).
 *
 * Layout of the work: one (group, head) at a time, VW = 16 tokens per vector (GCC vector extensions, lowered to
 * one zmm, two ymm or four xmm by the target clone). The forward puts 16 *queries* in the lanes and walks the
 * keys as scalars broadcast from their rows: the scores, the running max, the exponentials, the normaliser and
 * the d output channels are all lane-wise, so no horizontal sum is ever taken and the d accumulators stay in
 * registers (d = 8 for the default network is a compile-time constant in its own specialisation).
 * The backward recomputes the probabilities from the saved lse in the same query-lane sweep (the score is
 * Σ_c (q_ic·scale)·k_jc in the forward's order, so p is bitwise the forward's) and gets
 *   dq_i = scale·Σ_j ds_ij k_j                 in the query lanes, and, from the 16 × n blocks of p and ds it
 *   dk_j = scale·Σ_i ds_ij q_i, dv_j = Σ_i p_ij do_i    leaves in scratch, with the d channels in the lanes,
 * with ds_ij = p_ij (dp_ij − D_i), dp_ij = do_i·v_j, D_i = do_i·o_i.
 * Cost per (query, key) pair and head: forward ≈ 2d + 20 lane-operations / 16, backward ≈ 2× that.
 * No FMA contraction under -std=c11 and a fixed summation order: results do not depend on the clone that runs
 * except for the vector width, which does not change any sum (all sums run over keys or queries in order).
 */
/* Comparisons inside the vector exp must be if-converted; this changes no value (IEEE results are the same), it
 * only lets gcc assume no FP trap is enabled (the project never enables one). */
#pragma GCC optimize("no-trapping-math")

#include "recon/nerf/attention.h"
#include "recon/nerf/vec16.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

/* clang before 16 exports a target_clones function as NAME.ifunc, which other files' calls do not link to
 * (the fuzzers are built with clang): a single version there */
#if defined(__clang__) && __clang_major__ < 16
#define CLONES
#else
#define CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#endif
#define INLINE static inline __attribute__((always_inline))

#define MAXD 128 /* d = C/(2·heads) <= 128 since C <= 256 */
typedef int32_t vi __attribute__((vector_size(4 * VW)));

/* Selects are macros and vexp takes a pointer: no function has a 64-byte vector parameter (vec16.h) */
#define vsel(m, a, b) ((vf)(((vi)(a) & (m)) | ((vi)(b) & ~(m))))
typedef float v8 __attribute__((vector_size(32)));
INLINE v8 v8load(const float *p)
{
    v8 v;
    memcpy(&v, p, sizeof v);
    return v;
}
typedef struct v8box {
    v8 v;
} v8box;
#define v8store(p, x) memcpy((p), &(v8box){(x)}.v, sizeof(v8))

/* Lane-wise nerf_expf (fastmath.h), the same operations in the same order. */
INLINE vf vexp(const vf *xp)
{
    const vf x = *xp;
    const vf lo = vsplat(-87.3f), hi = vsplat(88.3f);
    vf xc = vsel(x < lo, lo, x);
    xc = vsel(xc > hi, hi, xc);
    vf n = (xc * 1.44269504088896341f + 12582912.0f) - 12582912.0f;
    vf r = xc - n * 0.693145751953125f;
    r = r - n * 1.42860682030941723212e-6f;
    vf p = vsplat(1.0f / 720.0f);
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    vi bits = (__builtin_convertvector(n, vi) + 127) << 23;
    vf y = p * (vf)bits;
    y = vsel(x < lo, vsplat(0.0f), y);
    return vsel(x != x, x, y);
}

static inline int padded(int n) { return (n + VW - 1) / VW * VW; }

size_t nerf_i2r_scratch_floats(const nerf_i2r_shape *s)
{
    int n = s->L > s->R ? s->L : s->R, np = padded(n);
    int d = s->C / (2 * s->heads);
    /* backward: Qt, Gt (d·np each), Dq, Lq (np), Qc, Gc (np·d), dK, dV (n·d), Pb, Sb (n·VW) */
    return (size_t)(4 * d + 2) * np + (size_t)n * (2 * d + 2 * VW) + 64;
}

/* A group: n tokens, token j at row base + j·stride; one head at channel offset c0, width d. Tokens sit in raster
 * order in rows 2^wshift wide (wshift 0: a sequence, token i at position i). */
typedef struct grp {
    int n, d, C, c0;
    size_t base, stride;
    float slope; /* the logit of query i for key j gets −slope·(|xi − xj| + |yi − yj|) (0: none) */
    int wshift;
} grp;

INLINE size_t row_of(const grp *g, int j) { return g->base + (size_t)j * g->stride; }

/* The logit of the 16 queries b … b+15 (lanes) for key j: the dot product s, minus the distance bias (a sequence's
 * |i − j|; a window's city-block distance between pixels). The forward and the backward's recomputation call this
 * with the same s, so p is bitwise the same in both. */
INLINE vf biased(const grp *g, const vf *sp, int b, int j)
{
    const vf s = *sp;
    if (g->slope == 0.0f) return s;
    const vi lane = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
    const int m = (1 << g->wshift) - 1;
    const vi qi = b + lane, dx = (qi & m) - (j & m), dy = (qi >> g->wshift) - (j >> g->wshift);
    const vi dist = ((dx ^ (dx >> 31)) - (dx >> 31)) + ((dy ^ (dy >> 31)) - (dy >> 31));
    return s - g->slope * __builtin_convertvector(dist, vf);
}

/* Transposed copy of channels [off, off + d) of the group's rows: dst[c·np + j] = scale·src[row_j·ld + off + c],
 * lanes j >= n zero. */
INLINE void gather_t(const grp *g, int d, int np, const float *src, int ld, int off, float scale, float *dst)
{
    for (int j = 0; j < g->n; j++) {
        const float *r = src + row_of(g, j) * ld + off;
        for (int c = 0; c < d; c++) dst[(size_t)c * np + j] = r[c] * scale;
    }
    for (int c = 0; c < d; c++)
        for (int j = g->n; j < np; j++) dst[(size_t)c * np + j] = 0.0f;
}

INLINE void group_forward(const grp *g, const int d, const float *qkv, int ldq, float *o, int ldo, float *lse,
                          int lse_ld, int lse_col, float *scr)
{
    const int n = g->n, np = padded(n), C = g->C, c0 = g->c0;
    const float scale = 1.0f / sqrtf((float)d);
    float *Qt = scr, *St = Qt + (size_t)d * np;
    gather_t(g, d, np, qkv, ldq, c0, scale, Qt);
    for (int b = 0; b < np; b += VW) {
        vf q[MAXD], acc[MAXD];
        for (int c = 0; c < d; c++) q[c] = vload(Qt + (size_t)c * np + b), acc[c] = vsplat(0.0f);
        vf m = vsplat(0.0f);
        for (int j = 0; j < n; j++) {
            const float *k = qkv + row_of(g, j) * ldq + C + c0;
            vf s = q[0] * k[0];
            for (int c = 1; c < d; c++) s += q[c] * k[c];
            s = biased(g, &s, b, j);
            vstore(St + (size_t)j * VW, s);
            m = j ? vsel(s > m, s, m) : s;
        }
        vf l = vsplat(0.0f);
        for (int j = 0; j < n; j++) {
            const float *v = qkv + row_of(g, j) * ldq + 2 * C + c0;
            vf arg = vload(St + (size_t)j * VW) - m;
            vf p = vexp(&arg);
            l += p;
            for (int c = 0; c < d; c++) acc[c] += p * v[c];
        }
        vf inv = 1.0f / l;
        float ob[MAXD][VW], mb[VW], lb[VW];
        for (int c = 0; c < d; c++) vstore(ob[c], acc[c] * inv);
        vstore(mb, m);
        vstore(lb, l);
        int nt = n - b < VW ? n - b : VW;
        for (int t = 0; t < nt; t++) {
            size_t ri = row_of(g, b + t);
            float *oi = o + ri * ldo + c0;
            for (int c = 0; c < d; c++) oi[c] = ob[c][t];
            lse[ri * lse_ld + lse_col] = mb[t] + logf(lb[t]);
        }
    }
}

INLINE void group_backward(const grp *g, const int d, const float *qkv, int ldq, const float *o, int ldo,
                           const float *lse, int lse_ld, int lse_col, const float *dout, int lddo, float *dqkv,
                           int ldd, float *scr)
{
    const int n = g->n, np = padded(n), C = g->C, c0 = g->c0;
    const float scale = 1.0f / sqrtf((float)d);
    float *Qt = scr, *Gt = Qt + (size_t)d * np, *Dq = Gt + (size_t)d * np, *Lq = Dq + np;
    float *Qc = Lq + np, *Gc = Qc + (size_t)np * d, *dK = Gc + (size_t)np * d, *dV = dK + (size_t)n * d;
    float *Pb = dV + (size_t)n * d, *Sb = Pb + (size_t)n * VW;
    gather_t(g, d, np, qkv, ldq, c0, scale, Qt);
    gather_t(g, d, np, dout, lddo, c0, 1.0f, Gt);
    for (int i = 0; i < np; i++) Dq[i] = 0.0f, Lq[i] = 0.0f;
    for (int i = 0; i < n; i++) {
        size_t ri = row_of(g, i);
        const float *oi = o + ri * ldo + c0, *gi = dout + ri * lddo + c0, *qi = qkv + ri * ldq + c0;
        float D = 0.0f;
        for (int c = 0; c < d; c++) D += gi[c] * oi[c], Qc[(size_t)i * d + c] = qi[c], Gc[(size_t)i * d + c] = gi[c];
        Dq[i] = D;
        Lq[i] = lse[ri * lse_ld + lse_col];
    }
    memset(dK, 0, 2 * (size_t)n * d * sizeof *dK);
    for (int b = 0; b < np; b += VW) {
        /* query lanes: p and ds for 16 queries against every key; dq in registers */
        vf q[MAXD], gq[MAXD], dq[MAXD];
        for (int c = 0; c < d; c++)
            q[c] = vload(Qt + (size_t)c * np + b), gq[c] = vload(Gt + (size_t)c * np + b), dq[c] = vsplat(0.0f);
        const vf Dv = vload(Dq + b), Lv = vload(Lq + b);
        for (int j = 0; j < n; j++) {
            const float *k = qkv + row_of(g, j) * ldq + C + c0, *v = k + C;
            vf s = q[0] * k[0], dp = gq[0] * v[0];
            for (int c = 1; c < d; c++) s += q[c] * k[c], dp += gq[c] * v[c];
            s = biased(g, &s, b, j);
            vf arg = s - Lv;
            vf p = vexp(&arg);
            vf ds = p * (dp - Dv);
            for (int c = 0; c < d; c++) dq[c] += ds * k[c];
            vstore(Pb + (size_t)j * VW, p);
            vstore(Sb + (size_t)j * VW, ds);
        }
        float ob[MAXD][VW];
        for (int c = 0; c < d; c++) vstore(ob[c], dq[c] * scale);
        int nt = n - b < VW ? n - b : VW;
        for (int t = 0; t < nt; t++) {
            float *r = dqkv + row_of(g, b + t) * ldd + c0;
            for (int c = 0; c < d; c++) r[c] = ob[c][t];
        }
        /* channel lanes: dk_j += Σ_t ds_tj q_t, dv_j += Σ_t p_tj do_t over this block's queries in order (d-wide
         * vectors, no horizontal sum; the sum over queries keeps the query order) */
        const float *qb = Qc + (size_t)b * d, *gb = Gc + (size_t)b * d;
        if (d == 8) {
            v8 qv[VW], gv[VW];
            for (int t = 0; t < nt; t++) qv[t] = v8load(qb + 8 * t), gv[t] = v8load(gb + 8 * t);
            for (int j = 0; j < n; j++) {
                const float *sj = Sb + (size_t)j * VW, *pj = Pb + (size_t)j * VW;
                v8 ak = v8load(dK + 8 * (size_t)j), av = v8load(dV + 8 * (size_t)j);
                for (int t = 0; t < nt; t++) ak += sj[t] * qv[t], av += pj[t] * gv[t];
                v8store(dK + 8 * (size_t)j, ak), v8store(dV + 8 * (size_t)j, av);
            }
        } else {
            for (int j = 0; j < n; j++) {
                float ak[MAXD], av[MAXD];
                const float *sj = Sb + (size_t)j * VW, *pj = Pb + (size_t)j * VW;
                for (int c = 0; c < d; c++) ak[c] = dK[(size_t)j * d + c], av[c] = dV[(size_t)j * d + c];
                for (int t = 0; t < nt; t++) {
                    const float st = sj[t], pt = pj[t], *qt = qb + (size_t)t * d, *gt = gb + (size_t)t * d;
                    for (int c = 0; c < d; c++) ak[c] += st * qt[c], av[c] += pt * gt[c];
                }
                for (int c = 0; c < d; c++) dK[(size_t)j * d + c] = ak[c], dV[(size_t)j * d + c] = av[c];
            }
        }
    }
    for (int j = 0; j < n; j++) {
        float *r = dqkv + row_of(g, j) * ldd;
        for (int c = 0; c < d; c++) r[C + c0 + c] = dK[(size_t)j * d + c] * scale, r[2 * C + c0 + c] = dV[(size_t)j * d + c];
    }
}

/* The d = 8 case (width 32, 2 heads per path) gets its own fully unrolled copy. */
#define DISPATCH_D(call_d)                                                                                       \
    do {                                                                                                         \
        if (d == 8)                                                                                              \
            call_d(8);                                                                                           \
        else if (d == 4)                                                                                         \
            call_d(4);                                                                                           \
        else                                                                                                     \
            call_d(d);                                                                                           \
    } while (0)

/* A switched-off path (ablation): o = v on its channels, lse = 0 (forward); dv = do, dq = dk = 0 (backward). */
static void pass_forward(const nerf_i2r_shape *s, size_t p0, int path, const float *qkv, int ld_qkv, float *o,
                         int ldo, float *lse)
{
    const int C = s->C, H = s->heads, half = C / 2, c0 = path * half;
    const size_t rows = (size_t)s->R * s->L;
    for (size_t i = p0; i < p0 + rows; i++) {
        memcpy(o + i * ldo + c0, qkv + i * ld_qkv + 2 * C + c0, (size_t)half * sizeof *o);
        for (int h = 0; h < H; h++) lse[i * 2 * H + path * H + h] = 0.0f;
    }
}

static void pass_backward(const nerf_i2r_shape *s, size_t p0, int path, const float *dout, int lddo, float *dqkv,
                          int ld_dqkv)
{
    const int C = s->C, half = C / 2, c0 = path * half;
    const size_t rows = (size_t)s->R * s->L;
    for (size_t i = p0; i < p0 + rows; i++) {
        float *r = dqkv + i * ld_dqkv;
        memset(r + c0, 0, (size_t)half * sizeof *r);
        memset(r + C + c0, 0, (size_t)half * sizeof *r);
        memcpy(r + 2 * C + c0, dout + i * lddo + c0, (size_t)half * sizeof *r);
    }
}

CLONES void nerf_i2r_forward(const nerf_i2r_shape *s, int n_patches, const float *qkv, int ld_qkv, float *o,
                             int ldo, float *lse, float *scratch)
{
    const int C = s->C, H = s->heads, L = s->L, R = s->R, d = C / (2 * H), half = C / 2;
    const int wshift = s->win_w > 1 ? __builtin_ctz((unsigned)s->win_w) : 0;
    for (int pa = 0; pa < n_patches; pa++) {
        size_t p0 = (size_t)pa * R * L;
        if (s->intra_off) pass_forward(s, p0, 0, qkv, ld_qkv, o, ldo, lse);
        if (s->inter_off) pass_forward(s, p0, 1, qkv, ld_qkv, o, ldo, lse);
        for (int h = 0; h < H; h++) {
            for (int r = 0; r < R && !s->intra_off; r++) { /* intra-ray: the L samples of ray r */
                grp g = {.n = L, .d = d, .C = C, .c0 = h * d, .base = p0 + (size_t)r * L, .stride = 1,
                         .slope = ldexpf(s->intra_slope, -h)};
#define FWD_A(D) group_forward(&g, D, qkv, ld_qkv, o, ldo, lse, 2 * H, h, scratch)
                DISPATCH_D(FWD_A);
            }
            for (int t = 0; t < L && !s->inter_off; t++) { /* inter-ray: the R rays at sample t */
                grp g = {.n = R, .d = d, .C = C, .c0 = half + h * d, .base = p0 + t, .stride = (size_t)L,
                         .slope = ldexpf(s->inter_slope, -h), .wshift = wshift};
#define FWD_B(D) group_forward(&g, D, qkv, ld_qkv, o, ldo, lse, 2 * H, H + h, scratch)
                DISPATCH_D(FWD_B);
            }
        }
    }
}

CLONES void nerf_i2r_backward(const nerf_i2r_shape *s, int n_patches, const float *qkv, int ld_qkv, const float *o,
                              int ldo, const float *lse, const float *dout, int lddo, float *dqkv, int ld_dqkv,
                              float *scratch)
{
    const int C = s->C, H = s->heads, L = s->L, R = s->R, d = C / (2 * H), half = C / 2;
    const int wshift = s->win_w > 1 ? __builtin_ctz((unsigned)s->win_w) : 0;
    for (int pa = 0; pa < n_patches; pa++) {
        size_t p0 = (size_t)pa * R * L;
        if (s->intra_off) pass_backward(s, p0, 0, dout, lddo, dqkv, ld_dqkv);
        if (s->inter_off) pass_backward(s, p0, 1, dout, lddo, dqkv, ld_dqkv);
        for (int h = 0; h < H; h++) {
            for (int r = 0; r < R && !s->intra_off; r++) {
                grp g = {.n = L, .d = d, .C = C, .c0 = h * d, .base = p0 + (size_t)r * L, .stride = 1,
                         .slope = ldexpf(s->intra_slope, -h)};
#define BWD_A(D) group_backward(&g, D, qkv, ld_qkv, o, ldo, lse, 2 * H, h, dout, lddo, dqkv, ld_dqkv, scratch)
                DISPATCH_D(BWD_A);
            }
            for (int t = 0; t < L && !s->inter_off; t++) {
                grp g = {.n = R, .d = d, .C = C, .c0 = half + h * d, .base = p0 + t, .stride = (size_t)L,
                         .slope = ldexpf(s->inter_slope, -h), .wshift = wshift};
#define BWD_B(D)                                                                                                 \
    group_backward(&g, D, qkv, ld_qkv, o, ldo, lse, 2 * H, H + h, dout, lddo, dqkv, ld_dqkv, scratch)
                DISPATCH_D(BWD_B);
            }
        }
    }
}
