/* bench_pnp_ffdnet — PnP-FFDNet in C against the same recipe in PyTorch-CPU, side by side in one run: the same
 * threads, the same inputs (drop40 snapshot 1, exported to a temporary folder that bench/ffdnet_torch.py reads).
 *
 * Prints and writes bench/results/pnp_ffdnet.md:
 *   1. the machine's measured single-precision peak (AVX-512 FMA chains, or AVX2, on the benchmark's threads),
 *   2. the FFDNet denoiser on one 256×256 frame: median time, direct-convolution-equivalent GFLOP/s and its
 *      fraction of the peak (C), and the same for PyTorch, one frame and eight frames as one batch,
 *   3. the whole GAP-FFDNet solve (σ = 50, 25, 12, 6 × 10 iterations; the balanced preset): time and PSNR,
 *   4. peak memory (RSS) of each side's process.
 * Options: --threads N (default 2), --repeat R (default 7), --no-torch. Needs $SCICAP_DATA (drop40_cacti.mat,
 * ffdnet/net_gray.pth); the PyTorch side needs Debian's python3-torch (/usr/bin/python3), else it is left out
 * and said so. A benchmark, not a test: it measures and reports.
 */
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/clock.h"
#include "base/runtime_env.h"
#include "io/matfile.h"
#include "recon/cnn/ffdnet.h"
#include "recon/metrics.h"
#include "recon/pnp_ffdnet.h"
#include "recon/solver.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
/* 16 independent FMA chains per thread: enough to fill two FMA ports at four cycles' latency. */
__attribute__((target("avx512f"))) static float fma_chains512(long n)
{
    __m512 a[16];
    const __m512 b = _mm512_set1_ps(1.0000001f), c = _mm512_set1_ps(1e-7f);
    for (int i = 0; i < 16; i++)
        a[i] = _mm512_set1_ps((float)i);
    for (long k = 0; k < n; k++)
#pragma GCC unroll 16
        for (int i = 0; i < 16; i++)
            a[i] = _mm512_fmadd_ps(a[i], b, c);
    __m512 s = a[0];
    for (int i = 1; i < 16; i++)
        s = _mm512_add_ps(s, a[i]);
    return _mm512_reduce_add_ps(s);
}
__attribute__((target("avx2,fma"))) static float fma_chains256(long n)
{
    __m256 a[16];
    const __m256 b = _mm256_set1_ps(1.0000001f), c = _mm256_set1_ps(1e-7f);
    for (int i = 0; i < 16; i++)
        a[i] = _mm256_set1_ps((float)i);
    for (long k = 0; k < n; k++)
#pragma GCC unroll 16
        for (int i = 0; i < 16; i++)
            a[i] = _mm256_fmadd_ps(a[i], b, c);
    float o[8];
    __m256 s = a[0];
    for (int i = 1; i < 16; i++)
        s = _mm256_add_ps(s, a[i]);
    _mm256_storeu_ps(o, s);
    return o[0];
}
#endif

/* GFLOP/s of FMA chains on `threads` threads, best of three; *isa names the instructions. */
static double peak_gflops(int threads, const char **isa)
{
    *isa = "none measured";
#if defined(__x86_64__) && defined(__GNUC__)
    const int wide = __builtin_cpu_supports("avx512f");
    if (!wide && !__builtin_cpu_supports("fma"))
        return NAN;
    *isa = wide ? "AVX-512 FMA" : "AVX2 FMA";
    const long n = 20000000;
    double best = 0;
    volatile float sink = 0;
    for (int rep = 0; rep < 3; rep++) {
        int64_t t0 = sci_clock_mono_ns();
        float s = 0;
#pragma omp parallel num_threads(threads) reduction(+ : s)
        s += wide ? fma_chains512(n) : fma_chains256(n);
        double dt = sci_clock_s(t0, sci_clock_mono_ns());
        sink += s;
        double g = (double)threads * n * 16 * (wide ? 16 : 8) * 2 / dt / 1e9;
        best = g > best ? g : best;
    }
    (void)sink;
    return best;
#else
    (void)threads;
    return NAN;
#endif
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int write_floats(const char *dir, const char *name, const float *v, size_t n)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    if (!f)
        return -errno;
    size_t w = fwrite(v, sizeof *v, n, f);
    return fclose(f) == 0 && w == n ? 0 : -EIO;
}

/* The problem and recipe for bench/ffdnet_torch.py; frames planar (n × h × w), rows contiguous, as the cubes. */
static int export_problem(const char *dir, const sci_problem *p, const char *weights, const sci_pnp_params *q)
{
    const int w = p->mask->w, h = p->mask->h, n = p->mask->n;
    json_t *sig = json_array(), *its = json_array();
    for (int i = 0; i < q->sigma.n; i++) {
        json_array_append_new(sig, json_real(q->sigma.v[i]));
        json_array_append_new(its, json_integer(q->iters / q->sigma.n + (i < q->iters % q->sigma.n)));
    }
    json_t *meta = json_pack("{s:i,s:i,s:i,s:o,s:o,s:f,s:b,s:s}", "w", w, "h", h, "n", n, "sigma", sig, "iters",
                             its, "lambda", q->lambda, "accelerate", q->accelerate, "weights", weights);
    char path[512];
    snprintf(path, sizeof path, "%s/meta.json", dir);
    int rc = json_dump_file(meta, path, JSON_INDENT(1)) == 0 ? 0 : -EIO;
    json_decref(meta);
    if (rc == 0)
        rc = write_floats(dir, "mask.f32", p->mask->data, sci_cube_count(p->mask));
    if (rc == 0)
        rc = write_floats(dir, "meas.f32", p->meas->data, sci_cube_count(p->meas));
    if (rc == 0 && p->truth)
        rc = write_floats(dir, "truth.f32", p->truth->data, sci_cube_count(p->truth));
    return rc;
}

/* bench/ffdnet_torch.py bench on the exported folder: its JSON line, or NULL (reason printed). */
static json_t *run_torch(const char *dir, int threads, int repeat)
{
    if (access("/usr/bin/python3", X_OK) != 0 || system("/usr/bin/python3 -c 'import torch' 2>/dev/null") != 0) {
        printf("PyTorch side left out: /usr/bin/python3 cannot import torch (Debian's python3-torch)\n");
        return NULL;
    }
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "/usr/bin/python3 bench/ffdnet_torch.py bench --dir '%s' --threads %d --repeat %d",
             dir, threads, repeat);
    FILE *f = popen(cmd, "r");
    if (!f)
        return NULL;
    char line[8192], last[8192] = "";
    while (fgets(line, sizeof line, f))
        if (line[0] == '{')
            snprintf(last, sizeof last, "%s", line);
    int st = pclose(f);
    json_t *j = last[0] ? json_loads(last, 0, NULL) : NULL;
    if (!j)
        printf("PyTorch side failed (exit status %d)\n", st);
    return j;
}

static double jnum(const json_t *j, const char *key)
{
    const json_t *v = j ? json_object_get(j, key) : NULL;
    return json_is_number(v) ? json_number_value(v) : NAN;
}

/* What one run measured, for the report. */
typedef struct pnp_bench {
    int threads, w, h;
    const char *isa;       /* the instructions the peak was measured with */
    double peak;           /* GFLOP/s */
    double load0[3], load1[3];
    const cnn_ffdnet *net;
    const cnn_ffdnet_plan *plan;
    double c_frame, flop, c_solve, c_psnr, c_rss;
    const json_t *tj;      /* PyTorch's JSON line, or NULL */
    double pt_frame, pt_batch, pt_solve, pt_psnr, pt_rss;
} pnp_bench;

/* --threads, --repeat, --no-torch. 0, or the exit status 2 (the usage printed for an unknown argument). */
static int bench_args(int argc, char **argv, int *threads, int *repeat, int *torch)
{
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            *threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--repeat") && i + 1 < argc)
            *repeat = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--no-torch"))
            *torch = 0;
        else {
            fprintf(stderr, "usage: bench_pnp_ffdnet [--threads N] [--repeat R] [--no-torch]\n");
            return 2;
        }
    }
    if (*threads < 1 || *repeat < 1)
        return 2;
    return 0;
}

/* The median time of `repeat` denoises of the truth's first frame (after one warm-up), s; t: repeat slots. */
static double bench_denoiser(cnn_ffdnet_plan *plan, const sci_problem *p, float *frame, double *t, int repeat)
{
    cnn_ffdnet_denoise(plan, p->truth->data, 25 / 255.0f, frame); /* warm-up */
    for (int r = 0; r < repeat; r++) {
        int64_t t0 = sci_clock_mono_ns();
        cnn_ffdnet_denoise(plan, p->truth->data, 25 / 255.0f, frame);
        t[r] = sci_clock_s(t0, sci_clock_mono_ns());
    }
    qsort(t, (size_t)repeat, sizeof *t, cmp_double);
    return t[repeat / 2];
}

/* The C solve at PnP-SCI's recipe (the one the PyTorch script runs), into res; its time in *secs. */
static int bench_c_solve(const sci_problem *p, const char *weights, int threads, sci_pnp_params *q,
                         sci_result *res, double *secs)
{
    const solver_ops *m = &sci_pnp_ffdnet_solver;
    sci_pnp_params_default(q);
    /* PnP-SCI's recipe, the one the PyTorch script runs: 40 iterations over σ 50, 25, 12, 6 */
    q->iters = 40;
    q->sigma = (solver_values){4, {50, 25, 12, 6}};
    snprintf(q->weights, sizeof q->weights, "%s", weights);
    q->threads = threads;
    q->ssim_every = 0;
    int64_t s0 = sci_clock_mono_ns();
    int rc = solver_run(m, p, q, NULL, res);
    *secs = sci_clock_s(s0, sci_clock_mono_ns());
    return rc;
}

/* The PyTorch side on the problem exported to a temporary folder (removed after): its JSON line, or NULL. */
static json_t *bench_torch(const sci_problem *p, const char *weights, const sci_pnp_params *q, int threads,
                           int repeat)
{
    json_t *tj = NULL;
    char dir[] = "/tmp/bench_pnp_ffdnet.XXXXXX";
    if (mkdtemp(dir)) {
        if (export_problem(dir, p, weights, q) == 0)
            tj = run_torch(dir, threads, repeat);
        char cmd[256];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
        if (system(cmd) != 0)
            fprintf(stderr, "bench_pnp_ffdnet: could not remove %s\n", dir);
    }
    return tj;
}

/* v printed with fmt into one of a few rotating buffers, or "—" when it is not a number (PyTorch not run). */
static const char *num(const char *fmt, double v)
{
    static char buf[8][32];
    static int next;
    char *b = buf[next++ % 8];
    if (isnan(v))
        return "—";
    snprintf(b, sizeof buf[0], fmt, v);
    return b;
}

static void bench_report(FILE *f, const pnp_bench *b)
{
    const double c_frame = b->c_frame, flop = b->flop, peak = b->peak;
    const double pt_frame = b->pt_frame, pt_batch = b->pt_batch, pt_best = fmin(pt_frame, pt_batch);
    fprintf(f, "\nMeasured by `make bench` (bench/bench_pnp_ffdnet.c with bench/ffdnet_torch.py): drop40 snapshot "
               "1 (256×256×8), grey FFDNet (15 layers, 64 features, %.2f G multiply-adds a frame), %d threads "
               "for both; the machine's single-precision peak measured by %s chains: %.0f GFLOP/s.\n\n",
            cnn_ffdnet_macs(b->net, b->w, b->h) / 1e9, b->threads, b->isa, peak);
    fprintf(f, "| | C (%s) | PyTorch-CPU %s | C faster by |\n|---|---:|---:|---:|\n", cnn_ffdnet_plan_kernel(b->plan),
            b->tj ? json_string_value(json_object_get(b->tj, "torch")) : "(not run)");
    fprintf(f, "| denoiser, s per 256×256 frame | %.4f | %s | %s |\n", c_frame, num("%.4f", pt_frame),
            num("%.2f×", pt_frame / c_frame));
    fprintf(f, "| denoiser, s per frame in a batch of 8 | %.4f | %s | %s |\n", c_frame, num("%.4f", pt_batch),
            num("%.2f×", pt_batch / c_frame));
    fprintf(f, "| GFLOP/s (direct-convolution equivalent) | %.0f | %s | |\n", flop / c_frame / 1e9,
            num("%.0f", flop / pt_best / 1e9));
    fprintf(f, "| fraction of the measured peak | %.0f %% | %s | |\n", 100 * flop / c_frame / 1e9 / peak,
            num("%.0f %%", 100 * flop / pt_best / 1e9 / peak));
    fprintf(f, "| whole solve (40 iterations), s | %.2f | %s | %s |\n", b->c_solve, num("%.2f", b->pt_solve),
            num("%.2f×", b->pt_solve / b->c_solve));
    fprintf(f, "| PSNR, dB (peak = frame max) | %.2f | %s | |\n", b->c_psnr, num("%.2f", b->pt_psnr));
    fprintf(f, "| peak RSS of the process, MiB | %.0f | %s | |\n", b->c_rss, num("%.0f", b->pt_rss));
    fprintf(f, "\nLoad average %.2f %.2f %.2f at the start, %.2f %.2f %.2f at the end (2 cores). The C "
               "convolution is Winograd F(4×4, 3×3): 4× fewer multiplications than the direct convolution "
               "PyTorch runs, so its direct-equivalent rate can exceed the peak.\n",
            b->load0[0], b->load0[1], b->load0[2], b->load1[0], b->load1[1], b->load1[2]);
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv);
    int threads = 2, repeat = 7, torch = 1;
    int rc = bench_args(argc, argv, &threads, &repeat, &torch);
    if (rc != 0)
        return rc;
    omp_set_num_threads(threads);
    const char *data = getenv("SCICAP_DATA");
    char mat[1024], weights[1024];
    snprintf(mat, sizeof mat, "%s/drop40_cacti.mat", data ? data : "../shared/data");
    snprintf(weights, sizeof weights, "%s/ffdnet/net_gray.pth", data ? data : "../shared/data");
    pnp_bench b = {.threads = threads};
    getloadavg(b.load0, 3);

    b.peak = peak_gflops(threads, &b.isa);
    printf("single-precision peak (%s, %d threads): %.1f GFLOP/s\n", b.isa, threads, b.peak);

    sci_problem **probs = NULL;
    int k = 0;
    sci_error err = {0};
    cnn_ffdnet *net = NULL;
    if (sci_mat_read(mat, 255, &probs, &k, &err) < 0 || cnn_ffdnet_load(weights, &net, &err) < 0) {
        fprintf(stderr, "bench_pnp_ffdnet: %s\n", err.msg);
        return 1;
    }
    const sci_problem *p = probs[0];
    const int w = p->mask->w, h = p->mask->h;
    cnn_ffdnet_plan *plan = NULL;
    if (cnn_ffdnet_plan_new(net, w, h, threads, &plan, &err) < 0) {
        fprintf(stderr, "bench_pnp_ffdnet: %s\n", err.msg);
        return 1;
    }
    b.net = net, b.plan = plan, b.w = w, b.h = h;
    const size_t fs = (size_t)w * h;
    float *frame = malloc(fs * sizeof *frame);
    double *t = malloc((size_t)repeat * sizeof *t);
    b.c_frame = bench_denoiser(plan, p, frame, t, repeat);
    b.flop = 2 * cnn_ffdnet_macs(net, w, h);
    printf("C denoiser (%s): %.4f s per %dx%d frame, %.1f GFLOP/s direct-equivalent (%.0f %% of peak)\n",
           cnn_ffdnet_plan_kernel(plan), b.c_frame, w, h, b.flop / b.c_frame / 1e9,
           100 * b.flop / b.c_frame / 1e9 / b.peak);

    sci_pnp_params q;
    sci_result res = {0};
    if (bench_c_solve(p, weights, threads, &q, &res, &b.c_solve) < 0) {
        fprintf(stderr, "bench_pnp_ffdnet: %s\n", res.error.msg);
        return 1;
    }
    b.c_psnr = res.trace.e[res.trace.len - 1].psnr;
    b.c_rss = sci_clock_peak_rss_bytes() / 1048576.0;
    printf("C solve: %.2f s, PSNR %.2f dB (peak = frame max), peak RSS %.0f MiB\n", b.c_solve, b.c_psnr, b.c_rss);

    json_t *tj = torch ? bench_torch(p, weights, &q, threads, repeat) : NULL;
    b.tj = tj;
    b.pt_frame = jnum(tj, "denoise_frame_s"), b.pt_batch = jnum(tj, "denoise_batch_frame_s");
    b.pt_solve = jnum(tj, "solve_s"), b.pt_psnr = jnum(tj, "psnr"), b.pt_rss = jnum(tj, "peak_rss_mib");
    getloadavg(b.load1, 3);
    if (tj)
        printf("PyTorch %s: %.4f s per frame (%.4f in a batch of %d), solve %.2f s, PSNR %.2f dB, peak RSS %.0f MiB\n",
               json_string_value(json_object_get(tj, "torch")), b.pt_frame, b.pt_batch, p->mask->n, b.pt_solve,
               b.pt_psnr, b.pt_rss);

    FILE *md = fopen("bench/results/pnp_ffdnet.md", "w");
    bench_report(stdout, &b);
    if (md) {
        bench_report(md, &b);
        fclose(md);
    }
    json_decref(tj);
    sci_result_free_contents(&res);
    free(frame);
    free(t);
    cnn_ffdnet_plan_free(plan);
    cnn_ffdnet_free(net);
    sci_problem_array_free(probs, k);
    return 0;
}
