/* bench/bench_nerf.c — forward+backward throughput of the NeRF blocks, the two-block RayFormer training step and
 * the SCINeRF-style MLP field.
 *
 * Prints, per block and for the whole networks, forward + backward points per second on both threads, the memory
 * per point and the process peak RSS, and writes bench/results/nerf.md. The RayFormer step is the throughput target:
 * network forward, volume rendering, measurement + TV loss, backward and Adam at 65,536 points per step
 * (4 patches × 64 pixels × 8 poses × 32 samples). Each figure is the best and the median of repeated runs after a
 * warm-up (the machine is shared: the best is the machine's speed, the median what the load left of it); the
 * load average at the start and the end is recorded with them.
 */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench/bench_load.h"
#include "base/clock.h"
#include "base/rng.h"
#include "base/runtime_env.h"
#include "recon/nerf/act.h"
#include "recon/nerf/adam.h"
#include "recon/nerf/attention.h"
#include "recon/nerf/block.h"
#include "recon/nerf/hashgrid.h"
#include "recon/nerf/layernorm.h"
#include "recon/nerf/linear.h"
#include "recon/nerf/loss.h"
#include "recon/nerf/mlp.h"
#include "recon/nerf/posenc.h"
#include "recon/nerf/rayformer.h"
#include "recon/nerf/render.h"
#include "recon/nerf/shenc.h"

typedef struct row {
    char name[64];
    double best, median, bytes_per_pt, cpu_ratio;
} row;

static row rows[32];
static int n_rows;

static double now(void) { return (double)sci_clock_mono_ns() * 1e-9; }
static double cpu(void) { return (double)sci_clock_cpu_ns() * 1e-9; }

static int cmpd(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

typedef void (*bench_fn)(void *ctx);

/* Best and median wall time of `reps` runs after one warm-up; also the CPU/wall ratio (≈ cores kept busy). */
static double time_it(bench_fn f, void *ctx, int reps, double *cpu_ratio, double *median)
{
    double t[64];
    f(ctx);
    double c0 = cpu(), w0 = now();
    for (int r = 0; r < reps; r++) {
        double a = now();
        f(ctx);
        t[r] = now() - a;
    }
    double c1 = cpu(), w1 = now();
    qsort(t, reps, sizeof *t, cmpd);
    *cpu_ratio = (c1 - c0) / (w1 - w0);
    *median = t[reps / 2];
    return t[0];
}

static void add_row(const char *name, double n_points, double best, double median, double bytes_per_pt, double cr)
{
    row *r = &rows[n_rows++];
    snprintf(r->name, sizeof r->name, "%s", name);
    r->best = n_points / best;
    r->median = n_points / median;
    r->bytes_per_pt = bytes_per_pt;
    r->cpu_ratio = cr;
    printf("%-48s %8.3f Mpts/s (median %7.3f)  %7.0f B/pt  cpu/wall %.2f\n", name, r->best * 1e-6,
           r->median * 1e-6, bytes_per_pt, cr);
}

/* ---------------------------------------------------------------- per-block contexts */

#define NPTS 65536
#define NT 2

typedef struct blk {
    float *x, *y, *dy, *dx, *W, *b, *gW[NT], *gb[NT], *xhat, *rstd, *table, *gtab[NT];
    nerf_hashgrid *grid;
    nerf_i2r_shape att;
    nerf_block_shape bs;
    nerf_block_saved sv;
    float *sv_mem, *scr[NT], *lse, *qkv, *dqkv;
    size_t np;
} blk;

static void run_linear(void *c)
{
    blk *k = c;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = NPTS / NT;
        size_t r0 = (size_t)t * n;
        nerf_linear_forward(n, 32, 32, k->W, k->b, k->x + r0 * 32, 32, k->y + r0 * 32, 32);
        nerf_linear_backward(n, 32, 32, k->W, k->x + r0 * 32, 32, k->dy + r0 * 32, 32, k->dx + r0 * 32, 32, 0,
                             k->gW[t], k->gb[t]);
    }
}

static void run_layernorm(void *c)
{
    blk *k = c;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = NPTS / NT;
        size_t r0 = (size_t)t * n;
        nerf_layernorm_forward(n, 32, k->W, k->b, k->x + r0 * 32, 32, k->y + r0 * 32, 32, k->xhat + r0 * 32,
                               k->rstd + r0);
        nerf_layernorm_backward(n, 32, k->W, k->xhat + r0 * 32, k->rstd + r0, k->dy + r0 * 32, 32, k->dx + r0 * 32,
                                32, 0, k->gW[t], k->gb[t]);
    }
}

static void run_gelu(void *c)
{
    blk *k = c;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num();
        size_t n = (size_t)NPTS * 32 / NT, r0 = (size_t)t * n;
        nerf_act_forward(NERF_ACT_GELU, n, k->x + r0, k->y + r0);
        nerf_act_backward(NERF_ACT_GELU, n, k->x + r0, k->y + r0, k->dy + r0, k->dx + r0);
    }
}

static void run_gelu_fused(void *c)
{
    blk *k = c;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num();
        size_t n = (size_t)NPTS * 32 / NT, r0 = (size_t)t * n;
        nerf_act_gelu_with_grad(n, k->x + r0, k->y + r0, k->dx + r0);
    }
}

static void run_trunc_exp(void *c)
{
    blk *k = c;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num();
        size_t n = (size_t)NPTS / NT, r0 = (size_t)t * n;
        nerf_act_forward(NERF_ACT_TRUNC_EXP, n, k->x + r0, k->y + r0);
        nerf_act_backward(NERF_ACT_TRUNC_EXP, n, k->x + r0, k->y + r0, k->dy + r0, k->dx + r0);
    }
}

static void run_posenc(void *c)
{
    blk *k = c; /* 3 dims, 10 frequencies: 63 outputs (SCINeRF xyz) */
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = NPTS / NT;
        size_t r0 = (size_t)t * n;
        nerf_posenc_forward(n, 3, 10, 1, k->x + r0 * 3, k->y + r0 * 63, 63);
        nerf_posenc_backward(n, 3, 10, 1, k->x + r0 * 3, k->dy + r0 * 63, 63, k->dx + r0 * 3, 0);
    }
}

static void run_sh(void *c)
{
    blk *k = c;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = NPTS / NT;
        size_t r0 = (size_t)t * n;
        nerf_sh_forward(n, 4, k->x + r0 * 3, k->y + r0 * 16, 16);
        nerf_sh_backward(n, 4, k->x + r0 * 3, k->dy + r0 * 16, 16, k->dx + r0 * 3, 0);
    }
}

static void run_hash(void *c)
{
    blk *k = c;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = NPTS / NT;
        size_t r0 = (size_t)t * n;
        memset(k->gtab[t], 0, k->np * sizeof(float));
        nerf_hashgrid_forward(k->grid, k->table, n, k->x + r0 * 3, k->y + r0 * 32, 32);
        nerf_hashgrid_backward(k->grid, k->table, n, k->x + r0 * 3, k->dy + r0 * 32, 32, k->gtab[t], k->dx + r0 * 3);
#pragma omp barrier
#pragma omp for schedule(static)
        for (size_t j = 0; j < k->np; j++) k->gtab[0][j] += k->gtab[1][j];
    }
}

static void run_attention(void *c)
{
    blk *k = c;
    int patches = NPTS / (k->att.R * k->att.L);
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = patches / NT;
        size_t r0 = (size_t)t * n * k->att.R * k->att.L;
        nerf_i2r_forward(&k->att, n, k->qkv + r0 * 96, 96, k->y + r0 * 32, 32, k->lse + r0 * 4, k->scr[t]);
        nerf_i2r_backward(&k->att, n, k->qkv + r0 * 96, 96, k->y + r0 * 32, 32, k->lse + r0 * 4, k->dy + r0 * 32, 32,
                          k->dqkv + r0 * 96, 96, k->scr[t]);
    }
}

static void run_block(void *c)
{
    blk *k = c;
    int patches = NPTS / (k->att.R * k->att.L), rp = k->att.R * k->att.L;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = patches / NT;
        for (int p = t * n; p < (t + 1) * n; p++)
            nerf_block_forward(&k->bs, k->W, 1, (size_t)p * rp, k->x, k->y, &k->sv, k->scr[t]);
        for (int p = (t + 1) * n - 1; p >= t * n; p--)
            nerf_block_backward(&k->bs, k->W, 1, (size_t)p * rp, &k->sv, k->dy, k->dx, k->gW[t], k->scr[t]);
    }
}

typedef struct rnd {
    nerf_render_rays r;
    float *color, *dc, *ds, *drgb;
} rnd;

static void run_render(void *c)
{
    rnd *k = c;
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = k->r.n_rays / NT;
        nerf_render_rays s = k->r;
        size_t o = (size_t)t * n;
        s.n_rays = n, s.sigma += o * s.L, s.rgb += o * s.L * 3, s.delta += o * s.L, s.t = s.t ? s.t + o * s.L : NULL;
        nerf_render_forward(&s, k->color + o * 3, NULL, NULL, NULL);
        nerf_render_backward(&s, k->dc + o * 3, NULL, NULL, k->ds + o * s.L, k->drgb + o * s.L * 3, NULL);
    }
}

/* ---------------------------------------------------------------- whole network */

typedef struct train {
    nerf_rayformer *net;
    nerf_rayformer_ws *ws;
    nerf_adam *adam;
    float *P, *G, *pos, *dir, *sigma, *rgb, *dsig, *drgb, *delta, *color, *dcolor, *Y, *M;
    int patches, poses, R, L;
    double loss;
} train;

static void run_train(void *c)
{
    train *k = c;
    const int Pn = k->patches * k->poses, rays = Pn * k->R, N = rays * k->L;
    nerf_rayformer_forward(k->net, k->P, k->ws, Pn, k->pos, k->dir, k->sigma, k->rgb);
    nerf_render_rays rr = {.n_rays = rays, .L = k->L, .sigma = k->sigma, .rgb = k->rgb, .delta = k->delta,
                           .t_stop = NERF_RENDER_T_STOP};
    /* rays are [pose][patch][ray]; render all rays on both threads */
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = rays / NT;
        nerf_render_rays s = rr;
        size_t o = (size_t)t * n;
        s.n_rays = n, s.sigma += o * s.L, s.rgb += o * s.L * 3, s.delta += o * s.L;
        nerf_render_forward(&s, k->color + o * 3, NULL, NULL, NULL);
    }
    memset(k->dcolor, 0, (size_t)rays * 3 * sizeof(float));
    int pix = k->patches * k->R;
    k->loss = nerf_loss_measurement(pix, k->poses, 3, k->Y, k->M, k->color, k->dcolor);
    k->loss += nerf_loss_tv(Pn, 8, 8, 3, k->color, 0.0, 0.01, k->dcolor);
#pragma omp parallel num_threads(NT)
    {
        int t = omp_get_thread_num(), n = rays / NT;
        nerf_render_rays s = rr;
        size_t o = (size_t)t * n;
        s.n_rays = n, s.sigma += o * s.L, s.rgb += o * s.L * 3, s.delta += o * s.L;
        nerf_render_backward(&s, k->dcolor + o * 3, NULL, NULL, k->dsig + o * s.L, k->drgb + o * s.L * 3, NULL);
    }
    nerf_rayformer_backward(k->net, k->P, k->ws, k->dsig, k->drgb, k->G, NULL, NULL);
    size_t nh = nerf_rayformer_hash_param_count(k->net), np = nerf_rayformer_param_count(k->net);
    nerf_adam_step(k->adam, k->P, k->G, 0, nh, 1e-2, 1, 0);
    nerf_adam_step(k->adam, k->P, k->G, nh, np, 1e-3, 0, 0);
    (void)N;
}

/* ---------------------------------------------------------------- SCINeRF-style MLP field */

typedef struct mlpb {
    nerf_mlp *net;
    nerf_mlp_ws *ws;
    float *P, *G, *pos, *dir, *sigma, *rgb, *dsig, *drgb;
    int n, every;
} mlpb;

static void run_mlp(void *c)
{
    mlpb *k = c;
    nerf_mlp_forward(k->net, k->P, k->ws, k->n, k->pos, k->dir, k->every, k->sigma, k->rgb);
    nerf_mlp_backward(k->net, k->P, k->ws, k->dsig, k->drgb, k->G, NULL, NULL);
}

static float *falloc(size_t n, sci_rng *rng, double lo, double hi);

/* Forward + backward of the field over n points (32 samples per ray share a direction). */
static void bench_mlp(const char *name, const nerf_mlp_config *cfg, int n, int reps, sci_rng *rng)
{
    mlpb k = {.n = n, .every = 32};
    sci_error err = {0};
    if (nerf_mlp_new(&k.net, cfg, &err) < 0 || nerf_mlp_ws_new(&k.ws, k.net, n, NT, &err) < 0) {
        fprintf(stderr, "bench_nerf: %s: %s\n", name, err.msg);
        return;
    }
    size_t np = nerf_mlp_param_count(k.net);
    k.P = falloc(np, NULL, 0, 0), k.G = falloc(np, NULL, 0, 0);
    nerf_mlp_init(k.net, k.P, 2);
    k.pos = falloc(3 * (size_t)n, rng, -1, 1), k.dir = falloc(3 * (size_t)n, NULL, 0, 0);
    for (int r = 0; r < n; r++) k.dir[3 * r + 2] = -1.0f;
    k.sigma = falloc(n, NULL, 0, 0), k.rgb = falloc(3 * (size_t)n, NULL, 0, 0);
    k.dsig = falloc(n, rng, -1, 1), k.drgb = falloc(3 * (size_t)n, rng, -1, 1);
    double cr, med, b = time_it(run_mlp, &k, reps, &cr, &med);
    char label[64];
    snprintf(label, sizeof label, "%s, %d pts", name, n);
    add_row(label, n, b, med, (double)nerf_mlp_ws_bytes(k.ws) / n, cr);
    free(k.P), free(k.G), free(k.pos), free(k.dir), free(k.sigma), free(k.rgb), free(k.dsig), free(k.drgb);
    nerf_mlp_ws_free(k.ws);
    nerf_mlp_free(k.net);
}

static float *falloc(size_t n, sci_rng *rng, double lo, double hi)
{
    float *p = malloc(n * sizeof *p);
    for (size_t i = 0; i < n; i++) p[i] = rng ? (float)(lo + (hi - lo) * sci_rng_uniform(rng)) : 0.0f;
    return p;
}

/* What the RayFormer step measured, for the report. */
typedef struct step_result {
    int N;          /* points per step */
    double best, median; /* s per step */
    double mib;     /* peak RSS after the step, MiB */
    size_t np;      /* parameters */
} step_result;

/* The RayFormer training step (fwd + render + loss + bwd + Adam) at 65,536 points; its row added. 0, or -1 with the
 * error printed. */
static int bench_train(const nerf_rayformer_config *cfg, sci_rng *rng, step_result *out)
{
    train tr = {.patches = 4, .poses = 8, .R = 64, .L = 32};
    sci_error err = {0};
    if (nerf_rayformer_new(&tr.net, cfg, &err) < 0) return fprintf(stderr, "%s\n", err.msg), -1;
    const int Pn = tr.patches * tr.poses, rays = Pn * tr.R, N = rays * tr.L;
    size_t np = nerf_rayformer_param_count(tr.net);
    int64_t rss0 = sci_clock_peak_rss_bytes();
    tr.P = falloc(np, NULL, 0, 0), tr.G = falloc(np, NULL, 0, 0);
    nerf_rayformer_init(tr.net, tr.P, 1);
    if (nerf_rayformer_ws_new(&tr.ws, tr.net, Pn, NT, &err) < 0) return fprintf(stderr, "%s\n", err.msg), -1;
    nerf_adam_config ac = {.beta1 = 0.9, .beta2 = 0.99, .eps = 1e-15, .weight_decay = 0};
    if (nerf_adam_new(&tr.adam, np, &ac, &err) < 0) return fprintf(stderr, "%s\n", err.msg), -1;
    tr.pos = falloc(3 * (size_t)N, rng, -1, 1), tr.dir = falloc(3 * (size_t)rays, NULL, 0, 0);
    for (int r = 0; r < rays; r++) tr.dir[3 * r + 2] = -1.0f;
    tr.sigma = falloc(N, NULL, 0, 0), tr.rgb = falloc(3 * (size_t)N, NULL, 0, 0), tr.dsig = falloc(N, NULL, 0, 0);
    tr.drgb = falloc(3 * (size_t)N, NULL, 0, 0), tr.delta = falloc(N, rng, 0.02, 0.04);
    tr.color = falloc(3 * (size_t)rays, NULL, 0, 0), tr.dcolor = falloc(3 * (size_t)rays, NULL, 0, 0);
    tr.Y = falloc(3 * (size_t)tr.patches * tr.R, rng, 0, 4), tr.M = falloc((size_t)tr.poses * tr.patches * tr.R, rng, 0, 1);
    double cr, med;
    double s = time_it(run_train, &tr, 15, &cr, &med);
    int64_t rss = sci_clock_peak_rss_bytes();
    double mib = (double)rss / (1 << 20);
    printf("RayFormer 2 blocks, width 32, %d points/step: best %.1f ms/step, median %.1f ms, peak RSS %.0f MiB "
           "(%.0f MiB before the network), workspace %.0f MiB, %zu parameters\n",
           N, s * 1e3, med * 1e3, mib, (double)rss0 / (1 << 20), (double)nerf_rayformer_ws_bytes(tr.ws) / (1 << 20),
           np);
    add_row("RayFormer step (fwd+render+loss+bwd+Adam)", N, s, med, (double)(rss - rss0) / N, cr);
    *out = (step_result){.N = N, .best = s, .median = med, .mib = mib, .np = np};
    nerf_rayformer_ws_free(tr.ws);
    nerf_adam_free(tr.adam);
    nerf_rayformer_free(tr.net);
    free(tr.P), free(tr.G), free(tr.pos), free(tr.dir), free(tr.sigma), free(tr.rgb), free(tr.dsig), free(tr.drgb);
    free(tr.delta), free(tr.color), free(tr.dcolor), free(tr.Y), free(tr.M);
    return 0;
}

/* The per-point blocks: linear, layernorm, GELU, trunc_exp, encodings; k's buffers allocated here. */
static void bench_blocks_pointwise(blk *k, int reps, sci_rng *rng)
{
    double cr, med, s;
    size_t big = (size_t)NPTS * 96;
    k->x = falloc(big, rng, -1, 1), k->y = falloc(big, NULL, 0, 0), k->dy = falloc(big, rng, -1, 1);
    k->dx = falloc(big, NULL, 0, 0), k->W = falloc(64 * 1024, rng, -0.2, 0.2), k->b = falloc(1024, rng, -0.1, 0.1);
    for (int t = 0; t < NT; t++) k->gW[t] = falloc(64 * 1024, NULL, 0, 0), k->gb[t] = falloc(1024, NULL, 0, 0);
    k->xhat = falloc((size_t)NPTS * 32, NULL, 0, 0), k->rstd = falloc(NPTS, NULL, 0, 0);
    s = time_it(run_linear, k, reps, &cr, &med);
    add_row("linear 32→32 (sgemm)", NPTS, s, med, 4.0 * (32 + 32), cr);
    s = time_it(run_layernorm, k, reps, &cr, &med);
    add_row("layernorm 32", NPTS, s, med, 4.0 * (32 + 1), cr);
    s = time_it(run_gelu, k, reps, &cr, &med);
    add_row("GELU ×32 channels (forward, backward)", NPTS, s, med, 4.0 * 32, cr);
    s = time_it(run_gelu_fused, k, reps, &cr, &med);
    add_row("GELU ×32 channels (value + derivative, 1 pass)", NPTS, s, med, 4.0 * 64, cr);
    s = time_it(run_trunc_exp, k, reps, &cr, &med);
    add_row("trunc_exp", NPTS, s, med, 4.0, cr);
    for (size_t i = 0; i < (size_t)NPTS * 3; i++) k->x[i] = (float)sci_rng_uniform(rng);
    s = time_it(run_posenc, k, reps, &cr, &med);
    add_row("frequency encoding 3→63", NPTS, s, med, 4.0 * 63, cr);
    s = time_it(run_sh, k, reps, &cr, &med);
    add_row("SH degree 4 (16)", NPTS, s, med, 4.0 * 16, cr);
}

/* The hash grid (at RayFormer's grid settings), the I²R-MSA core and the whole transformer block, on k's buffers
 * from bench_blocks_pointwise. */
static void bench_blocks_network(blk *k, const nerf_hashgrid_config *grid, int reps, sci_rng *rng)
{
    double cr, med, s;
    sci_error err = {0};
    size_t big = (size_t)NPTS * 96;
    nerf_hashgrid_config hc = *grid;
    nerf_hashgrid_new(&k->grid, &hc, &err);
    k->np = nerf_hashgrid_param_count(k->grid);
    k->table = falloc(k->np, rng, -1e-4, 1e-4);
    for (int t = 0; t < NT; t++) k->gtab[t] = falloc(k->np, NULL, 0, 0);
    s = time_it(run_hash, k, reps, &cr, &med);
    add_row("hash grid 16×2, T=2^16", NPTS, s, med, 4.0 * (3 + 32), cr);
    k->att = (nerf_i2r_shape){.C = 32, .heads = 2, .L = 32, .R = 64};
    k->qkv = falloc(big, rng, -2, 2), k->dqkv = falloc(big, NULL, 0, 0), k->lse = falloc((size_t)NPTS * 4, NULL, 0, 0);
    const nerf_block_shape scr_shape = {.att = k->att, .hidden = 64, .inter_gate = 1};
    for (int t = 0; t < NT; t++) k->scr[t] = falloc(nerf_block_scratch_floats(&scr_shape, 2048), NULL, 0, 0);
    s = time_it(run_attention, k, reps, &cr, &med);
    add_row("I²R-MSA core (2 heads/path, L=32, R=64)", NPTS, s, med, 4.0 * (96 + 32 + 4), cr);
    k->bs = (nerf_block_shape){.att = k->att, .hidden = 64, .inter_gate = 1}; /* as RayFormer's default: gated */
    free(k->W);
    k->W = falloc(nerf_block_param_count(&k->bs), NULL, 0, 0);
    nerf_block_init(&k->bs, k->W, 2, rng);
    for (int t = 0; t < NT; t++) free(k->gW[t]), k->gW[t] = falloc(nerf_block_param_count(&k->bs), NULL, 0, 0);
    k->sv_mem = falloc((size_t)NPTS * nerf_block_saved_floats(&k->bs), NULL, 0, 0);
    nerf_block_saved_bind(&k->bs, NPTS, k->sv_mem, &k->sv);
    s = time_it(run_block, k, reps, &cr, &med);
    add_row("I²R transformer block (C=32, FFN 64, gated inter-ray path)", NPTS, s, med,
            4.0 * nerf_block_saved_floats(&k->bs), cr);
}

/* Volume rendering of NPTS / 32 rays, on k's buffers. */
static void bench_render(blk *k, int reps, sci_rng *rng)
{
    double cr, med, s;
    rnd rd = {.r = {.n_rays = NPTS / 32, .L = 32, .sigma = k->x, .rgb = k->dy, .delta = k->b, .t_stop = 1e-4f}};
    float *delta = falloc(NPTS, rng, 0.01, 0.05);
    rd.r.delta = delta;
    for (size_t i = 0; i < (size_t)NPTS; i++) k->x[i] = (float)(5 * sci_rng_uniform(rng));
    rd.color = falloc((size_t)NPTS / 32 * 3, NULL, 0, 0), rd.dc = falloc((size_t)NPTS / 32 * 3, rng, -1, 1);
    rd.ds = k->y, rd.drgb = k->dx;
    s = time_it(run_render, &rd, reps, &cr, &med);
    add_row("volume rendering (32 samples/ray)", NPTS, s, med, 0.0, cr);
}

static void bench_report(FILE *f, const step_result *st, int64_t rss_all, const char *load0, const char *load1)
{
    fprintf(f, "| forward + backward, %d threads | Mpoints/s best | median | bytes/point | CPU/wall |\n"
               "|---|---:|---:|---:|---:|\n", NT);
    for (int i = 0; i < n_rows; i++)
        fprintf(f, "| %s | %.3f | %.3f | %.0f | %.2f |\n", rows[i].name, rows[i].best * 1e-6,
                rows[i].median * 1e-6, rows[i].bytes_per_pt, rows[i].cpu_ratio);
    fprintf(f, "\nRayFormer step: %d points (4 patches × 64 pixels × 8 poses × 32 samples), best %.1f ms, median "
               "%.1f ms; peak RSS %.0f MiB during the step (whole run %.0f MiB), %zu parameters. bytes/point: "
               "peak RSS growth of the step per point for the step, saved activations + workspace for the MLP "
               "fields, inputs + outputs for the blocks. Load average %s at the start, %s at the end (2 cores, "
               "shared with other jobs).\n",
            st->N, st->best * 1e3, st->median * 1e3, st->mib, (double)rss_all / (1 << 20), st->np, load0, load1);
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* the BLAS kernels and OpenMP waiting that scicap and scicapd run with */
    sci_rng rng;
    sci_rng_seed(&rng, 1234, 9);
    omp_set_dynamic(0);
    int reps = 9;
    char load0[64], load1[64];
    bench_loadavg(load0, sizeof load0);
    printf("nerf blocks, %d points per call, %d threads; load average %s\n", NPTS, NT, load0);

    /* whole network first, so that peak RSS is its own */
    nerf_rayformer_config cfg = nerf_rayformer_config_default();
    step_result st;
    if (bench_train(&cfg, &rng, &st) < 0)
        return 1;

    /* the SCINeRF-style field: the paper's network and the hash variant */
    nerf_mlp_config mc = nerf_mlp_config_scinerf();
    bench_mlp("MLP field: SCINeRF freq, 8×256 skip 4", &mc, 8192, 5, &rng);
    mc = nerf_mlp_config_hash();
    bench_mlp("MLP field: hash 16×2, 2×64, SH", &mc, NPTS, reps, &rng);

    /* per-block */
    blk k = {0};
    bench_blocks_pointwise(&k, reps, &rng);
    bench_blocks_network(&k, &cfg.grid, reps, &rng);
    bench_render(&k, reps, &rng);
    bench_loadavg(load1, sizeof load1);
    int64_t rss_all = sci_clock_peak_rss_bytes();

    FILE *f = fopen("bench/results/nerf.md", "w");
    if (f) {
        bench_report(f, &st, rss_all, load0, load1);
        fclose(f);
    }
    printf("peak RSS of the whole run %.0f MiB; load average %s → %s\n", (double)rss_all / (1 << 20), load0, load1);
    return 0;
}
