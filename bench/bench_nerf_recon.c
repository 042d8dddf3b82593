/* bench/bench_nerf_recon.c — cost and accuracy of the NeRF reconstruction presets.
 *
 * Part 1: seconds per training step, rendering seconds per frame and peak memory (RSS) of each preset of rayformer
 * and scinerf at 128×128 (static3d_corridor) and 256×256 (static3d_tabletop), N = 8: each measurement runs in its
 * own child process (so that its peak RSS is its own, from wait4), trains STEPS steps and renders the frames once;
 * the step time is the median over the steps after the first two, the render time the final render / N.
 * Part 2: PSNR and SSIM against wall time of each preset run to its end on static3d_corridor (known poses),
 * sampled every 1/8 of the run (the evaluation renders are excluded from the wall time, as in every trace).
 * Part 1 writes bench/results/nerf_recon.md, part 2 bench/results/nerf_recon_curves.md; each records the load
 * average before and after (2 shared cores: timings vary with what else runs). Part 2 takes about 25 minutes for
 * fast and balanced (measured: 9 min for the two fast presets and ≈ 15 for the balanced ones, evaluations
 * included), and the best presets about 16 minutes each more. `--quick`: part 1 only; `--curves-only
 * [--presets fast,balanced]`: part 2 only, for the presets named.
 * Part 3, `--ceiling [STEPS] [--scene NAME] [--out NAME] [--methods a,b] [--set KEY=VALUE]...` (alone; not in
 * `make bench`): each method's fast preset (with the settings --set names over it) run for STEPS steps (default
 * 10000, the learning rate decayed over all of them) on etc/scenes/NAME.json (default static3d_corridor), PSNR,
 * the measurement residual and the mean largest ray weight every STEPS/20 steps, written to
 * bench/results/nerf_ceiling.md (the corridor) or nerf_ceiling_NAME.md: where accuracy stops following the fit
 * (--set takes any setting but the three the ceiling sets itself: iters, metrics_every, ssim_every); `--out NAME`
 * writes bench/results/NAME.md instead, for a curve the preset rule is not to read. About 25 min for rayformer and
 * 45 for scinerf on 2 cores at 128 × 128.
 * `--place TABLE...` (alone): where the preset rule of io/ceiling.h puts every preset on those ceiling tables, and
 * the methods at equal wall time on each, to bench/results/nerf_presets.md (the presets are placed on
 * bench/results/nerf_ceiling_photo_*.md; tests/unit/test_nerf_presets checks the same).
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "base/file.h"
#include "base/json.h"
#include "base/runtime_env.h"
#include "bench/bench_load.h"
#include "bench/bench_scene.h"
#include "io/ceiling.h"
#include "recon/solver.h"
#include "sim/simulate.h"

#define STEPS 12
#define MAX_CURVE 24

typedef struct measure {
    int ok;
    double step_s, render_s_per_frame, total_s;
    int n_curve;
    double curve[MAX_CURVE][6]; /* iter, wall s, PSNR, SSIM, measurement residual, mean largest weight */
    long n_params;
    char err[256];
} measure;

static int cmpd(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}


/* Runs in the child: one preset of one method on one scene, `full` = the whole preset, else STEPS steps;
 * `steps` > 0 overrides the preset's step count (the ceiling runs: evaluated every steps/20, no SSIM); `extra`
 * (may be NULL) holds settings that override the preset's (the ceiling's --set). */
static void run_child(const char *method, const char *preset, const char *scene, int full, int steps,
                      const json_t *extra, measure *m)
{
    sci_error err = {0};
    sci_problem *p = bench_scene_first(scene, &err);
    if (!p) {
        snprintf(m->err, sizeof m->err, "%s", err.msg);
        return;
    }
    /* the method's defaults and preset (recon/solver.h); the short run stops after STEPS steps without evaluation
     * renders, the full one evaluates every 1/8 of the run */
    sci_result r = {0};
    int rc = -EINVAL, iters = 0;
    const solver_ops *op = solver_find_err(method, &r.error);
    solver_preset pr;
    void *q = op ? solver_settings_new(op) : NULL;
    if (q && solver_preset_parse(preset, &pr, NULL, &r.error) == 0) {
        solver_settings_preset(op, q, pr);
        iters = steps > 0 ? steps : full ? solver_settings_iters(op, q) : STEPS;
        const int every = steps > 0 ? (iters + 19) / 20 : full ? (iters + 7) / 8 : 0;
        json_t *set = json_pack("{s:i, s:i, s:i}", "iters", iters, "metrics_every", every, "ssim_every",
                                steps > 0 ? 0 : every);
        if (extra && (rc = solver_settings_from_json(op, q, extra, NULL, "--set", &r.error)) < 0)
            ;
        else if ((rc = solver_settings_from_json(op, q, set, NULL, "settings", &r.error)) == 0)
            rc = solver_run(op, p, q, NULL, &r);
        json_decref(set);
    }
    solver_settings_free(q);
    if (rc < 0 || (int)r.trace.len != iters) {
        snprintf(m->err, sizeof m->err, "%s", r.error.msg);
    } else {
        const sci_trace_entry *e = r.trace.e;
        const int n = (int)r.trace.len;
        if (!full) {
            double d[STEPS];
            int k = 0;
            for (int i = 2; i < n - 1; i++)
                d[k++] = e[i].wall_s - e[i - 1].wall_s;
            qsort(d, (size_t)k, sizeof *d, cmpd);
            m->step_s = d[k / 2];
            m->render_s_per_frame = (e[n - 1].wall_s - e[n - 2].wall_s - m->step_s) / p->mask->n;
        }
        m->total_s = e[n - 1].wall_s;
        for (int i = 0; i < n && m->n_curve < MAX_CURVE; i++)
            if (!isnan(e[i].psnr_peak1)) {
                double *c = m->curve[m->n_curve++];
                c[0] = e[i].iter, c[1] = e[i].wall_s, c[2] = e[i].psnr_peak1, c[3] = e[i].ssim;
                c[4] = e[i].meas_residual, c[5] = e[i].max_weight;
            }
        m->ok = 1;
    }
    sci_result_free_contents(&r);
    sci_problem_free(p);
}

/* Fork, run, collect the measurement and the child's peak RSS (KiB). */
static int measure_in_child(const char *method, const char *preset, const char *scene, int full, int steps,
                            const json_t *extra, measure *m, long *maxrss_kib)
{
    int fd[2];
    if (pipe(fd) < 0)
        return -errno;
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0)
        return -errno;
    if (pid == 0) {
        close(fd[0]);
        measure mm = {0};
        run_child(method, preset, scene, full, steps, extra, &mm);
        ssize_t w = write(fd[1], &mm, sizeof mm);
        _exit(w == (ssize_t)sizeof mm ? 0 : 1);
    }
    close(fd[1]);
    memset(m, 0, sizeof *m);
    size_t got = 0;
    while (got < sizeof *m) {
        ssize_t k = read(fd[0], (char *)m + got, sizeof *m - got);
        if (k <= 0)
            break;
        got += (size_t)k;
    }
    close(fd[0]);
    int status;
    struct rusage ru;
    if (wait4(pid, &status, 0, &ru) < 0)
        return -errno;
    *maxrss_kib = ru.ru_maxrss;
    return got == sizeof *m && WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : -EIO;
}

/* A results table: collected in memory with the load average at the start, replacing path atomically at
 * table_close with the load average at the end, so a killed run leaves the previous file intact. */
typedef struct table {
    FILE *md; /* an open_memstream over buf */
    char *buf;
    size_t len;
    const char *path;
    char load0[64];
} table;

static int table_open(table *t, const char *path)
{
    t->path = path;
    t->buf = NULL;
    t->len = 0;
    bench_loadavg(t->load0, sizeof t->load0);
    if (!(t->md = open_memstream(&t->buf, &t->len)))
        perror(path);
    return t->md ? 0 : -1;
}

/* Returns 1 when the file could not be published, else `status`. */
static int table_close(table *t, int status)
{
    char load1[64];
    bench_loadavg(load1, sizeof load1);
    fprintf(t->md, "\nLoad average %s at the start, %s at the end (2 cores).\n", t->load0, load1);
    sci_error err = {0};
    int rc = fclose(t->md) == 0 ? sci_file_write_atomic(t->path, t->buf, t->len, 0644, 0, &err)
                                : sci_error_set(&err, -ENOMEM, "%s: out of memory", t->path);
    free(t->buf);
    if (rc < 0) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    return status;
}

/* Part 1: cost per step, render and memory of every preset at both sizes. */
static int part_costs(const char *const *methods, int n_methods, const char *const *presets)
{
    const char *scenes[] = {"etc/scenes/static3d_corridor.json", "etc/scenes/static3d_tabletop.json"};
    const int sizes[] = {128, 256};
    table t;
    if (table_open(&t, "bench/results/nerf_recon.md") < 0)
        return 1;
    FILE *md = t.md;
    fprintf(md, "Measured by `make bench` (bench/bench_nerf_recon.c): each preset trained for %d steps in its own "
                "process on static3d_corridor (128×128) and static3d_tabletop (256×256), N = 8, 2 threads; step "
                "time = median step after the first two; render = the final window-wise render of all N frames, "
                "per frame; peak RSS of that process.\n\n",
            STEPS);
    fprintf(md, "| method | preset | size | s per step | render s per frame | peak RSS MiB |\n");
    fprintf(md, "|---|---|---:|---:|---:|---:|\n");
    int status = 0;
    for (int mi = 0; mi < n_methods; mi++)
        for (int pi = 0; pi < 3; pi++)
            for (int si = 0; si < 2; si++) {
                measure m;
                long rss = 0;
                int rc = measure_in_child(methods[mi], presets[pi], scenes[si], 0, 0, NULL, &m, &rss);
                if (rc < 0 || !m.ok) {
                    printf("%s %s %d: failed: %s\n", methods[mi], presets[pi], sizes[si], m.err);
                    fprintf(md, "| %s | %s | %d | failed | | |\n", methods[mi], presets[pi], sizes[si]);
                    status = 1;
                    continue;
                }
                printf("%-9s %-8s %3d²: %.3f s/step, render %.2f s/frame, peak RSS %.0f MiB\n", methods[mi],
                       presets[pi], sizes[si], m.step_s, m.render_s_per_frame, rss / 1024.0);
                fprintf(md, "| %s | %s | %d² | %.3f | %.2f | %.0f |\n", methods[mi], presets[pi], sizes[si],
                        m.step_s, m.render_s_per_frame, rss / 1024.0);
            }
    return table_close(&t, status);
}

/* Part 2: PSNR and SSIM against wall time of the presets in `which` (comma-separated), each run to its end. */
static int part_curves(const char *const *methods, int n_methods, const char *const *presets, const char *which)
{
    table t;
    if (table_open(&t, "bench/results/nerf_recon_curves.md") < 0)
        return 1;
    FILE *md = t.md;
    fprintf(md, "PSNR (peak = 1) and SSIM against wall time, each preset (%s) run to its end on static3d_corridor "
                "(128×128×8, known poses, 2 threads; every 1/8 of the run; evaluation renders excluded from the "
                "time, the final render included in the last row):\n\n",
            which);
    fprintf(md, "| method | preset | step | wall s | PSNR dB | SSIM |\n|---|---|---:|---:|---:|---:|\n");
    int status = 0;
    /* cheapest presets first: a run cut short still has them */
    for (int pi = 0; pi < 3; pi++) {
        char key[32], list[128];
        snprintf(key, sizeof key, ",%s,", presets[pi]);
        snprintf(list, sizeof list, ",%s,", which);
        if (!strstr(list, key))
            continue;
        for (int mi = 0; mi < n_methods; mi++) {
            measure m;
            long rss = 0;
            int rc = measure_in_child(methods[mi], presets[pi], "etc/scenes/static3d_corridor.json", 1, 0, NULL, &m,
                                      &rss);
            if (rc < 0 || !m.ok) {
                printf("%s %s full run failed: %s\n", methods[mi], presets[pi], m.err);
                status = 1;
                continue;
            }
            for (int k = 0; k < m.n_curve; k++) {
                const double *c = m.curve[k];
                printf("%-9s %-8s step %5.0f  %7.1f s  PSNR %.2f dB  SSIM %.4f\n", methods[mi], presets[pi], c[0],
                       c[1], c[2], c[3]);
                fprintf(md, "| %s | %s | %.0f | %.1f | %.2f | %.4f |\n", methods[mi], presets[pi], c[0], c[1], c[2],
                        c[3]);
            }
            fflush(stdout);
        }
    }
    return table_close(&t, status);
}

#define CEILING_SCENE "static3d_corridor"

/* A scene name for --scene: a file name under etc/scenes/ without a path, a-z, 0-9 and _ only. */
static int scene_name_ok(const char *name)
{
    size_t n = strlen(name);
    return n > 0 && n < 64 && strspn(name, "abcdefghijklmnopqrstuvwxyz0123456789_") == n;
}

/* Part 3: each method's fast preset run for `steps` steps on etc/scenes/<scene>.json: the ceiling of the recipe.
 * The table is bench/results/nerf_ceiling.md for the corridor, nerf_ceiling_<scene>.md for another scene, or
 * bench/results/<out>.md when `out` is not empty (a curve the preset rule must not read: see --out below). */
static int part_ceiling(const char *const *methods, int n_methods, int steps, const char *scene, const char *out,
                        const json_t *extra)
{
    char json[160], mdpath[160];
    snprintf(json, sizeof json, "etc/scenes/%s.json", scene);
    if (out[0])
        snprintf(mdpath, sizeof mdpath, "bench/results/%s.md", out);
    else if (strcmp(scene, CEILING_SCENE) == 0)
        snprintf(mdpath, sizeof mdpath, "bench/results/nerf_ceiling.md");
    else
        snprintf(mdpath, sizeof mdpath, "bench/results/nerf_ceiling_%s.md", scene);
    table t;
    if (table_open(&t, mdpath) < 0)
        return 1;
    FILE *md = t.md;
    char *with = json_object_size(extra) ? json_dumps(extra, JSON_COMPACT | JSON_SORT_KEYS) : NULL;
    fprintf(md, "The ceiling of the recipe: each method's fast preset%s%s run for %d steps (the learning rate decayed "
                "over all of them) on %s (known poses, 2 threads), evaluated every %d steps "
                "(renders excluded from the time). PSNR with peak 1; residual = ‖y − Σ Mᵢ Xᵢ‖ / ‖y‖ of the render; "
                "largest weight = mean over the rays that hit something of the ray's largest sample weight.\n\n",
            with ? " with " : "", with ? with : "", steps, scene, (steps + 19) / 20);
    free(with);
    fprintf(md, "| method | step | wall s | PSNR dB | residual | largest weight |\n|---|---:|---:|---:|---:|---:|\n");
    int status = 0;
    for (int mi = 0; mi < n_methods; mi++) {
        measure m;
        long rss = 0;
        int rc = measure_in_child(methods[mi], "fast", json, 1, steps, extra, &m, &rss);
        if (rc < 0 || !m.ok) {
            printf("%s ceiling run failed: %s\n", methods[mi], m.err);
            status = 1;
            continue;
        }
        for (int k = 0; k < m.n_curve; k++) {
            const double *c = m.curve[k];
            printf("%-9s step %6.0f  %7.1f s  PSNR %.2f dB  residual %.4f  largest weight %.3f\n", methods[mi], c[0],
                   c[1], c[2], c[4], c[5]);
            fprintf(md, "| %s | %.0f | %.1f | %.2f | %.4f | %.3f |\n", methods[mi], c[0], c[1], c[2], c[4], c[5]);
        }
        fflush(stdout);
    }
    status = table_close(&t, status);
    printf("wrote %s\n", mdpath);
    return status;
}

/* `--place TABLE...`: where the preset rule (io/ceiling.h) puts each method's presets over the given ceiling tables,
 * beside the steps each preset has now, and the methods at equal wall time on each table; written to
 * bench/results/nerf_presets.md and stdout. Exit 1 when a preset is off its place or a table does not load. */
static void place_presets(FILE *md, const char *method, const sci_ceiling *tabs, int nt, char **paths, int *status)
{
    const solver_ops *op = solver_find_err(method, NULL);
    void *q = op ? solver_settings_new(op) : NULL;
    for (int p = 0; q && p < SOLVER_PRESET_COUNT; p++) {
        sci_ceiling_place at;
        solver_settings_preset(op, q, (solver_preset)p);
        const int now = solver_settings_iters(op, q);
        const char *pn = solver_preset_name((solver_preset)p);
        if (sci_ceiling_place_preset(tabs, nt, method, (solver_preset)p, &at) < 0) {
            fprintf(md, "| %s | %s | %d | no ceiling row | | | | |\n", method, pn, now);
            *status = 1;
            continue;
        }
        double wall = 0, psnr = 0;
        for (int k = 0; k < tabs[at.table].n; k++)
            if (!strcmp(tabs[at.table].p[k].method, method) && tabs[at.table].p[k].step == at.step)
                wall = tabs[at.table].p[k].wall_s, psnr = tabs[at.table].p[k].psnr_db;
        const int ok = sci_ceiling_place_holds(&at, now);
        const char *base = strrchr(paths[at.table], '/');
        fprintf(md, "| %s | %s | %d | %s | %.2f | %.1f | (%d, %d] | %.2f dB, %.0f s%s |\n", method, pn, now,
                base ? base + 1 : paths[at.table], at.plateau_db, sci_ceiling_margin_db((solver_preset)p), at.prev,
                at.step, psnr, wall, ok ? "" : " — **off its place**");
        *status |= !ok;
    }
    solver_settings_free(q);
}

static int part_place(const char *const *methods, int n_methods, char **paths, int n_paths)
{
    static sci_ceiling tabs[16];
    int nt = 0, status = 0;
    if (n_paths > 16) {
        fprintf(stderr, "bench_nerf_recon: --place takes at most 16 tables (%d given)\n", n_paths);
        return 2;
    }
    for (int i = 0; i < n_paths; i++) {
        sci_error err = {0};
        if (sci_ceiling_load(paths[i], &tabs[nt], &err) < 0) {
            fprintf(stderr, "bench_nerf_recon: %s\n", err.msg);
            return 1;
        }
        nt++;
    }
    char *buf = NULL;
    size_t len = 0;
    FILE *md = open_memstream(&buf, &len);
    if (!md)
        return 1;
    fprintf(md, "Written by `bench_nerf_recon --place` from the ceiling tables (io/ceiling.h): each preset at the least "
                "evaluated step within its margin of the method's best PSNR on the table that asks for the most steps "
                "(fast 1 dB, balanced 0.3 dB, best 0.1 dB); a preset must lie in (the step before, that step]. PSNR "
                "with peak 1.\n\n| method | preset | steps | deciding table | plateau dB | margin dB | place | "
                "the long run there |\n|---|---|---:|---|---:|---:|---|---|\n");
    for (int mi = 0; mi < n_methods; mi++)
        place_presets(md, methods[mi], tabs, nt, paths, &status);
    /* equal wall time: every other method's PSNR where the first one was evaluated */
    for (int t = 0; t < nt && n_methods > 1; t++) {
        int others = 0;
        for (int k = 0; k < tabs[t].n; k++)
            others += strcmp(tabs[t].p[k].method, methods[0]) != 0;
        if (!others)
            continue;
        fprintf(md, "\nAt equal wall time on %s (PSNR dB; the others interpolated at %s's evaluations):\n\n| wall s |",
                paths[t], methods[0]);
        for (int mi = 0; mi < n_methods; mi++)
            fprintf(md, " %s |", methods[mi]);
        fprintf(md, "\n|---:|");
        for (int mi = 0; mi < n_methods; mi++)
            fprintf(md, "---:|");
        fprintf(md, "\n");
        for (int k = 0; k < tabs[t].n; k++) {
            const sci_ceiling_point *pt = &tabs[t].p[k];
            if (strcmp(pt->method, methods[0]) != 0)
                continue;
            fprintf(md, "| %.0f | %.2f |", pt->wall_s, pt->psnr_db);
            for (int mi = 1; mi < n_methods; mi++) {
                double v;
                if (sci_ceiling_psnr_at(&tabs[t], methods[mi], pt->wall_s, &v) == 0)
                    fprintf(md, " %.2f |", v);
                else
                    fprintf(md, " |");
            }
            fprintf(md, "\n");
        }
    }
    fclose(md);
    fwrite(buf, 1, len, stdout);
    sci_error err = {0};
    if (sci_file_write_atomic("bench/results/nerf_presets.md", buf, len, 0644, 0, &err) < 0) {
        fprintf(stderr, "%s\n", err.msg);
        status = 1;
    }
    free(buf);
    return status;
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* the BLAS kernels and OpenMP waiting that scicap and scicapd run with */
    int costs = 1, curves = 1, ceiling = 0, place = 0;
    json_t *extra = json_object();
    char which[128] = "fast,balanced,best", scene[64] = CEILING_SCENE, only[128] = "", out[64] = "";
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--quick") == 0)
            curves = 0;
        else if (strcmp(argv[i], "--curves-only") == 0)
            costs = 0;
        else if (strcmp(argv[i], "--presets") == 0 && i + 1 < argc)
            snprintf(which, sizeof which, "%s", argv[++i]);
        else if (strcmp(argv[i], "--ceiling") == 0) {
            ceiling = 10000;
            if (i + 1 < argc && argv[i + 1][0] != '-') {
                char *end;
                long v = strtol(argv[++i], &end, 10);
                if (*end || v < 20 || v > 1000000) {
                    fprintf(stderr, "bench_nerf_recon: --ceiling takes a step count in [20, 1000000]\n");
                    return 2;
                }
                ceiling = (int)v;
            }
        } else if (strcmp(argv[i], "--scene") == 0 && i + 1 < argc && scene_name_ok(argv[i + 1]))
            snprintf(scene, sizeof scene, "%s", argv[++i]);
        else if (strcmp(argv[i], "--out") == 0 && i + 1 < argc && scene_name_ok(argv[i + 1]))
            snprintf(out, sizeof out, "%s", argv[++i]);
        else if (strcmp(argv[i], "--methods") == 0 && i + 1 < argc)
            snprintf(only, sizeof only, ",%s,", argv[++i]);
        else if (strcmp(argv[i], "--set") == 0 && i + 1 < argc && sci_json_set_kv(extra, argv[++i]) == 0)
            ;
        else if (strcmp(argv[i], "--place") == 0 && i + 1 < argc) {
            place = i + 1; /* the tables run to the end of the arguments */
            break;
        } else {
            fprintf(stderr, "usage: bench_nerf_recon [--quick | --curves-only [--presets fast,balanced,best] | "
                            "--ceiling [STEPS] [--scene NAME] [--out NAME] [--methods a,b] [--set KEY=VALUE]... | "
                            "[--methods a,b] --place TABLE...]\n"
                            "  --scene: etc/scenes/NAME.json (a-z, 0-9 and _), default " CEILING_SCENE "\n"
                            "  --out: the ceiling's table is bench/results/NAME.md\n"
                            "  --set: a setting over the fast preset's (samples=64), as scicap recon --set\n");
            json_decref(extra);
            return 2;
        }
    }
    /* the methods that train on a camera's views, every preset; --methods keeps the ones it names */
    const char *methods[8], *const *presets = solver_preset_names;
    int n_methods = 0;
    for (const solver_ops *const *m = solver_list(NULL); *m && n_methods < 8; m++) {
        char key[SOLVER_NAME_MAX + 2];
        snprintf(key, sizeof key, ",%s,", (*m)->name);
        if (((*m)->caps & SOLVER_NEEDS_CAMERA) && (!only[0] || strstr(only, key)))
            methods[n_methods++] = (*m)->name;
    }
    if (n_methods == 0) {
        fprintf(stderr, "bench_nerf_recon: --methods names no method that trains on a camera's views\n");
        return 2;
    }
    if (!ceiling && (out[0] || json_object_size(extra))) {
        fprintf(stderr, "bench_nerf_recon: --out and --set go with --ceiling\n");
        json_decref(extra);
        return 2;
    }
    for (const char *const *k = (const char *const[]){"iters", "metrics_every", "ssim_every", NULL}; *k; k++)
        if (json_object_get(extra, *k)) { /* run_child sets them after --set: a value here would be ignored */
            fprintf(stderr, "bench_nerf_recon: --set %s: the ceiling sets it (STEPS, and evaluations every STEPS/20)\n",
                    *k);
            json_decref(extra);
            return 2;
        }
    int status = 0;
    if (place || ceiling) {
        status = place ? part_place(methods, n_methods, argv + place, argc - place)
                       : part_ceiling(methods, n_methods, ceiling, scene, out, extra);
        json_decref(extra);
        return status;
    }
    json_decref(extra);
    if (costs)
        status |= part_costs(methods, n_methods, presets);
    if (curves)
        status |= part_curves(methods, n_methods, presets, which);
    printf("wrote%s%s\n", costs ? " bench/results/nerf_recon.md" : "", curves ? " bench/results/nerf_recon_curves.md" : "");
    return status;
}
