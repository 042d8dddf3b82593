/* scicap bench — what accuracy costs in time, for every reconstruction method, on a fixed suite.
 *
 * For each scene of the suite and each point of each method's grid of cost knobs, the point runs in a child
 * process (this program, re-executed with --point), so its peak memory is its own: the parent reads the child's
 * peak RSS and CPU time from wait4(2) and the solver's own wall time, CPU time and accuracy from the child's JSON
 * line. The parent then marks each method's Pareto front (no cheaper point is as accurate), names the cheapest
 * setting within 0.5 dB of the method's best, and writes:
 *     bench/results.csv                      every point
 *     <out>/report.md                         per scene: the fronts and the recommended settings
 *     <out>/psnr_time_<scene>.png             PSNR against wall time, each method's points and front (gnuplot)
 * Why a child per point: OpenMP's thread pool does not survive fork(), and peak RSS only grows within a process.
 */
#include <errno.h>
#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <omp.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "base/clock.h"
#include "cli/commands.h"
#include "io/curves.h"
#include "io/problem_dir.h"
#include "io/source.h"
#include "io/staging.h"
#include "recon/solver.h"
#include "sim/simulate.h"

extern char **environ;

typedef struct bench_scene {
    char name[64];     /* short name used in files and tables */
    char path[1024];   /* problem folder or .mat the points read */
    char what[160];    /* description for the report */
    int has_camera;    /* NeRF methods need one */
    double voxels;     /* w·h·N: io/curves.h scales times by it */
} bench_scene;

typedef struct bench_point {
    int scene;
    char method[32];   /* as sci_result.method */
    char setting[SCI_CURVE_SETTING_MAX]; /* e.g. "iters=100 tv_iters=5" */
    json_t *params;    /* passed to the child */
    /* results */
    int ok;
    char error[256];
    double psnr, psnr1, ssim, wall_s, cpu_s, rss_mib;
    int pareto, recommended;
    int threads;       /* threads per point it ran with */
    int kept;          /* read back from the previous CSV (a method not re-run), not measured now */
} bench_point;

static void usage(FILE *f)
{
    fprintf(f,
            "usage: scicap bench [--quick | --full] [--out DIR] [--csv FILE] [--data DIR] [--scenes DIR]\n"
            "                   [--methods LIST] [--scene NAME[,NAME]] [-j N]\n"
            "\n"
            "Runs every reconstruction method over a grid of its cost knobs on a fixed suite — the drop40 benchmark\n"
            "(.mat, snapshot 1) when present and the simulator's example scenes of each kind, with and without\n"
            "noise — and records PSNR (both peak conventions), SSIM, wall time, CPU time and peak memory for each\n"
            "point. Marks each method's Pareto front, names the cheapest setting within 0.5 dB of each method's best,\n"
            "and writes the CSV, a Markdown report and PNG plots of PSNR against wall time (gnuplot).\n"
            "\n"
            "  --quick           a small grid that runs in about a minute (CI)\n"
            "  --full            the full grid (default; `make bench-report`, under 30 minutes here)\n"
            "  --out DIR         report and plots (default bench/results)\n"
            "  --csv FILE        every point (default bench/results.csv)\n"
            "  --data DIR        where drop40_cacti.mat is (default $SCICAP_DATA, else ../shared/data)\n"
            "  --scenes DIR      example scenes (default: ./etc/scenes in a checkout, else the build tree's, else the\n"
            "                    installed ones in $SCICAP_DATADIR/scenes, default " SCICAP_DATADIR "/scenes)\n"
            "  --methods LIST    comma-separated subset of the methods (scicap recon --help lists them); the other\n"
            "                    methods' points are kept from the existing CSV (--full), so the report and plots\n"
            "                    still show every method\n"
            "  --scene LIST      comma-separated subset of the suite's scenes (drop40, video2d, video2d_noise,\n"
            "                    static3d, static3d_noise); the other scenes' points are kept from the existing\n"
            "                    CSV (--full), so the report and plots still show every scene\n"
            "  -j, --threads N   OpenMP threads per point (default: all cores)\n"
            "  --point SPEC      internal: run one grid point in this process (the runner starts one per point)\n"
            "  -h, --help        this text\n");
}

/* Where the example scenes are when --scenes is not given: a checkout's (run from the source tree), the build
 * tree's (a binary in <tree>/build/), else the installed copy. The first that holds the suite's first scene. */
static const char *find_scenes(char *buf, size_t n)
{
    if (access("etc/scenes/cacti_layers.json", R_OK) == 0)
        return "etc/scenes";
    char self[4096];
    ssize_t l = readlink("/proc/self/exe", self, sizeof self - 1);
    if (l > 0) {
        self[l] = 0;
        char *slash = strrchr(self, '/');
        if (slash) {
            *slash = 0;
            snprintf(buf, n, "%s/../etc/scenes", self);
            char probe[4200];
            snprintf(probe, sizeof probe, "%s/cacti_layers.json", buf);
            if (access(probe, R_OK) == 0)
                return buf;
        }
    }
    const char *d = getenv("SCICAP_DATADIR");
    snprintf(buf, n, "%s/scenes", d && *d ? d : SCICAP_DATADIR);
    return buf;
}

/* --- the child: one point ------------------------------------------------------------------------------ */

static int run_point(const char *spec)
{
    json_error_t je;
    json_t *j = json_loads(spec, 0, &je);
    const char *path = NULL, *method = NULL;
    json_t *params = NULL;
    if (!j || json_unpack_ex(j, &je, 0, "{s:s, s:s, s:o}", "path", &path, "method", &method, "params", &params) != 0) {
        fprintf(stderr, "scicap bench --point: bad spec: %s\n", je.text);
        return 2;
    }
    sci_problem **p = NULL;
    int k = 0;
    sci_error err = {0};
    if (sci_source_read(path, &p, &k, &err) < 0) {
        json_t *o = json_pack("{s:b, s:s}", "ok", 0, "error", err.msg);
        char *s = json_dumps(o, JSON_COMPACT);
        printf("%s\n", s);
        free(s);
        json_decref(o);
        json_decref(j);
        return 1;
    }
    /* the method's defaults, then the point's settings ("preset" first; recon/solver.h), no trace metrics but the
     * last row's: the point measures the method, not its trace */
    sci_result r = {0};
    int rc = -EINVAL;
    const solver_ops *m = solver_find_err(method, &err);
    void *q = m ? solver_settings_new(m) : NULL;
    json_t *zero = json_integer(0);
    if (q && (rc = solver_settings_from_json(m, q, params, NULL, "params", &err)) == 0 &&
        solver_settings_set(m, q, "metrics_every", zero, NULL, "metrics_every", &err) >= 0 &&
        solver_settings_set(m, q, "ssim_every", zero, NULL, "ssim_every", &err) >= 0)
        rc = solver_run(m, p[0], q, NULL, &r);
    json_decref(zero);
    solver_settings_free(q);
    if (rc < 0 && !r.error.msg[0])
        snprintf(r.error.msg, sizeof r.error.msg, "%s", err.msg[0] ? err.msg : sci_strerror(rc));
    json_t *out;
    if (rc < 0 || r.trace.len == 0) {
        out = json_pack("{s:b, s:s}", "ok", 0, "error", r.error.msg[0] ? r.error.msg : sci_strerror(rc));
    } else {
        const sci_trace_entry *e = &r.trace.e[r.trace.len - 1];
        out = json_pack("{s:b, s:f, s:f, s:f, s:f, s:f}", "ok", 1, "psnr", e->psnr, "psnr1", e->psnr_peak1, "ssim",
                        e->ssim, "wall_s", e->wall_s, "cpu_s", e->cpu_s);
    }
    char *s = json_dumps(out, JSON_COMPACT);
    printf("%s\n", s);
    free(s);
    json_decref(out);
    sci_result_free_contents(&r);
    sci_problem_array_free(p, k);
    json_decref(j);
    return rc < 0 ? 1 : 0;
}

/* --- the parent ------------------------------------------------------------------------------------------ */

/* Run one point in a child; fills the point's results. */
static void spawn_point(const char *self, const bench_scene *sc, bench_point *pt, int threads)
{
    json_t *spec = json_pack("{s:s, s:s, s:O}", "path", sc->path, "method", pt->method, "params", pt->params);
    char *specs = json_dumps(spec, JSON_COMPACT);
    json_decref(spec);
    int pipefd[2];
    if (pipe(pipefd) != 0) {
        snprintf(pt->error, sizeof pt->error, "pipe: %s", strerror(errno));
        free(specs);
        return;
    }
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, pipefd[1], 1);
    posix_spawn_file_actions_addclose(&fa, pipefd[0]);
    char thr[32];
    snprintf(thr, sizeof thr, "%d", threads);
    char *argv[] = {(char *)self, "bench", "--point", specs, "--threads", thr, NULL};
    pid_t pid;
    int rc = posix_spawn(&pid, self, &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    close(pipefd[1]);
    free(specs);
    if (rc != 0) {
        snprintf(pt->error, sizeof pt->error, "spawn %s: %s", self, strerror(rc));
        close(pipefd[0]);
        return;
    }
    char buf[4096];
    size_t len = 0;
    ssize_t got;
    while ((got = read(pipefd[0], buf + len, sizeof buf - 1 - len)) > 0)
        len += (size_t)got;
    buf[len] = 0;
    close(pipefd[0]);
    int status;
    struct rusage ru;
    while (wait4(pid, &status, 0, &ru) < 0 && errno == EINTR)
        ;
    pt->rss_mib = ru.ru_maxrss / 1024.0;
    json_error_t je;
    json_t *res = json_loads(buf, JSON_DISABLE_EOF_CHECK, &je);
    if (!res || !json_is_true(json_object_get(res, "ok"))) {
        const char *e = res ? json_string_value(json_object_get(res, "error")) : NULL;
        snprintf(pt->error, sizeof pt->error, "%s", e ? e : "the point's process failed");
    } else {
        pt->ok = 1;
        pt->psnr = json_number_value(json_object_get(res, "psnr"));
        pt->psnr1 = json_number_value(json_object_get(res, "psnr1"));
        pt->ssim = json_number_value(json_object_get(res, "ssim"));
        pt->wall_s = json_number_value(json_object_get(res, "wall_s"));
        pt->cpu_s = json_number_value(json_object_get(res, "cpu_s"));
    }
    json_decref(res);
}

static int add_point(bench_point **pts, int *n, int *cap, int scene, const char *method, json_t *params)
{
    if (*n == *cap) {
        int nc = *cap ? *cap * 2 : 64;
        bench_point *np = realloc(*pts, (size_t)nc * sizeof *np);
        if (!np)
            return -ENOMEM;
        *pts = np;
        *cap = nc;
    }
    bench_point *p = &(*pts)[(*n)++];
    memset(p, 0, sizeof *p);
    p->scene = scene;
    snprintf(p->method, sizeof p->method, "%s", method);
    p->params = params;
    int rc = params ? sci_curves_setting_text(params, p->setting, sizeof p->setting) : 0;
    if (rc < 0)
        (*n)--; /* a grid point the CSV cannot name */
    return rc;
}

/* Pareto front per (scene, method): sorted by wall time, a point is on the front when it beats the PSNR of every
 * cheaper point. The recommended setting is the cheapest point within 0.5 dB of the method's best. */
static void mark_fronts(bench_point *pts, int n, int nscenes)
{
    for (int s = 0; s < nscenes; s++)
        for (int i = 0; i < n; i++) {
            bench_point *a = &pts[i];
            if (a->scene != s || !a->ok)
                continue;
            int dominated = 0;
            double best = -INFINITY;
            for (int j = 0; j < n; j++) {
                bench_point *b = &pts[j];
                if (b->scene != s || !b->ok || strcmp(a->method, b->method) != 0)
                    continue;
                best = fmax(best, b->psnr);
                if (j != i && b->wall_s <= a->wall_s && b->psnr >= a->psnr &&
                    (b->wall_s < a->wall_s || b->psnr > a->psnr))
                    dominated = 1;
            }
            a->pareto = !dominated;
            /* recommended: within 0.5 dB of best, and no cheaper point also within 0.5 dB */
            if (a->psnr >= best - 0.5) {
                int cheaper = 0;
                for (int j = 0; j < n; j++) {
                    bench_point *b = &pts[j];
                    if (j != i && b->scene == s && b->ok && strcmp(a->method, b->method) == 0 &&
                        b->psnr >= best - 0.5 && (b->wall_s < a->wall_s || (b->wall_s == a->wall_s && j < i)))
                        cheaper = 1;
                }
                a->recommended = !cheaper;
            }
        }
}

static int cmp_time(const void *x, const void *y)
{
    const bench_point *a = *(bench_point *const *)x, *b = *(bench_point *const *)y;
    return (a->wall_s > b->wall_s) - (a->wall_s < b->wall_s);
}

static int write_plot(const char *outdir, const bench_scene *sc, int s, bench_point *pts, int n,
                      const char *const *methods, int nm)
{
    char dat[1200], gp[1200], png[1200];
    snprintf(dat, sizeof dat, "%s/psnr_time_%s.dat", outdir, sc->name);
    snprintf(gp, sizeof gp, "%s/psnr_time_%s.gp", outdir, sc->name);
    snprintf(png, sizeof png, "%s/psnr_time_%s.png", outdir, sc->name);
    FILE *f = fopen(dat, "w");
    if (!f)
        return -errno;
    /* One gnuplot data block per method (all points), then one per method (front, by time). */
    int blocks = 0;
    int *have = calloc((size_t)nm + 1, sizeof *have); /* as many methods as the table has */
    if (!have) {
        fclose(f);
        return -ENOMEM;
    }
    for (int pass = 0; pass < 2; pass++)
        for (int m = 0; m < nm; m++) {
            bench_point *sel[512];
            int k = 0;
            for (int i = 0; i < n && k < 512; i++)
                if (pts[i].scene == s && pts[i].ok && strcmp(pts[i].method, methods[m]) == 0 &&
                    (pass == 0 || pts[i].pareto))
                    sel[k++] = &pts[i];
            qsort(sel, (size_t)k, sizeof sel[0], cmp_time);
            fprintf(f, "# %s %s\n", methods[m], pass ? "front" : "all");
            for (int i = 0; i < k; i++)
                fprintf(f, "%.6f %.4f\n", sel[i]->wall_s, sel[i]->psnr);
            if (k == 0)
                fprintf(f, "NaN NaN\n");
            fprintf(f, "\n\n");
            have[m] |= k > 0;
            blocks++;
        }
    fclose(f);
    f = fopen(gp, "w");
    if (!f) {
        free(have);
        return -errno;
    }
    fprintf(f, "set terminal pngcairo size 900,560 noenhanced\nset output '%s'\n", png);
    fprintf(f, "set title '%s: PSNR against wall time (lines: Pareto fronts)'\n", sc->what);
    fprintf(f, "set xlabel 'wall time (s), log scale'\nset ylabel 'PSNR (dB), peak = frame max'\n");
    fprintf(f, "set logscale x\nset grid\nset key bottom right\n");
    fprintf(f, "plot ");
    int first = 1;
    for (int m = 0; m < nm; m++) {
        if (!have[m])
            continue;
        fprintf(f, "%s'%s' index %d with points pt 7 ps 0.8 lc %d title '%s', '%s' index %d with lines lw 2 lc %d notitle",
                first ? "" : ", ", dat, m, m + 1, methods[m], dat, nm + m, m + 1);
        first = 0;
    }
    fprintf(f, "\n");
    fclose(f);
    free(have);
    if (first)
        return 0; /* nothing ran on this scene */
    char cmd[2600];
    snprintf(cmd, sizeof cmd, "gnuplot '%s' 2>&1", gp);
    int rc = system(cmd);
    unlink(gp);
    unlink(dat);
    (void)blocks;
    return rc == 0 ? 0 : -EIO;
}

static int prepare_scene(bench_scene *sc, const char *scene_path, const char *name, const char *what,
                         const char *tmpdir)
{
    sci_error err = {0};
    sim_scene *s = NULL;
    if (sim_scene_load_file(&s, scene_path, &err) < 0) {
        fprintf(stderr, "scicap bench: %s\n", err.msg);
        return -1;
    }
    sim_scene_set_snapshots(s, 1, NULL);
    sci_problem **p = NULL;
    int k = 0;
    int rc = sim_run(s, &p, &k, NULL, NULL, NULL, &err);
    sim_scene_free(s);
    if (rc < 0) {
        fprintf(stderr, "scicap bench: %s: %s\n", scene_path, err.msg);
        return -1;
    }
    snprintf(sc->name, sizeof sc->name, "%s", name);
    snprintf(sc->path, sizeof sc->path, "%s/%s", tmpdir, name);
    snprintf(sc->what, sizeof sc->what, "%s (%dx%dx%d)", what, p[0]->mask->w, p[0]->mask->h, p[0]->mask->n);
    sc->has_camera = p[0]->camera != NULL;
    sc->voxels = (double)sci_cube_count(p[0]->mask);
    rc = sci_problem_dir_write(sc->path, p, k, NULL, 1, &err);
    sci_problem_array_free(p, k);
    if (rc < 0) {
        fprintf(stderr, "scicap bench: %s\n", err.msg);
        return -1;
    }
    return 0;
}

static int method_enabled(const char *list, const char *m);

/* The points not re-run (method not in `methods` or scene not in `scenes`), from the previous CSV, for the scenes
 * of this suite: appended as kept points. A missing CSV keeps nothing; a row not kept (malformed, or of a scene
 * not in the suite) is said on stderr. Returns how many were kept. */
static int keep_previous(const char *csv, const char *methods, const char *scenes, const bench_scene *sc, int ns,
                         bench_point **pts, int *n, int *cap)
{
    FILE *f = fopen(csv, "r");
    if (!f)
        return 0;
    char *line = NULL; /* a whole line however long, so an overlong setting is reported, not split */
    size_t line_cap = 0;
    int kept = 0, lineno = 0, other_scene = 0;
    while (getline(&line, &line_cap, f) != -1) {
        char *col[14], *save = NULL;
        int nc = 0;
        lineno++;
        for (char *t = strtok_r(line, ",\n", &save); t && nc < 14; t = strtok_r(NULL, ",\n", &save))
            col[nc++] = t;
        if (nc == 0 || strcmp(col[0], "scene") == 0)
            continue;
        if (nc < 12) {
            fprintf(stderr, "scicap bench: %s:%d: not kept: %d columns, fewer than 12\n", csv, lineno, nc);
            continue;
        }
        /* A row is re-measured now (so not kept) when both its method and its scene are selected. */
        if (method_enabled(methods, col[1]) && method_enabled(scenes, col[0]))
            continue;
        int s = 0;
        while (s < ns && strcmp(sc[s].name, col[0]) != 0)
            s++;
        if (s == ns) {
            other_scene++;
            continue;
        }
        if (strlen(col[2]) >= SCI_CURVE_SETTING_MAX) {
            fprintf(stderr, "scicap bench: %s:%d: not kept: setting of %zu bytes (at most %d)\n", csv, lineno,
                    strlen(col[2]), SCI_CURVE_SETTING_MAX - 1);
            continue;
        }
        if (add_point(pts, n, cap, s, col[1], NULL) < 0) {
            fprintf(stderr, "scicap bench: %s:%d: not kept: out of memory\n", csv, lineno);
            continue;
        }
        bench_point *p = &(*pts)[*n - 1];
        snprintf(p->setting, sizeof p->setting, "%s", col[2]);
        p->psnr = atof(col[3]), p->psnr1 = atof(col[4]), p->ssim = atof(col[5]);
        p->wall_s = atof(col[6]), p->cpu_s = atof(col[7]), p->rss_mib = atof(col[8]);
        p->threads = atoi(col[11]);
        p->ok = p->kept = 1;
        kept++;
    }
    free(line);
    fclose(f);
    if (other_scene)
        fprintf(stderr, "scicap bench: %s: %d row%s of scenes not in the suite dropped\n", csv, other_scene,
                other_scene == 1 ? "" : "s");
    return kept;
}

static int method_enabled(const char *list, const char *m)
{
    if (!list)
        return 1;
    size_t l = strlen(m);
    for (const char *p = list; (p = strstr(p, m)); p += l)
        if ((p == list || p[-1] == ',') && (p[l] == 0 || p[l] == ','))
            return 1;
    return 0;
}

/* The command line, as parsed. `scenes` may point into scenes_buf once defaults are filled. */
typedef struct bench_opts {
    int quick, threads;
    const char *out, *csv, *data, *scenes, *methods_arg, *point, *scene_arg;
    char scenes_buf[4096];
} bench_opts;

/* One run of the suite: what cli_bench_main's steps share. pts and methods are owned (bench_run_free). */
typedef struct bench_run {
    bench_opts *o;
    char self[4096];           /* this executable, re-run per point */
    char tmpdir[512];          /* the simulated scenes' problem folders, under $TMPDIR or /tmp */
    bench_scene sc[8];
    int ns;
    bench_point *pts;
    int np, cap;
    const char **methods;      /* every row of the solver table */
    int n_methods;
    const solver_ops *const *table;
    int nrun, nkept, failed;
    int64_t t0;
} bench_run;

/* The simulator's example scenes of the suite; quick = part of --quick. */
static const struct { const char *file, *name, *what; int quick; } bench_suite[] = {
    {"cacti_layers.json", "video2d", "video2d layers, no noise", 1},
    {"cacti_sensor_noise.json", "video2d_noise", "video2d layers, sensor noise", 0},
    {"static3d_corridor.json", "static3d", "static3d corridor, moving camera, no noise", 1},
    {"static3d_noisy.json", "static3d_noise", "static3d, moving camera, shot and read noise", 0},
};
#define BENCH_SUITE_LEN (sizeof bench_suite / sizeof bench_suite[0])

/* Parses argv into o. Returns -1 to go on, else the exit code (0 after --help, 2 on a bad option). */
static int bench_opts_parse(bench_opts *o, int argc, char **argv)
{
    static const struct option longopts[] = {
        {"quick", no_argument, 0, 'Q'},        {"full", no_argument, 0, 'F'},
        {"out", required_argument, 0, 'o'},    {"csv", required_argument, 0, 'c'},
        {"data", required_argument, 0, 'd'},   {"scenes", required_argument, 0, 's'},
        {"methods", required_argument, 0, 'm'}, {"threads", required_argument, 0, 'j'},
        {"point", required_argument, 0, 'P'},  {"help", no_argument, 0, 'h'},
        {"scene", required_argument, 0, 'S'},
        {0, 0, 0, 0},
    };
    o->out = "bench/results", o->csv = "bench/results.csv", o->data = getenv("SCICAP_DATA");
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, "o:c:d:s:m:j:h", longopts, NULL)) != -1) {
        switch (c) {
        case 'Q': o->quick = 1; break;
        case 'F': o->quick = 0; break;
        case 'o': o->out = optarg; break;
        case 'c': o->csv = optarg; break;
        case 'd': o->data = optarg; break;
        case 's': o->scenes = optarg; break;
        case 'm': o->methods_arg = optarg; break;
        case 'j': o->threads = atoi(optarg); break;
        case 'P': o->point = optarg; break;
        case 'S': o->scene_arg = optarg; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    return -1;
}

/* Defaults for data, scenes and threads; finds this executable and makes the output and temporary folders.
 * Returns 0, or 1 after a message. */
static int bench_run_prepare(bench_run *r)
{
    bench_opts *o = r->o;
    if (!o->data || !*o->data)
        o->data = "../shared/data";
    if (!o->scenes) {
        o->scenes = find_scenes(o->scenes_buf, sizeof o->scenes_buf);
        fprintf(stderr, "scicap bench: example scenes from %s\n", o->scenes);
    }
    if (o->threads <= 0)
        o->threads = omp_get_max_threads();
    ssize_t sl = readlink("/proc/self/exe", r->self, sizeof r->self - 1);
    if (sl <= 0) {
        fprintf(stderr, "scicap bench: cannot find my own executable: %s\n", strerror(errno));
        return 1;
    }
    r->self[sl] = 0;
    mkdir(o->out, 0755);
    const char *tmp = getenv("TMPDIR");
    if (!tmp || !*tmp || strlen(tmp) > sizeof r->tmpdir - 32)
        tmp = "/tmp";
    snprintf(r->tmpdir, sizeof r->tmpdir, "%s/scicap-bench-XXXXXX", tmp);
    if (!mkdtemp(r->tmpdir)) {
        fprintf(stderr, "scicap bench: mkdtemp: %s\n", strerror(errno));
        return 1;
    }
    return 0;
}

/* The drop40 benchmark as the suite's first scene when its .mat is readable. Returns 0, or 1 after a message. */
static int bench_suite_add_drop40(bench_run *r)
{
    char mat[2048];
    snprintf(mat, sizeof mat, "%s/drop40_cacti.mat", r->o->data);
    if (access(mat, R_OK) != 0) {
        fprintf(stderr, "scicap bench: NOTE: %s not found (set SCICAP_DATA or --data); the suite runs without it\n",
                mat);
        return 0;
    }
    sci_problem **p = NULL;
    int k = 0;
    sci_error err = {0};
    if (sci_source_read(mat, &p, &k, &err) < 0) {
        fprintf(stderr, "scicap bench: %s\n", err.msg);
        return 1;
    }
    bench_scene *sc = &r->sc[r->ns];
    snprintf(sc->name, sizeof sc->name, "drop40");
    snprintf(sc->path, sizeof sc->path, "%s", mat);
    snprintf(sc->what, sizeof sc->what, "drop40 benchmark, snapshot 1 (%dx%dx%d)", p[0]->mask->w, p[0]->mask->h,
             p[0]->mask->n);
    sc->has_camera = 0;
    sc->voxels = (double)sci_cube_count(p[0]->mask);
    sci_problem_array_free(p, k);
    r->ns++;
    return 0;
}

/* Every name in --scene must be one of the suite's; drop40 also needs its .mat. Returns 0, or 2 after a message. */
static int bench_scenes_check(const bench_run *r)
{
    const bench_opts *o = r->o;
    if (!o->scene_arg)
        return 0;
    char list[1024];
    snprintf(list, sizeof list, "%s", o->scene_arg);
    char *save = NULL;
    for (char *t = strtok_r(list, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        int known = r->ns > 0 && strcmp(t, "drop40") == 0;
        for (size_t i = 0; i < BENCH_SUITE_LEN; i++)
            known |= strcmp(t, bench_suite[i].name) == 0 && !(o->quick && !bench_suite[i].quick);
        if (!known) {
            fprintf(stderr,
                    "scicap bench: --scene: unknown scene '%s'%s; the suite's scenes are: %svideo2d, "
                    "video2d_noise, static3d, static3d_noise%s\n",
                    t, strcmp(t, "drop40") == 0 ? " (drop40_cacti.mat not found)" : "", r->ns ? "drop40, " : "",
                    o->quick ? " (--quick: video2d, static3d)" : "");
            return 2;
        }
    }
    return 0;
}

/* The suite: drop40, the check of --scene, then the simulated scenes. Returns 0 or the exit code. */
static int bench_suite_build(bench_run *r)
{
    int rc = bench_suite_add_drop40(r);
    if (rc == 0)
        rc = bench_scenes_check(r);
    if (rc != 0)
        return rc;
    for (size_t i = 0; i < BENCH_SUITE_LEN; i++) {
        if (r->o->quick && !bench_suite[i].quick)
            continue;
        char path[2048];
        snprintf(path, sizeof path, "%s/%s", r->o->scenes, bench_suite[i].file);
        fprintf(stderr, "scicap bench: simulating %s\n", path);
        if (prepare_scene(&r->sc[r->ns], path, bench_suite[i].name, bench_suite[i].what, r->tmpdir) == 0)
            r->ns++;
        else
            return 1;
    }
    return 0;
}

/* The grids: one point per scene × enabled method × grid row. Returns 0, or 1 after a message. */
static int bench_grid_build(bench_run *r)
{
    const bench_opts *o = r->o;
    size_t n_methods;
    r->table = solver_list(&n_methods);
    /* every row of the table, however many (a new method needs no edit here) */
    r->methods = calloc(n_methods + 1, sizeof *r->methods);
    if (!r->methods) {
        fprintf(stderr, "scicap bench: out of memory\n");
        return 1;
    }
    r->n_methods = (int)n_methods;
    for (int m = 0; m < r->n_methods; m++)
        r->methods[m] = r->table[m]->name;
    /* Each method's grid is its own (solver_ops.bench_quick / bench_full): the classical methods over iterations ×
     * TV passes; the NeRF methods on the fast preset (4–7 min each here) with fewer steps, and at 300 steps one
     * other knob at a time — about 15 minutes per scene on 2 cores; the presets balanced/best (10–17 min each) are
     * measured by bench_nerf_recon instead. A method that needs a camera runs on the scenes that have one. */
    for (int s = 0; s < r->ns; s++)
        for (int m = 0; m < r->n_methods; m++) {
            const solver_ops *op = r->table[m];
            if (!method_enabled(o->methods_arg, op->name) || !method_enabled(o->scene_arg, r->sc[s].name) ||
                ((op->caps & SOLVER_NEEDS_CAMERA) && !r->sc[s].has_camera))
                continue;
            for (const char *const *g = o->quick ? op->bench_quick : op->bench_full; g && *g; g++) {
                json_t *params = json_loads(*g, 0, NULL);
                if (!params) {
                    fprintf(stderr, "scicap bench: %s: bad grid point %s\n", op->name, *g);
                    return 1;
                }
                int rc = add_point(&r->pts, &r->np, &r->cap, s, op->name, params);
                if (rc < 0) {
                    if (rc == -ENAMETOOLONG)
                        fprintf(stderr, "scicap bench: %s: grid point %s: its setting is %d bytes or more\n", op->name,
                                *g, SCI_CURVE_SETTING_MAX);
                    else if (rc == -EINVAL)
                        fprintf(stderr, "scicap bench: %s: grid point %s: a value the curves cannot name (an object, a "
                                "list of other than numbers, a string with a space or a comma)\n", op->name, *g);
                    else
                        fprintf(stderr, "scicap bench: %s: grid point %s: out of memory\n", op->name, *g);
                    json_decref(params);
                    return 1;
                }
            }
        }
    return 0;
}

/* Runs every new point in its own process, a progress line each; keeps the other points from the previous CSV. */
static void bench_points_run(bench_run *r)
{
    const bench_opts *o = r->o;
    r->nrun = r->np;
    r->nkept = (o->methods_arg || o->scene_arg) && !o->quick
                   ? keep_previous(o->csv, o->methods_arg, o->scene_arg, r->sc, r->ns, &r->pts, &r->np, &r->cap)
                   : 0;
    fprintf(stderr, "scicap bench: %d points on %d scenes, %d threads each", r->nrun, r->ns, o->threads);
    if (r->nkept)
        fprintf(stderr, "; %d points of the other methods kept from %s", r->nkept, o->csv);
    fprintf(stderr, "\n");
    r->t0 = sci_clock_mono_ns();
    for (int i = 0; i < r->nrun; i++) {
        bench_point *p = &r->pts[i];
        const bench_scene *sc = &r->sc[p->scene];
        p->threads = o->threads;
        spawn_point(r->self, sc, p, o->threads);
        double el = sci_clock_s(r->t0, sci_clock_mono_ns());
        if (p->ok)
            fprintf(stderr, "[%3d/%d] %-14s %-9s %-34s %7.2f dB  SSIM %.4f  %8.3f s  %6.1f MiB   (%.0f s elapsed)\n",
                    i + 1, r->nrun, sc->name, p->method, p->setting, p->psnr, p->ssim, p->wall_s, p->rss_mib, el);
        else {
            fprintf(stderr, "[%3d/%d] %-14s %-9s %-34s FAILED: %s\n", i + 1, r->nrun, sc->name, p->method,
                    p->setting, p->error);
            r->failed++;
        }
    }
    mark_fronts(r->pts, r->np, r->ns);
}

/* Every point that ran, to --csv. Returns 0, or 1 after a message. */
static int bench_csv_write(const bench_run *r)
{
    FILE *f = fopen(r->o->csv, "w");
    if (!f) {
        fprintf(stderr, "scicap bench: %s: %s\n", r->o->csv, strerror(errno));
        return 1;
    }
    fprintf(f, "scene,method,setting,psnr_db,psnr_peak1_db,ssim,wall_s,cpu_s,peak_rss_mib,pareto,recommended,threads,"
               "voxels,camera\n");
    for (int i = 0; i < r->np; i++) {
        const bench_point *p = &r->pts[i];
        const bench_scene *sc = &r->sc[p->scene];
        if (!p->ok)
            continue;
        fprintf(f, "%s,%s,%s,%.4f,%.4f,%.5f,%.6f,%.6f,%.1f,%d,%d,%d,%.0f,%d\n", sc->name, p->method, p->setting,
                p->psnr, p->psnr1, p->ssim, p->wall_s, p->cpu_s, p->rss_mib, p->pareto, p->recommended, p->threads,
                sc->voxels, sc->has_camera);
    }
    fclose(f);
    return 0;
}

/* One scene's section of the report: its plot, then each method's front by time; writes the plot too. */
static void bench_report_scene(const bench_run *r, FILE *md, int s)
{
    const bench_scene *sc = &r->sc[s];
    fprintf(md, "#### %s\n\n![PSNR against wall time: %s](%s/psnr_time_%s.png)\n\n", sc->what, sc->name, r->o->out,
            sc->name);
    fprintf(md, "| method | setting | PSNR dB (peak = frame max) | SSIM | wall s | CPU s | peak MiB | |\n|---|---|---:|---:|---:|---:|---:|---|\n");
    for (int m = 0; m < r->n_methods; m++) {
        bench_point *sel[512];
        int k = 0;
        for (int i = 0; i < r->np && k < 512; i++)
            if (r->pts[i].scene == s && r->pts[i].ok && r->pts[i].pareto && strcmp(r->pts[i].method, r->methods[m]) == 0)
                sel[k++] = &r->pts[i];
        qsort(sel, (size_t)k, sizeof sel[0], cmp_time);
        for (int i = 0; i < k; i++)
            fprintf(md, "| %s | %s | %.2f | %.4f | %.3f | %.3f | %.0f | %s |\n", sel[i]->method, sel[i]->setting,
                    sel[i]->psnr, sel[i]->ssim, sel[i]->wall_s, sel[i]->cpu_s, sel[i]->rss_mib,
                    sel[i]->recommended ? "**cheapest within 0.5 dB of best**" : "front");
    }
    fprintf(md, "\n");
    int rc = write_plot(r->o->out, sc, s, r->pts, r->np, r->methods, r->n_methods);
    if (rc < 0)
        fprintf(stderr, "scicap bench: plot for %s failed (is gnuplot installed?)\n", sc->name);
}

/* <out>/report.md and the plots, then the closing line. Returns 0, or 1 after a message. */
static int bench_report_write(const bench_run *r)
{
    const bench_opts *o = r->o;
    char mdpath[1200];
    snprintf(mdpath, sizeof mdpath, "%s/report.md", o->out);
    FILE *md = fopen(mdpath, "w");
    if (!md) {
        fprintf(stderr, "scicap bench: %s: %s\n", mdpath, strerror(errno));
        return 1;
    }
    double la[3] = {NAN, NAN, NAN};
    getloadavg(la, 3);
    fprintf(md, "Produced by `scicap bench%s%s%s%s%s` (%d points, %.0f s, %d threads per point; load average %.2f %.2f "
                "%.2f at the end, %ld cores)%s. PSNR: mean over frames, peak = per-frame max of the truth; SSIM: "
                "Gaussian 11×11, σ 1.5; wall and CPU time: the solver's own; memory: peak RSS of the point's "
                "process. Every point is in `bench/results.csv`.\n\n",
            o->quick ? " --quick" : "", o->methods_arg ? " --methods " : "", o->methods_arg ? o->methods_arg : "",
            o->scene_arg ? " --scene " : "", o->scene_arg ? o->scene_arg : "", r->nrun,
            sci_clock_s(r->t0, sci_clock_mono_ns()), o->threads, la[0], la[1], la[2], sysconf(_SC_NPROCESSORS_ONLN),
            r->nkept ? "; the other points are kept from the previous full run" : "");
    for (int s = 0; s < r->ns; s++)
        bench_report_scene(r, md, s);
    fprintf(md, "Only Pareto-front points are listed (no cheaper point of the same method is as accurate).\n");
    fclose(md);
    fprintf(stderr, "scicap bench: wrote %s, %s and the plots in %s/ (%d point(s) failed)\n", o->csv, mdpath, o->out,
            r->failed);
    return 0;
}

/* Removes the temporary scenes and frees the points. */
static void bench_run_finish(bench_run *r)
{
    int rc = sci_staging_remove(r->tmpdir);
    if (rc < 0)
        fprintf(stderr, "scicap bench: could not remove %s: %s\n", r->tmpdir, strerror(-rc));
    for (int i = 0; i < r->np; i++)
        json_decref(r->pts[i].params);
    free(r->pts);
    free(r->methods);
}

int cli_bench_main(int argc, char **argv)
{
    bench_opts o = {0};
    int rc = bench_opts_parse(&o, argc, argv);
    if (rc >= 0)
        return rc;
    if (o.threads > 0)
        omp_set_num_threads(o.threads);
    if (o.point)
        return run_point(o.point);
    if (optind != argc) {
        usage(stderr);
        return 2;
    }
    bench_run r = {.o = &o};
    if ((rc = bench_run_prepare(&r)) != 0)
        return rc;
    /* from here on the temporary scenes exist: every way out removes them */
    if ((rc = bench_suite_build(&r)) == 0 && (rc = bench_grid_build(&r)) == 0) {
        bench_points_run(&r);
        if ((rc = bench_csv_write(&r)) == 0 && (rc = bench_report_write(&r)) == 0)
            rc = r.failed ? 1 : 0;
    }
    bench_run_finish(&r);
    return rc;
}
