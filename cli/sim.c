/* scicap sim — simulate a scene (docs/scene-format.md) and write a problem folder that `scicap recon` reads. */
#include <errno.h>
#include <getopt.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/clock.h"
#include "cli/commands.h"
#include "io/problem_dir.h"
#include "recon/bayer.h"
#include "sim/bench.h"
#include "sim/default_scene.h"
#include "sim/dmd_sim.h"
#include "sim/simulate.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: scicap sim SCENE.json -o DIR [OPTIONS]\n"
            "       scicap sim --default -o DIR [OPTIONS]\n"
            "\n"
            "Render the scene's truth frames, make its masks, form the coded snapshot(s) through the effects the\n"
            "scene lists (and only those), and write DIR: problem.json, meas/mask/truth stacks (float EXR), the\n"
            "camera poses and intrinsics of a static3d scene, and the scene record. Then 'scicap recon DIR -o OUT'\n"
            "reconstructs it and prints PSNR against the truth.\n"
            "\n"
            "  -o, --output DIR     output folder (required); replaced only with --force\n"
            "  -f, --force          replace an existing output folder\n"
            "      --seed S         override the scene's seed (masks, noise, textures)\n"
            "      --snapshots K    override the number of snapshots\n"
            "      --default        simulate the embedded default scene instead of a file\n"
            "      --bench          measure each snapshot on the simulated bench (sim/bench.h: the sim DMD, 1 ms\n"
            "                       per mask, trigger, camera with scicapd's simulator defaults: 6000 counts per\n"
            "                       unit, dark level 200, read noise 2 counts) instead of the effects' model; the\n"
            "                       measurement is (counts - dark) / counts per unit; grey scenes only\n"
            "  -j, --threads N      OpenMP threads (default: all cores)\n"
            "  -q, --quiet          no progress on stderr\n"
            "  -h, --help           this text\n"
            "\n"
            "Scale: truth and masks in [0, 1]; the measurement is the plain forward model sum(mask * frame) when no\n"
            "effects are listed (peak 1). Exit status: 0 ok, 1 failure, 2 usage.\n");
}

/* The scene as the options ask: a file or the embedded default, seed and snapshot count overridden. */
static int load_scene(int use_default, const char *path, int have_seed, unsigned long long seed, int have_k,
                      unsigned long long snapshots, sim_scene **out, sci_error *err)
{
    int rc = use_default ? sim_default_scene_load(out, err) : sim_scene_load_file(out, path, err);
    if (rc == 0 && have_seed)
        rc = sim_scene_set_seed(*out, seed, err);
    if (rc == 0 && have_k)
        rc = sim_scene_set_snapshots(*out, (int)snapshots, err);
    if (rc < 0) {
        sim_scene_free(*out);
        *out = NULL;
    }
    return rc;
}

#define BENCH_PATTERN_US 1000

/* Replace each problem's measurement by the simulated bench's snapshot of its masks (scene handed over). */
static int measure_on_bench(sim_scene *scene, sci_problem **p, int k, json_t *record, sci_error *err)
{
    sim_bench_options o = sim_bench_options_default();
    o.scene = scene;
    o.seed = scene->seed;
    sim_bench *b = NULL;
    dmd *dev = NULL;
    int rc = sim_bench_open(&b, &o, err);
    if (rc < 0)
        return rc;
    dmd_config dc = dmd_config_default();
    sim_bench_size(b, &dc.width, &dc.height); /* a mirror per pixel */
    if ((rc = dmd_open(&dev, &dmd_sim_ops, &dc, err)) == 0) {
        sim_bench_attach_dmd(b, dev);
        for (int j = 0; rc == 0 && j < k; j++) {
            sim_bench_set_snapshot(b, j);
            rc = sim_bench_snapshot(b, p[j]->mask, BENCH_PATTERN_US, p[j]->meas, err);
        }
        sim_bench_attach_dmd(b, NULL);
    }
    if (rc == 0) {
        const sim_bench_options *u = sim_bench_get_options(b);
        json_object_set_new(record, "bench",
                            json_pack("{s:s, s:i, s:f, s:f, s:f, s:I, s:s}", "model", "sim/bench.h", "pattern_us",
                                      BENCH_PATTERN_US, "counts_per_unit", u->counts_per_unit, "dark_counts",
                                      u->dark_counts, "read_noise_counts", u->read_noise, "dmd_latency_ns",
                                      (json_int_t)u->dmd_latency_ns, "measurement",
                                      "(counts - dark_counts) / counts_per_unit; effects on the measurement not "
                                      "applied"));
    }
    dmd_close(dev);
    sim_bench_close(b);
    return rc;
}

typedef struct progress {
    int quiet;
    int64_t t0_ns;
} progress;

static int on_progress(void *user, int done, int total)
{
    progress *p = user;
    if (!p->quiet)
        fprintf(stderr, "scicap sim: snapshot %d/%d rendered and measured (%.1f s)\n", done, total,
                sci_clock_s(p->t0_ns, sci_clock_mono_ns()));
    return 0;
}

static int parse_ull(const char *s, const char *opt, unsigned long long hi, unsigned long long *out)
{
    char *end;
    errno = 0;
    unsigned long long v = strtoull(s, &end, 0);
    if (errno || *end || end == s || s[0] == '-' || v > hi) {
        fprintf(stderr, "scicap sim: %s wants an integer in [0, %llu], got '%s'\n", opt, hi, s);
        return -1;
    }
    *out = v;
    return 0;
}

/* scicap sim's command line, as parsed. */
typedef struct sim_opts {
    const char *out;
    int force, quiet, use_default, have_seed, have_k, bench;
    unsigned long long seed, snapshots, threads;
} sim_opts;

/* Parses the options into o. Returns -1 to go on, else the exit code (0 after --help, 2 on a bad option). */
static int sim_opts_parse(sim_opts *o, int argc, char **argv)
{
    enum { OPT_SEED = 256, OPT_SNAPSHOTS, OPT_DEFAULT, OPT_BENCH };
    static const struct option longopts[] = {
        {"output", required_argument, 0, 'o'},     {"force", no_argument, 0, 'f'},
        {"seed", required_argument, 0, OPT_SEED},  {"snapshots", required_argument, 0, OPT_SNAPSHOTS},
        {"default", no_argument, 0, OPT_DEFAULT},  {"threads", required_argument, 0, 'j'},
        {"bench", no_argument, 0, OPT_BENCH},
        {"quiet", no_argument, 0, 'q'},            {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, "o:fj:qh", longopts, NULL)) != -1) {
        switch (c) {
        case 'o': o->out = optarg; break;
        case 'f': o->force = 1; break;
        case 'q': o->quiet = 1; break;
        case OPT_DEFAULT: o->use_default = 1; break;
        case OPT_BENCH: o->bench = 1; break;
        case OPT_SEED:
            if (parse_ull(optarg, "--seed", 1ULL << 53, &o->seed) < 0)
                return 2;
            o->have_seed = 1;
            break;
        case OPT_SNAPSHOTS:
            if (parse_ull(optarg, "--snapshots", 1024, &o->snapshots) < 0 || o->snapshots < 1) {
                if (o->snapshots < 1)
                    fprintf(stderr, "scicap sim: --snapshots must be at least 1\n");
                return 2;
            }
            o->have_k = 1;
            break;
        case 'j':
            if (parse_ull(optarg, "--threads", 1024, &o->threads) < 0 || o->threads < 1)
                return 2;
            break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    return -1;
}

/* One scene file, or none with --default, and an output folder. Returns 0, or 2 after a message. */
static int sim_opts_check(const sim_opts *o, int nargs)
{
    if ((o->use_default && nargs != 0) || (!o->use_default && nargs != 1)) {
        fprintf(stderr, "scicap sim: %s\n", o->use_default ? "--default takes no scene file"
                                                           : "give exactly one scene file (or --default)");
        usage(stderr);
        return 2;
    }
    if (!o->out) {
        fprintf(stderr, "scicap sim: an output folder is required (-o DIR)\n");
        return 2;
    }
    return 0;
}

/* Colour: the problems are the raw mosaic; the RGB truth goes beside them for colour PSNR and previews. *rgb gets
 * k cubes (the caller frees them, also on failure). Returns 0 or -errno with err filled. */
static int sim_write_color(const sim_opts *o, const sim_scene *sc, sci_problem **p, int k, json_t *record,
                           sci_cube ***rgb, sci_error *err)
{
    int rc;
    if (!(*rgb = calloc((size_t)k, sizeof **rgb)))
        return sci_error_set(err, -ENOMEM, "out of memory for the RGB truth");
    for (int j = 0; j < k; j++)
        if ((rc = sci_cube_new(&(*rgb)[j], sc->w, sc->h, 3 * sc->n, err)) < 0 ||
            (rc = sim_render_truth_rgb(sc, j, (*rgb)[j], err)) < 0)
            return rc;
    const sci_problem_color col = {.cfa = sc->cfa, .truth_rgb = *rgb};
    return sci_problem_dir_write_color(o->out, p, k, record, &col, o->force, 1, err);
}

/* The closing line on stdout: what was written, the effects listed, the time since t0_ns. */
static void sim_report_print(const sim_opts *o, const sim_scene *sc, int k, int64_t t0_ns)
{
    printf("wrote %s: %s%s%s, %dx%dx%d, %d snapshot(s), effects:", o->out, sim_scene_kind_name(sc->kind),
           sc->cfa ? ", colour, Bayer " : "", sc->cfa ? sci_cfa_name((sci_cfa)sc->cfa) : "", sc->w, sc->h, sc->n, k);
    int any = 0;
    for (int e = 0; e < SIM_FX_COUNT; e++)
        if (sim_fx_listed(&sc->fx, e)) {
            printf(" %s", sim_fx_name(e));
            any = 1;
        }
    printf("%s%s (%.2f s)\n", any ? "" : " none", o->bench ? ", measured on the simulated bench" : "",
           sci_clock_s(t0_ns, sci_clock_mono_ns()));
}

int cli_sim_main(int argc, char **argv)
{
    sim_opts o = {0};
    int rc = sim_opts_parse(&o, argc, argv);
    if (rc >= 0)
        return rc;
    if (sim_opts_check(&o, argc - optind) != 0)
        return 2;
    if (o.threads)
        omp_set_num_threads((int)o.threads);

    sci_error err = {0};
    sim_scene *sc = NULL;
    sci_problem **p = NULL;
    json_t *record = NULL;
    sci_cube **rgb = NULL;
    int k = 0, status = 1;
    const char *path = o.use_default ? NULL : argv[optind];
    rc = load_scene(o.use_default, path, o.have_seed, o.seed, o.have_k, o.snapshots, &sc, &err);
    if (rc < 0)
        goto fail;
    if (o.bench && sc->cfa) {
        rc = sci_error_set(&err, -EINVAL, "--bench: the simulated bench's camera is grey; %s has a colour sensor",
                           sc->name);
        goto fail;
    }
    if (!o.force && access(o.out, F_OK) == 0) {
        rc = sci_error_set(&err, -EEXIST, "%s exists (use --force to replace it)", o.out);
        goto fail;
    }
    progress pr = {o.quiet, sci_clock_mono_ns()};
    if (!o.quiet)
        fprintf(stderr, "scicap sim: %s: %s %dx%d, %d frames x %d snapshot(s), supersample %d, seed %llu\n",
                sc->name, sim_scene_kind_name(sc->kind), sc->w, sc->h, sc->n, sc->snapshots, sc->supersample,
                (unsigned long long)sc->seed);
    sim_stats st;
    if ((rc = sim_run(sc, &p, &k, &st, on_progress, &pr, &err)) < 0)
        goto fail;
    if (!(record = sim_record_new(sc, &st))) {
        rc = sci_error_set(&err, -ENOMEM, "out of memory for the scene record");
        goto fail;
    }
    if (o.bench) {
        sim_scene *again; /* the bench keeps a scene of its own */
        if ((rc = load_scene(o.use_default, path, o.have_seed, o.seed, o.have_k, o.snapshots, &again, &err)) < 0 ||
            (rc = measure_on_bench(again, p, k, record, &err)) < 0)
            goto fail;
    }
    if (sc->cfa)
        rc = sim_write_color(&o, sc, p, k, record, &rgb, &err);
    else
        rc = sci_problem_dir_write(o.out, p, k, record, o.force, &err);
    if (rc < 0)
        goto fail;
    sim_report_print(&o, sc, k, pr.t0_ns);
    status = 0;
    goto done;
fail:
    fprintf(stderr, "scicap sim: %s\n", err.msg[0] ? err.msg : sci_strerror(rc));
done:
    json_decref(record);
    for (int j = 0; rgb && j < k; j++)
        sci_cube_free(rgb[j]);
    free(rgb);
    if (p)
        sci_problem_array_free(p, k);
    sim_scene_free(sc);
    return status;
}
