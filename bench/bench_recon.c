/* bench_recon — what GAP-TV and ADMM-TV cost on the drop40 benchmark (256×256×8), and what accuracy that buys.
 *
 * Prints and writes bench/results/recon.md:
 *   1. plain memcpy bandwidth on this machine (the ceiling for streaming code),
 *   2. 100 GAP-TV iterations: best-of-5 wall time, time per iteration, and the effective bandwidth of the
 *      algorithm's array traffic (bytes the textbook form reads and writes per iteration / time),
 *   3. accuracy against time: PSNR (both peak conventions), SSIM and wall time after 10, 20, 50, 100 and 200
 *      iterations for both methods.
 * A benchmark, not a test: it measures and reports, it does not pass or fail on speed.
 */
#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/runtime_env.h"
#include "io/matfile.h"
#include "recon/gaptv.h"
#include "recon/metrics.h"
#include "recon/solver.h"

static double memcpy_gbs(void)
{
    const size_t bytes = (size_t)256 << 20;
    char *a = malloc(bytes), *b = malloc(bytes);
    if (!a || !b)
        return NAN;
    memset(a, 1, bytes);
    memset(b, 2, bytes);
    double best = 1e30;
    for (int rep = 0; rep < 5; rep++) {
        int64_t t0 = sci_clock_mono_ns();
        memcpy(b, a, bytes);
        double s = sci_clock_s(t0, sci_clock_mono_ns());
        best = s < best ? s : best;
    }
    volatile char sink = b[bytes / 2];
    (void)sink;
    free(a);
    free(b);
    return 2.0 * bytes / best * 1e-9; /* read + write */
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* as scicap and scicapd run */
    const char *dir = getenv("SCICAP_DATA");
    char path[4096];
    snprintf(path, sizeof path, "%s/drop40_cacti.mat", dir && *dir ? dir : "../shared/data");
    sci_problem **p;
    int k;
    sci_error err = {0};
    if (sci_mat_read(path, 255, &p, &k, &err) < 0) {
        fprintf(stderr, "bench_recon: %s\n", err.msg);
        return 1;
    }
    sci_problem *prob = p[0];
    const int w = prob->mask->w, h = prob->mask->h, n = prob->mask->n;
    printf("drop40 snapshot 1: %dx%dx%d, %d OpenMP threads\n", w, h, n, omp_get_max_threads());

    double mcpy = memcpy_gbs();
    printf("memcpy bandwidth (256 MiB, read+write): %.1f GB/s\n", mcpy);

    /* Solver time alone: no truth, so the tracer computes no metrics. */
    sci_cube *truth = prob->truth;
    prob->truth = NULL;
    sci_gaptv_params gp;
    sci_gaptv_params_default(&gp);
    double best = 1e30;
    for (int rep = 0; rep < 6; rep++) { /* the first run warms threads and pages */
        sci_result r = {0};
        int64_t t0 = sci_clock_mono_ns();
        if (sci_gaptv_solve(prob, &gp, &r, NULL, NULL) < 0) {
            fprintf(stderr, "bench_recon: %s\n", r.error.msg);
            return 1;
        }
        double s = sci_clock_s(t0, sci_clock_mono_ns());
        if (rep > 0 && s < best)
            best = s;
        sci_result_free_contents(&r);
    }
    prob->truth = truth;
    /* Array traffic of one iteration in the textbook form, in floats per pixel: A(x) reads x and M (2N) and
     * writes ŷ; the residual step touches y, ŷ, ȳ, Φ, r (6); per frame the data step reads M, r, x and writes x
     * (4N... counted 3N + N); each of the T−1 dual passes reads f, z_h, z_v and writes z_h, z_v (5N each); the
     * last pass reads f and writes u (2N). */
    const double P = (double)w * h, T = gp.tv_iters;
    const double floats = 2 * n + 1 + 6 + 4 * n + 5 * n * (T - 1) + 2 * n;
    const double bytes_iter = floats * P * 4;
    double per_iter = best / gp.iters;
    printf("GAP-TV %d iterations: %.4f s (best of 5), %.3f ms per iteration, effective bandwidth %.1f GB/s "
           "(%.1f MB of array traffic per iteration; memcpy %.1f GB/s)\n",
           gp.iters, best, per_iter * 1e3, bytes_iter / per_iter * 1e-9, bytes_iter * 1e-6, mcpy);

    const int iters[] = {10, 20, 50, 100, 200};
    FILE *md = fopen("bench/results/recon.md", "w");
    if (md) {
        fprintf(md, "Measured by `make bench` (bench/bench_recon.c) on drop40 snapshot 1 (256×256×8), %d threads.\n\n",
                omp_get_max_threads());
        fprintf(md, "| what | figure |\n|---|---|\n| memcpy bandwidth (read+write) | %.1f GB/s |\n", mcpy);
        fprintf(md, "| GAP-TV, 100 iterations (best of 5) | %.3f s |\n| time per iteration | %.3f ms |\n", best,
                per_iter * 1e3);
        fprintf(md, "| effective bandwidth of the array traffic | %.1f GB/s (%.1f MB per iteration) |\n\n",
                bytes_iter / per_iter * 1e-9, bytes_iter * 1e-6);
        fprintf(md, "Accuracy against time (PSNR averaged over the 8 frames; SSIM Gaussian 11×11, σ 1.5):\n\n");
        fprintf(md, "| method | iterations | wall time (s) | PSNR dB (peak = frame max) | PSNR dB (peak = 1) | SSIM |\n");
        fprintf(md, "|---|---:|---:|---:|---:|---:|\n");
    }
    printf("\n%-8s %6s %10s %12s %12s %8s\n", "method", "iters", "wall s", "PSNR fmax", "PSNR pk1", "SSIM");
    /* every method that needs no camera (recon/solver.h), at its defaults but the iterations, no trace metrics but
     * the last row's */
    for (const solver_ops *const *m = solver_list(NULL); *m; m++)
        for (size_t i = 0; i < sizeof iters / sizeof iters[0] && !((*m)->caps & SOLVER_NEEDS_CAMERA); i++) {
            sci_result r = {0};
            void *q = solver_settings_new(*m);
            json_t *set = json_pack("{s:i, s:i, s:i}", "iters", iters[i], "metrics_every", 0, "ssim_every", 0);
            int rc = q && set ? solver_settings_from_json(*m, q, set, NULL, "settings", &r.error) : -ENOMEM;
            if (rc == 0)
                rc = solver_run(*m, prob, q, NULL, &r);
            json_decref(set);
            solver_settings_free(q);
            if (rc < 0) {
                fprintf(stderr, "bench_recon: %s\n", r.error.msg);
                return 1;
            }
            const sci_trace_entry *e = &r.trace.e[r.trace.len - 1];
            printf("%-8s %6d %10.4f %12.2f %12.2f %8.4f\n", r.method, iters[i], e->wall_s, e->psnr, e->psnr_peak1,
                   e->ssim);
            if (md)
                fprintf(md, "| %s | %d | %.4f | %.2f | %.2f | %.4f |\n", r.method, iters[i], e->wall_s, e->psnr,
                        e->psnr_peak1, e->ssim);
            sci_result_free_contents(&r);
        }
    if (md)
        fclose(md);
    sci_problem_array_free(p, k);
    return 0;
}
