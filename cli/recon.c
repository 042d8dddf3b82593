/* scicap recon — reconstruct SCI snapshots from a .mat benchmark file or a problem folder: parse the command line
 * into recon_opts, check it and the output against the limits, read the input, run the method on each snapshot
 * and report. The method's settings come from the solver table through cli/recon_opts.h. */
#include <dirent.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <omp.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/clock.h"
#include "base/error.h"
#include "base/file.h"
#include "cli/client.h"
#include "cli/commands.h"
#include "cli/progress.h"
#include "cli/recon_color.h"
#include "cli/recon_opts.h"
#include "io/limits.h"
#include "io/problem_dir.h"
#include "io/recon_store.h"
#include "io/source.h"
#include "io/staging.h"
#include "recon/metrics.h"
#include "recon/solver.h"

enum { OPT_MASK = 256, OPT_MASK_VAR, OPT_MEAS_VAR, OPT_TRUTH_VAR, OPT_SCALE, OPT_FRAMES, OPT_MASK_SCALE,
       OPT_PREVIEW, OPT_CFA, OPT_DEMOSAIC, OPT_ALLOW_LARGE, OPT_CKPT, OPT_CKPT_EVERY, OPT_RESUME };
#define SETTING CLI_RECON_OPT_SETTING
#define SETTING_SHORT CLI_RECON_OPT_SETTING_SHORT

/* The command's own options, then the method settings the man page documents by name (test_cli_help reads this
 * table from the source to check help and man page). A setting's type, range and help are the method table's,
 * and every other key of every method is an option too (cli_recon_opts_longopts). */
static const struct option longopts[] = {
    {"method", required_argument, 0, 'm'}, {"output", required_argument, 0, 'o'},
    {"force", no_argument, 0, 'f'}, {"snapshot", required_argument, 0, 's'},
    {"threads", required_argument, 0, 'j'}, {"quiet", no_argument, 0, 'q'},
    {"help", no_argument, 0, 'h'}, {"allow-large", no_argument, 0, OPT_ALLOW_LARGE},
    {"preset", required_argument, 0, CLI_RECON_OPT_PRESET}, {"set", required_argument, 0, CLI_RECON_OPT_SET},
    {"checkpoint", required_argument, 0, OPT_CKPT}, {"checkpoint-every", required_argument, 0, OPT_CKPT_EVERY},
    {"resume", required_argument, 0, OPT_RESUME},
    {"mask", required_argument, 0, OPT_MASK}, {"mask-var", required_argument, 0, OPT_MASK_VAR},
    {"meas-var", required_argument, 0, OPT_MEAS_VAR}, {"truth-var", required_argument, 0, OPT_TRUTH_VAR},
    {"scale", required_argument, 0, OPT_SCALE}, {"frames", required_argument, 0, OPT_FRAMES},
    {"mask-scale", required_argument, 0, OPT_MASK_SCALE}, {"preview-range", required_argument, 0, OPT_PREVIEW},
    {"cfa", required_argument, 0, OPT_CFA}, {"demosaic", required_argument, 0, OPT_DEMOSAIC},
    {"iters", required_argument, 0, SETTING_SHORT('i')}, {"lambda", required_argument, 0, SETTING_SHORT('l')},
    {"tv-weight", required_argument, 0, SETTING_SHORT('w')}, {"tv-iters", required_argument, 0, SETTING_SHORT('t')},
    {"gamma", required_argument, 0, SETTING_SHORT('g')}, {"plain", no_argument, 0, SETTING},
    {"metrics-every", required_argument, 0, SETTING}, {"ssim-every", required_argument, 0, SETTING},
    {"patch", required_argument, 0, SETTING}, {"patches-per-step", required_argument, 0, SETTING},
    {"samples", required_argument, 0, SETTING}, {"lr", required_argument, 0, SETTING},
    {"pose-mode", required_argument, 0, SETTING}, {"seed", required_argument, 0, SETTING},
    {"ablation", required_argument, 0, SETTING}, {"net-lr-scale", required_argument, 0, SETTING},
    {"spacing", required_argument, 0, SETTING}, {"distortion", required_argument, 0, SETTING},
    {"prior-steps", required_argument, 0, SETTING}, {"prior-weight", required_argument, 0, SETTING},
    {"density-bias", required_argument, 0, SETTING}, {"zero-gates", required_argument, 0, SETTING},
    {"sh-degree", required_argument, 0, SETTING}, {0, 0, 0, 0},
};
static const char shortopts[] = "m:o:fs:i:l:w:t:g:j:qh";

/* What one `scicap recon` was asked to do. Owns all and settings (recon_opts_free). */
typedef struct recon_opts {
    const solver_ops *const *methods; /* the method table (recon/solver.h) */
    struct option *all;               /* longopts, then the other settings keys (owned) */
    cli_recon_given given;            /* the settings options as given */
    const solver_ops *method;
    void *settings;                   /* the method's, owned; NULL until the options are parsed */
    const char *input, *out, *ckpt_path, *resume_path, *cfa_opt;
    int force, quiet, preview_auto, snapshot, threads, ckpt_every, help;
    sci_demosaic_method demosaic;
    sci_mat_options mo;
    sci_io_limits limits;             /* mo.limits points here */
} recon_opts;

/* "a, b and c": the methods with (want = 1) or without (want = 0) the capability bits `caps`. */
static char *methods_with(const solver_ops *const *l, char *buf, size_t n, unsigned caps, int want)
{
    int k = 0, total = 0;
    for (int i = 0; l[i]; i++)
        total += ((l[i]->caps & caps) != 0) == want;
    size_t off = 0;
    buf[0] = 0;
    for (int i = 0; l[i] && off < n; i++)
        if (((l[i]->caps & caps) != 0) == want) {
            k++;
            off += (size_t)snprintf(buf + off, n - off, "%s%s", k == 1 ? "" : k == total ? " and " : ", ",
                                    l[i]->name);
        }
    return buf;
}

static void usage(FILE *f, const recon_opts *o)
{
    fprintf(f, "usage: scicap recon [OPTIONS] INPUT -o OUTDIR\n"
               "       scicap recon [OPTIONS] INPUT... -o OUTDIR   (several: as scicap batch, OUTDIR/NAME each)\n"
               "       scicap recon --capture ID [--method M] [--wait]   (ask scicapd; see scicap status)\n\n"
               "Methods (-m, --method NAME; default %s):\n", o->methods[0]->name);
    cli_recon_methods_usage(f, o->methods, 12);
    fprintf(f,
            "\n"
            "Reconstruct the N frames of each SCI snapshot in INPUT: a .mat file (MATLAB v5 or v7.3; by default the\n"
            "benchmark's variables mask, meas, orig with values divided by 255) or a problem folder written by\n"
            "'scicap sim' or by scicapd.\n"
            "Writes OUTDIR (OUTDIR/snap_NNN/ when INPUT has several snapshots) with float EXR frames, PNG and GIF\n"
            "previews, trace.csv (time against accuracy per iteration) and result.json. When the truth is known\n"
            "it prints per-frame and mean PSNR in both peak conventions, and SSIM.\n"
            "\n"
            "  -m, --method NAME      one of the methods above (those that need a camera want a static scene\n"
            "                         seen by a moving camera, e.g. from a static3d scene; see docs/nerf-methods.md)\n"
            "  -o, --output DIR       output folder (required); replaced only with --force\n"
            "  -f, --force            replace an existing output folder\n"
            "      --allow-large      lift the size limits checked before any work: %.0f GB of input in memory,\n"
            "                         %.0f GB or %zu files of output (a small file can declare huge sizes)\n"
            "  -s, --snapshot J       reconstruct only snapshot J (1-based); default all\n"
            "      --checkpoint FILE  %s: write a checkpoint every --checkpoint-every K steps (default 100),\n"
            "                         at the end, and when interrupted (Ctrl-C, SIGTERM)\n"
            "      --resume FILE      continue a run from its checkpoint (same input and options)\n"
            "  .mat input:  --mask FILE        the masks are in FILE (its only variable, or --mask-var)\n"
            "              --mask-var NAME    the masks' variable (default mask): H×W×N shared, H×W×N×k per snapshot\n"
            "              --meas-var NAME    the measurements' variable (default meas), H×W×k\n"
            "              --truth-var NAME   the truth's variable (default orig, optional), H×W×(k·N)\n"
            "              --frames N         use the first N mask frames (the capture's compression ratio, when\n"
            "                                 the mask sequence is longer)\n"
            "              --scale auto|N     the value of white in meas and truth (default auto: from the truth's\n"
            "                                 range, else from meas over the sum of masks; the line printed says)\n"
            "              --mask-scale auto|N  the value of a fully open mask pixel (default auto: the masks'\n"
            "                                 maximum when above 1, so measured grey masks land on [0, 1])\n"
            "  colour:      --cfa PATTERN      RGGB, BGGR, GRBG or GBRG: the Bayer pattern of a raw mosaic input (a\n"
            "                                 colour folder from 'scicap sim' names its own); none: treat it as grey\n"
            "              --demosaic M       mhc (default, Malvar-He-Cutler) or bilinear, after the 4 CFA planes\n"
            "                                 are solved; writes rgb_NNN.exr, colour preview_rgb_NNN.png, RGB PSNR\n"
            "      --preview-range fixed|auto  previews on [0, white] (default) or auto-contrast to the frames'\n"
            "                         99.5th percentile (stated in result.json and each PNG's description)\n"
            "  -j, --threads N        OpenMP threads (default: all cores)\n"
            "  -q, --quiet            no progress on stderr\n"
            "  -h, --help             this text\n",
            (double)SCI_IO_LIMIT_INPUT_BYTES / 1e9, (double)SCI_IO_LIMIT_OUTPUT_BYTES / 1e9,
            (size_t)SCI_IO_LIMIT_OUTPUT_FILES, methods_with(o->methods, (char[256]){0}, 256, SOLVER_CHECKPOINTS, 1));
    cli_recon_opts_usage(f, o->methods, o->all);
    fprintf(f, "\n"
               "Without --preset a method runs its defaults (the classical ones: the PnP-SCI benchmark's settings);\n"
               "result.json's params records every value. PSNR 'peak = frame max' uses each truth frame's maximum\n"
               "(the MATLAB reference's convention); 'peak = 1' uses the data's white level. Exit status: 0 ok,\n"
               "1 failure, 2 usage; on SIGINT/SIGTERM/SIGHUP/SIGQUIT it stops, removes what it had begun to write,\n"
               "and dies of that signal: OUTDIR appears only once complete (written as OUTDIR.tmp-PID and renamed;\n"
               "one left by a process that no longer runs is removed at the next run into OUTDIR).\n");
}
/* Ctrl-C / SIGTERM: the progress callback asks the solver to stop (a NeRF run first hands over its checkpoint);
 * nothing more is written and the process then dies of the same signal, so a calling shell loop stops too. The
 * handler is one-shot: a second Ctrl-C kills at once. */
static volatile sig_atomic_t stop_requested; /* the signal number, 0 while none */

static void on_stop_signal(int sig)
{
    stop_requested = sig;
}

/* A closed terminal (SIGHUP) or Ctrl-\ (SIGQUIT) ends a run as Ctrl-C does: nothing half-written stays behind. */
static const int stop_signals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};
#define STOP_SIGNALS ((int)(sizeof stop_signals / sizeof stop_signals[0]))

/* Remove OUT.tmp-PID folders whose process is gone (a run killed by SIGKILL or a power cut), saying so on stderr;
 * those of a living process are another run's and stay. */
static void clean_stale_stages(const char *out)
{
    char dir[4096], base[4096];
    snprintf(dir, sizeof dir, "%s", out);
    snprintf(base, sizeof base, "%s", out);
    size_t bl = strlen(base);
    while (bl > 1 && base[bl - 1] == '/')
        base[--bl] = '\0';
    char *slash = strrchr(base, '/');
    const char *name = slash ? slash + 1 : base;
    if (slash) {
        snprintf(dir, sizeof dir, "%.*s", slash == base ? 1 : (int)(slash - base), base);
    } else {
        snprintf(dir, sizeof dir, ".");
    }
    DIR *d = opendir(dir);
    if (!d)
        return;
    const size_t l = strlen(name);
    struct dirent *e;
    while ((e = readdir(d))) {
        char *end;
        if (strncmp(e->d_name, name, l) != 0 || strncmp(e->d_name + l, ".tmp-", 5) != 0)
            continue;
        long pid = strtol(e->d_name + l + 5, &end, 10);
        if (*end || pid <= 0 || pid == (long)getpid() || kill((pid_t)pid, 0) == 0 || errno != ESRCH)
            continue; /* not a staging name, or its writer is still alive */
        char p[8300];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        sci_staging_remove(p);
        fprintf(stderr, "scicap recon: removed %s, left by process %ld which no longer runs\n", p, pid);
    }
    closedir(d);
}

/* The NeRF checkpoint callback: the blob replaces path atomically (never a half-written checkpoint). */
typedef struct ckpt_file {
    const char *path;
    int written, iter;
} ckpt_file;

static int write_checkpoint(const void *blob, size_t bytes, int iter, void *user)
{
    ckpt_file *c = user;
    int rc = sci_file_write_atomic(c->path, blob, bytes, 0644, 0, NULL);
    if (rc < 0)
        return rc;
    c->written++, c->iter = iter;
    return 0;
}

static int parse_int(const char *s, const char *opt, int lo, int hi, int *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || *end || end == s || v < lo || v > hi) {
        fprintf(stderr, "scicap recon: %s wants an integer in [%d, %d], got '%s'\n", opt, lo, hi, s);
        return -1;
    }
    *out = (int)v;
    return 0;
}

static int parse_double(const char *s, const char *opt, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || *end || end == s || !isfinite(v)) {
        fprintf(stderr, "scicap recon: %s wants a number, got '%s'\n", opt, s);
        return -1;
    }
    *out = v;
    return 0;
}

/* result.json's "params": the method's settings, and for a resumable method whether this run was resumed. */
static json_t *params_json(const recon_opts *o, int resumed)
{
    json_t *j = solver_settings_to_json(o->method, o->settings);
    if (j && (o->method->caps & SOLVER_CHECKPOINTS))
        json_object_set_new(j, "resumed", json_boolean(resumed));
    return j;
}

static void print_metrics(const sci_problem *p, const sci_result *r)
{
    const int n = r->frames->n;
    double *v = malloc(3 * (size_t)n * sizeof *v);
    if (!v)
        return;
    double m0 = sci_psnr(r->frames, p->truth, SCI_PEAK_FRAME_MAX, 0, v);
    double m1 = sci_psnr(r->frames, p->truth, SCI_PEAK_FIXED, p->peak, v + n);
    double ms = sci_ssim(r->frames, p->truth, p->peak, v + 2 * n);
    printf("  frame   PSNR dB (peak = frame max)   PSNR dB (peak = %g)   SSIM\n", p->peak);
    for (int k = 0; k < n; k++)
        printf("  %5d   %26.2f   %19.2f   %.4f\n", k + 1, v[k], v[n + k], v[2 * n + k]);
    printf("  mean    %26.2f   %19.2f   %.4f\n", m0, m1, ms);
    free(v);
}

/* The frames' levels against white, and a warning when the scale looks wrong (io/recon_store.h). */
static void print_levels(const sci_problem *p, const sci_result *r)
{
    double p1, p99;
    char warn[320];
    int bad = sci_recon_levels(p, r->frames, &p1, &p99, warn, sizeof warn);
    printf("  frames: 1st percentile %.3f, 99th %.3f of white\n", p1, p99);
    if (bad)
        fprintf(stderr, "scicap recon: WARNING: %s\n", warn);
}

/* result.json's "input": how a .mat was read (scales and frames, what was inferred, any warning); NULL for a
 * problem folder, which states its own. */
static json_t *input_json(const sci_mat_info *mi)
{
    if (!(mi->white > 0))
        return NULL;
    json_t *in = json_pack("{s:f, s:f, s:f, s:i, s:i}", "white", mi->white, "meas_white", mi->meas_white,
                           "mask_white", mi->mask_white, "frames", mi->frames, "mask_frames", mi->mask_frames);
    if (mi->how[0])
        json_object_set_new(in, "inferred", json_string(mi->how));
    if (mi->warning[0])
        json_object_set_new(in, "warnings", json_pack("[s]", mi->warning));
    return json_pack("{s:o}", "input", in);
}


/* --scale / --mask-scale: "auto" (auto_value) or a number > 0. */
static int parse_white(const char *s, const char *opt, const char *what, double auto_value, double *out)
{
    if (strcmp(s, "auto") == 0) {
        *out = auto_value;
        return 0;
    }
    if (parse_double(s, opt, out) < 0)
        return -1;
    if (*out > 0)
        return 0;
    fprintf(stderr, "scicap recon: %s wants auto or a number > 0 (%s), got '%s'\n", opt, what, s);
    return -1;
}

/* One of the command's own options (not a method setting). 0, 1 when c is not one of them, or -1 after a message. */
static int take_own(recon_opts *o, int c, const char *arg)
{
    sci_cfa cfa;
    sci_error err = {0};
    switch (c) {
    case 'm':
        o->method = solver_list_find(o->methods, arg, &err);
        return o->method ? 0 : (fprintf(stderr, "scicap recon: %s\n", err.msg), -1);
    case 'o': o->out = arg; return 0;
    case 'f': o->force = 1; return 0;
    case 'q': o->quiet = 1; return 0;
    case 'h': o->help = 1; return 0;
    case 's': return parse_int(arg, "--snapshot", 1, 1 << 30, &o->snapshot);
    case 'j': return parse_int(arg, "--threads", 1, 1024, &o->threads);
    case OPT_ALLOW_LARGE: sci_io_limits_none(&o->limits); return 0;
    case OPT_CKPT: o->ckpt_path = arg; return 0;
    case OPT_CKPT_EVERY: return parse_int(arg, "--checkpoint-every", 1, 1 << 30, &o->ckpt_every);
    case OPT_RESUME: o->resume_path = arg; return 0;
    case OPT_MASK: o->mo.mask_path = arg; return 0;
    case OPT_MASK_VAR: o->mo.mask_var = arg; return 0;
    case OPT_MEAS_VAR: o->mo.meas_var = arg; return 0;
    case OPT_TRUTH_VAR: o->mo.truth_var = arg; return 0;
    case OPT_FRAMES: return parse_int(arg, "--frames", 1, 1 << 16, &o->mo.frames);
    case OPT_SCALE: return parse_white(arg, "--scale", "the value of white", SCI_MAT_WHITE_AUTO, &o->mo.white);
    case OPT_MASK_SCALE: return parse_white(arg, "--mask-scale", "a fully open mask pixel", 0, &o->mo.mask_white);
    case OPT_PREVIEW:
        if (strcmp(arg, "auto") == 0 || strcmp(arg, "fixed") == 0)
            return o->preview_auto = arg[0] == 'a', 0;
        fprintf(stderr, "scicap recon: --preview-range wants fixed or auto, got '%s'\n", arg);
        return -1;
    case OPT_CFA:
        o->cfa_opt = arg;
        if (sci_cfa_parse(arg, &cfa) == 0)
            return 0;
        fprintf(stderr, "scicap recon: --cfa wants RGGB, BGGR, GRBG, GBRG or none, got '%s'\n", arg);
        return -1;
    case OPT_DEMOSAIC:
        if (sci_demosaic_parse(arg, &o->demosaic) == 0)
            return 0;
        fprintf(stderr, "scicap recon: --demosaic wants mhc or bilinear, got '%s'\n", arg);
        return -1;
    }
    return 1;
}

/* The command line into o (argv is permuted: options first, as getopt_long leaves it). 0, 1 (out of memory), or 2
 * after a message; o->help set by -h. Free o with recon_opts_free whatever it returns. */
static int recon_opts_parse(recon_opts *o, const solver_ops *const *methods, int argc, char **argv)
{
    *o = (recon_opts){.methods = methods, .method = methods[0], .ckpt_every = 100, .demosaic = SCI_DEMOSAIC_MHC};
    o->given.methods = methods;
    sci_io_limits_default(&o->limits);
    o->mo.limits = &o->limits;
    if (!(o->all = cli_recon_opts_longopts(methods, longopts))) {
        fprintf(stderr, "scicap recon: out of memory\n");
        return 1;
    }
    optind = 1;
    int c, idx = -1;
    while ((c = getopt_long(argc, argv, shortopts, o->all, &idx)) != -1) {
        int rc = take_own(o, c, optarg);
        if (rc == 1)
            rc = cli_recon_opts_take(&o->given, o->all, c, idx, optarg);
        if (rc == 1)
            usage(stderr, o);
        if (rc)
            return 2;
        if (o->help)
            return 0; /* the help, whatever follows */
        idx = -1;
    }
    return 0;
}

static void recon_opts_free(recon_opts *o)
{
    solver_settings_free(o->settings);
    free(o->all);
}

/* The method's settings from the options, and what they allow. 0, 1 (out of memory) or 2 after a message. */
static int recon_opts_settings(recon_opts *o)
{
    char names[256];
    if (!(o->settings = solver_settings_new(o->method))) {
        fprintf(stderr, "scicap recon: out of memory\n");
        return 1;
    }
    int rc = cli_recon_opts_apply(&o->given, o->method, o->settings);
    if (o->threads)
        omp_set_num_threads(o->threads);
    if (rc == 0 && (o->ckpt_path || o->resume_path) && !(o->method->caps & SOLVER_CHECKPOINTS)) {
        fprintf(stderr, "scicap recon: --checkpoint and --resume are for %s\n",
                methods_with(o->methods, names, sizeof names, SOLVER_CHECKPOINTS, 1));
        rc = 2;
    }
    return rc;
}

/* Before any work: the output may be written (--force), the input's declared sizes and what writing them would
 * make are within the limits (io/limits.h), the output's folder is there and writable (not after hours of
 * solving). 0, 1 or 2 after a message. */
static int recon_check_output(const recon_opts *o)
{
    sci_error err = {0};
    long long dw, dh, dn, dk;
    if (access(o->out, F_OK) == 0 && !o->force) {
        fprintf(stderr, "scicap recon: %s already exists (use --force to replace it)\n", o->out);
        return 1;
    }
    int rc = sci_source_probe(o->input, &o->mo, &dw, &dh, &dn, &dk, &err);
    if (rc == 0) {
        double bytes, files;
        const long long nsel = o->snapshot ? 1 : dk;
        sci_recon_store_estimate(dw, dh, dn, nsel, &bytes, &files);
        char what[4400];
        snprintf(what, sizeof what, "%s (from %s: %lld snapshot(s) of %lldx%lld pixels, %lld frames each)", o->out,
                 o->input, nsel, dw, dh, dn);
        rc = sci_io_limits_check_output(&o->limits, what, bytes, files + (nsel > 1), &err);
    }
    if (rc < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        return rc == -EINVAL ? 2 : 1;
    }
    char parent[4096];
    snprintf(parent, sizeof parent, "%s", o->out);
    char *slash = strrchr(parent, '/');
    while (slash && slash > parent && slash[1] == 0) /* "out/" */
        *slash = 0, slash = strrchr(parent, '/');
    if (!slash)
        snprintf(parent, sizeof parent, ".");
    else
        slash[slash == parent] = 0; /* "/out" keeps "/" */
    if (access(parent, W_OK | X_OK) != 0) {
        fprintf(stderr, "scicap recon: cannot write %s: %s: %s\n", o->out, parent, strerror(errno));
        return 1;
    }
    return 0;
}

/* One run over the input's snapshots: what it read and holds until recon_job_free. */
typedef struct recon_job {
    const recon_opts *o;
    sci_problem **probs;
    int k, first, last;
    sci_mat_info minfo;
    sci_cube **truth_rgb; /* a colour folder's RGB truth, kc of them, or NULL */
    int kc;
    sci_cfa cfa;
    void *resume_blob;
    ckpt_file ck;
    solver_io io;
    json_t *params, *input_info;
    char stage[4096];     /* OUTDIR.tmp-PID of several snapshots, "" for one */
} recon_job;

static void recon_job_free(recon_job *j)
{
    json_decref(j->params);
    json_decref(j->input_info);
    for (int i = 0; j->truth_rgb && i < j->kc; i++)
        sci_cube_free(j->truth_rgb[i]);
    free(j->truth_rgb);
    free(j->resume_blob);
    sci_problem_array_free(j->probs, j->k);
}

/* Read the input (and a colour folder's CFA and RGB truth), check what it allows, read the checkpoint to resume.
 * 0, 1 or 2 after a message. */
static int recon_job_load(recon_job *j, const recon_opts *o)
{
    sci_error err = {0};
    char names[256];
    *j = (recon_job){.o = o, .cfa = SCI_CFA_NONE, .ck = {.path = o->ckpt_path}};
    int rc = sci_source_read_opts(o->input, &o->mo, &j->probs, &j->k, &j->minfo, &err);
    if (rc < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        return rc == -EINVAL ? 2 : 1;
    }
    if (j->minfo.how[0])
        fprintf(stderr, "scicap recon: scale: %s (override with --scale / --mask-scale)\n", j->minfo.how);
    if (j->minfo.warning[0])
        fprintf(stderr, "scicap recon: WARNING: %s\n", j->minfo.warning);
    /* Colour: a folder from a colour scene names its CFA and keeps the RGB truth; --cfa overrides (none: grey). */
    int cfa = SCI_CFA_NONE;
    if (!sci_source_is_mat(o->input) && sci_problem_dir_read_color(o->input, &cfa, &j->truth_rgb, &j->kc, &err) < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        return 1;
    }
    j->cfa = (sci_cfa)cfa;
    if (o->cfa_opt)
        sci_cfa_parse(o->cfa_opt, &j->cfa);
    if (j->cfa != SCI_CFA_NONE && (o->method->caps & SOLVER_NEEDS_CAMERA)) {
        fprintf(stderr, "scicap recon: %s is a Bayer mosaic; colour reconstruction runs %s per CFA plane (--cfa none "
                        "reconstructs it as grey)\n", o->input,
                methods_with(o->methods, names, sizeof names, SOLVER_NEEDS_CAMERA, 0));
        return 2;
    }
    if (o->snapshot > j->k) {
        fprintf(stderr, "scicap recon: %s has %d snapshot(s); --snapshot %d is out of range\n", o->input, j->k,
                o->snapshot);
        return 2;
    }
    j->first = o->snapshot ? o->snapshot - 1 : 0, j->last = o->snapshot ? o->snapshot - 1 : j->k - 1;
    if ((o->ckpt_path || o->resume_path) && j->first != j->last) {
        fprintf(stderr, "scicap recon: %s has %d snapshots; a checkpoint belongs to one (add --snapshot J)\n",
                o->input, j->k);
        return 2;
    }
    j->io = (solver_io){.progress = cli_progress_update};
    if (o->resume_path) {
        if (sci_file_read(o->resume_path, (size_t)16 << 30, &j->resume_blob, &j->io.resume_bytes, &err) < 0) {
            fprintf(stderr, "scicap recon: --resume: %s\n", err.msg);
            return 1;
        }
        j->io.resume = j->resume_blob;
    }
    if (o->ckpt_path)
        j->io.checkpoint_fn = write_checkpoint, j->io.checkpoint_user = &j->ck, j->io.checkpoint_every = o->ckpt_every;
    return 0;
}

/* A colour snapshot (cli/recon_color.h). 0, or 1 after a message. */
static int recon_snapshot_color(recon_job *j, const sci_problem *p, int s, const char *dir, const char *shown)
{
    const recon_opts *o = j->o;
    sci_error err = {0};
    const cli_color_job job = {.cfa = j->cfa, .demosaic = o->demosaic, .method = o->method, .settings = o->settings,
                               .params = j->params, .quiet = o->quiet, .preview_auto = o->preview_auto,
                               .extra = j->input_info, .stop = &stop_requested};
    int rc = cli_recon_color(&job, p, j->truth_rgb && s < j->kc ? j->truth_rgb[s] : NULL, dir, o->force, &err);
    if (rc == SCI_ECANCELED || stop_requested) {
        fprintf(stderr, "scicap recon: interrupted; %s not written\n", o->out);
        return 1;
    }
    if (rc < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        return 1;
    }
    printf("  wrote %s/ (RGB: rgb_NNN.exr, preview_rgb_NNN.png)\n", shown);
    return 0;
}

/* A grey snapshot: solve with a progress bar, print the levels and metrics, write the result folder. 0, or 1
 * after a message. */
static int recon_snapshot_grey(recon_job *j, const sci_problem *p, const char *dir, const char *shown)
{
    const recon_opts *o = j->o;
    sci_error err = {0};
    sci_result r = {0};
    cli_progress prog;
    cli_progress_init(&prog, o->quiet ? -1 : 2, solver_settings_iters(o->method, o->settings));
    prog.stop = &stop_requested;
    int64_t t0 = sci_clock_mono_ns();
    j->io.user = &prog;
    int rc = solver_run(o->method, p, o->settings, &j->io, &r);
    double secs = sci_clock_s(t0, sci_clock_mono_ns());
    cli_progress_done(&prog);
    if (rc == SCI_ECANCELED || (rc == 0 && stop_requested)) {
        fprintf(stderr, "scicap recon: interrupted after %d iterations; %s not written", r.iters_done, o->out);
        if (j->ck.written)
            fprintf(stderr, "; checkpoint of step %d in %s (continue with --resume %s)", j->ck.iter, j->ck.path,
                    j->ck.path);
        fprintf(stderr, "\n");
    } else if (rc < 0) {
        fprintf(stderr, "scicap recon: %s\n", r.error.msg);
    } else {
        double solver_s = r.trace.len ? r.trace.e[r.trace.len - 1].wall_s : secs;
        printf("  %d iterations in %.3f s solver time (%.3f s with trace metrics), final residual %.3g\n",
               r.iters_done, solver_s, secs, r.trace.len ? r.trace.e[r.trace.len - 1].residual : NAN);
        print_levels(p, &r);
        if (p->truth)
            print_metrics(p, &r);
        const sci_recon_store_opts so = {.extra = j->input_info, .stop = &stop_requested,
                                         .preview_auto = o->preview_auto,
                                         .flags = j->first == j->last && o->force ? SCI_STAGING_OVERWRITE : 0};
        rc = sci_recon_store_save(dir, p, &r, j->params, &so, &err);
        if (rc == SCI_ECANCELED)
            fprintf(stderr, "scicap recon: interrupted while writing; %s not written\n", o->out);
        else if (rc < 0)
            fprintf(stderr, "scicap recon: %s\n", err.msg);
        else
            printf("  wrote %s/\n", shown);
    }
    sci_result_free_contents(&r);
    return rc < 0 || stop_requested ? 1 : 0;
}

/* Snapshot s into OUTDIR, or into the staging folder's snap_NNN when there are several. 0, or 1 after a message. */
static int recon_snapshot(recon_job *j, int s)
{
    const sci_problem *p = j->probs[s];
    const char *out = j->o->out;
    char dir[4200], shown[4200];
    printf("%s: %s, %dx%d, %d frames per snapshot%s\n", p->name, j->o->method->name, p->mask->w, p->mask->h,
           p->mask->n, p->truth ? ", truth known" : "");
    fflush(stdout);
    if (j->first == j->last) {
        snprintf(shown, sizeof shown, "%s", out);
        snprintf(dir, sizeof dir, "%s", out);
    } else {
        snprintf(shown, sizeof shown, "%s/snap_%03d", out, s + 1);
        snprintf(dir, sizeof dir, "%s/snap_%03d", j->stage, s + 1);
    }
    if (j->cfa != SCI_CFA_NONE)
        return recon_snapshot_color(j, p, s, dir, shown);
    return recon_snapshot_grey(j, p, dir, shown);
}

/* Every selected snapshot, with the stop signals caught; several are staged in OUTDIR.tmp-PID and published
 * together once the last is written (one alone is staged by the store itself); nothing is published on failure or
 * on a signal. Returns the exit status. */
static int recon_job_run(recon_job *j)
{
    const recon_opts *o = j->o;
    sci_error err = {0};
    int status = 0;
    struct sigaction sa = {.sa_handler = on_stop_signal, .sa_flags = SA_RESETHAND}, old_sig[STOP_SIGNALS];
    sigemptyset(&sa.sa_mask);
    for (int i = 0; i < STOP_SIGNALS; i++)
        sigaction(stop_signals[i], &sa, &old_sig[i]);
    clean_stale_stages(o->out);
    j->params = params_json(o, j->resume_blob != NULL);
    j->input_info = input_json(&j->minfo);
    if (j->first != j->last && (sci_staging_name(j->stage, sizeof j->stage, o->out) < 0 || mkdir(j->stage, 0755))) {
        fprintf(stderr, "scicap recon: %s: %s\n", j->stage[0] ? j->stage : o->out,
                strerror(errno ? errno : ENAMETOOLONG));
        status = 1;
    }
    for (int s = j->first; s <= j->last && status == 0; s++)
        status = recon_snapshot(j, s);
    if (j->stage[0] && status == 0) {
        if (sci_staging_publish(j->stage, o->out, o->force ? SCI_STAGING_OVERWRITE : 0, &stop_requested, &err) < 0) {
            if (err.code != SCI_ECANCELED)
                fprintf(stderr, "scicap recon: %s\n", err.msg);
            status = 1;
        } else {
            printf("wrote %s/\n", o->out);
        }
    } else if (j->stage[0]) {
        sci_staging_remove(j->stage);
    }
    for (int i = 0; i < STOP_SIGNALS; i++)
        sigaction(stop_signals[i], &old_sig[i], NULL);
    if (o->ckpt_path && j->ck.written && status == 0)
        printf("  checkpoint of step %d in %s\n", j->ck.iter, o->ckpt_path);
    return status;
}

/* The options checked and the input read, then the run; the exit status. */
static int recon_run(recon_opts *o)
{
    recon_job j;
    int status = recon_opts_settings(o);
    if (status == 0)
        status = recon_check_output(o);
    if (status)
        return status;
    status = recon_job_load(&j, o);
    if (status == 0)
        status = recon_job_run(&j);
    recon_job_free(&j);
    return status;
}

int cli_recon_main(int argc, char **argv)
{
    /* `scicap recon --capture ID` asks the daemon to reconstruct one of its captures. */
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "--capture") == 0 || strncmp(argv[i], "--capture=", 10) == 0)
            return cli_client_recon(argc, argv);
    recon_opts o;
    int status = recon_opts_parse(&o, solver_list(NULL), argc, argv);
    if (status == 0 && o.help) {
        usage(stdout, &o);
        printf("\nThrough the daemon (scicap recon --capture ID ...):\n\n");
        cli_client_usage(stdout, "reconstruct");
    } else if (status == 0 && o.out &&
               (optind < argc - 1 || (optind == argc - 1 && cli_batch_is_many(argv[optind])))) {
        /* Several inputs (or a folder of them, or a quoted glob): the batch of cli/batch.c, one scicap recon per
         * input into OUTDIR/NAME, resumable. getopt has moved the options before the inputs. */
        status = cli_batch_recon(optind - 1, argv + 1, argc - optind, argv + optind);
    } else if (status == 0 && (optind != argc - 1 || !o.out)) {
        fprintf(stderr, "scicap recon: %s\n", !o.out ? "-o OUTDIR is required" : "exactly one INPUT is required");
        usage(stderr, &o);
        status = 2;
    } else if (status == 0) {
        o.input = argv[optind];
        status = recon_run(&o);
    }
    recon_opts_free(&o);
    /* A stop signal ends the process with that signal, after the cleanup, so a calling shell loop stops too. */
    const int sig = stop_requested;
    if (sig) {
        fflush(NULL);
        signal(sig, SIG_DFL);
        raise(sig);
    }
    return status;
}
