/* scicap recon — reconstruct SCI snapshots from a .mat benchmark file or a problem folder. */
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
#include "io/limits.h"
#include "io/problem_dir.h"
#include "io/recon_store.h"
#include "io/source.h"
#include "io/staging.h"
#include "recon/metrics.h"
#include "recon/solver.h"

/* "a, b and c": the methods with (want = 1) or without (want = 0) the capability bits `caps`. */
static char *methods_with(char *buf, size_t n, unsigned caps, int want)
{
    const solver_ops *const *l = solver_list(NULL);
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

static void usage(FILE *f)
{
    const solver_ops *const *l = solver_list(NULL);
    fprintf(f, "usage: scicap recon [OPTIONS] INPUT -o OUTDIR\n"
               "       scicap recon [OPTIONS] INPUT... -o OUTDIR   (several: as scicap batch, OUTDIR/NAME each)\n"
               "       scicap recon --capture ID [--method M] [--wait]   (ask scicapd; see scicap status)\n\n"
               "Methods (-m, --method NAME; default %s):\n", l[0]->name);
    for (int i = 0; l[i]; i++)
        fprintf(f, "  %-12s %s\n", l[i]->name, l[i]->summary);
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
            "      --preset P         fast, balanced or best for every method (scicap --help lists each one's\n"
            "                         settings; the options below override it); none: the method's defaults\n"
            "  -o, --output DIR       output folder (required); replaced only with --force\n"
            "  -f, --force            replace an existing output folder\n"
            "      --allow-large      lift the size limits checked before any work: %.0f GB of input in memory,\n"
            "                         %.0f GB or %zu files of output (a small file can declare huge sizes)\n"
            "  -s, --snapshot J       reconstruct only snapshot J (1-based); default all\n"
            "  -i, --iters N          outer iterations (default: the method's, 100 for gap-tv and admm-tv)\n"
            "  -l, --lambda X         step size lambda (default 1)\n"
            "  -w, --tv-weight X      TV weight on the data's [0, peak] scale (default 0.07)\n"
            "  -t, --tv-iters N       TV denoiser passes per iteration (default 5)\n"
            "      --plain            gap-tv: plain GAP instead of accelerated\n"
            "  -g, --gamma X          admm-tv: gamma added to the mask energy (default 1e-3)\n"
            "  rayformer, scinerf:\n"
            "              --samples L (per ray)  --lr X  --pose-mode known|linear|per-frame  --seed S\n"
            "              (--iters applies too; rayformer also --patch P (2,4,8,16) --patches-per-step B --tv-weight)\n"
            "              --net-lr-scale X  rayformer: the transformer learns at lr × X, the hash table at lr\n"
            "              --ablation STEP   rayformer: the paper's ladder, baseline|patch|inter|intra|tv (tv: the\n"
            "                                full method; each step adds its switch to the ones before)\n"
            "              --checkpoint FILE write a checkpoint every --checkpoint-every K steps (default 100), at\n"
            "                                the end, and when interrupted (Ctrl-C, SIGTERM)\n"
            "              --resume FILE     continue a run from its checkpoint (same input and options)\n"
            "              --checkpoint-every K  steps between checkpoints (default 100)\n"
            "              recipe knobs (the defaults are the presets' recipe, docs/nerf-methods.md):\n"
            "              --spacing linear|disparity|log  how the coarse samples divide [near, far]\n"
            "              --distortion X    weight of the distortion loss on the coarse weights (0: off)\n"
            "              --prior-steps K   GAP-TV warm start: the first K steps also pull the frames toward\n"
            "                                GAP-TV's reconstruction, --prior-weight X falling linearly to 0\n"
            "              --density-bias X  added to the density before its activation\n"
            "              --zero-gates 0|1  rayformer: each block's output projections start at zero\n"
            "              --sh-degree D     spherical-harmonics degree of the view direction encoding (1-4)\n"
            "  any method:  --set KEY=VALUE    any setting by its key, e.g. --set inter_gate=false (repeatable;\n"
            "                                 after the options above; result.json's params list every key)\n"
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
            "      --metrics-every K  PSNR against truth in the trace every K iterations (default 1)\n"
            "      --ssim-every K     SSIM in the trace every K iterations (default 10; 0 = last only)\n"
            "  -j, --threads N        OpenMP threads (default: all cores)\n"
            "  -q, --quiet            no progress on stderr\n"
            "  -h, --help             this text\n"
            "\n"
            "Defaults are the PnP-SCI benchmark settings (accelerated GAP, lambda 1, 100 iterations, TV weight\n"
            "0.07, 5 TV passes). PSNR 'peak = frame max' uses each truth frame's maximum (the MATLAB reference's\n"
            "convention); 'peak = 1' uses the data's white level. Exit status: 0 ok, 1 failure, 2 usage; on\n"
            "SIGINT/SIGTERM/SIGHUP/SIGQUIT it stops, removes what it had begun to write, and dies of that signal:\n"
            "OUTDIR appears only once complete (written as OUTDIR.tmp-PID and renamed; one left by a process that\n"
            "no longer runs is removed at the next run into OUTDIR).\n",
            (double)SCI_IO_LIMIT_INPUT_BYTES / 1e9, (double)SCI_IO_LIMIT_OUTPUT_BYTES / 1e9,
            (size_t)SCI_IO_LIMIT_OUTPUT_FILES);
}

typedef struct recon_opts {
    const solver_ops *method; /* recon/solver.h */
    void *settings;           /* the method's, owned */
    int quiet;
} recon_opts;

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

/* The NeRF checkpoint callback: the blob goes to path.tmp, then replaces path (never a half-written checkpoint). */
typedef struct ckpt_file {
    const char *path;
    int written, iter;
} ckpt_file;

static int write_checkpoint(const void *blob, size_t bytes, int iter, void *user)
{
    ckpt_file *c = user;
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.tmp", c->path);
    FILE *f = fopen(tmp, "wb");
    if (!f)
        return -errno;
    int ok = fwrite(blob, 1, bytes, f) == bytes;
    ok &= fflush(f) == 0 && fsync(fileno(f)) == 0;
    ok &= fclose(f) == 0;
    if (!ok || rename(tmp, c->path) != 0) {
        int e = errno ? -errno : -EIO;
        unlink(tmp);
        return e;
    }
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

/* One option given on the command line, as a settings key and a JSON value (stolen). */
typedef struct opt_value {
    const char *key, *option;
    json_t *value;
} opt_value;

/* Apply the options in their fixed order to the method's settings. An option the method has no setting for is
 * ignored (common options map onto whichever method runs), except those in `strict` (NULL-terminated keys),
 * which are refused naming the methods that have them. 0, or 2 (usage) after a message. */
static int apply_options(const recon_opts *o, opt_value *v, int n, const char *const *strict)
{
    for (int i = 0; i < n; i++) {
        sci_error err = {0};
        int rc = solver_settings_set(o->method, o->settings, v[i].key, v[i].value, NULL, v[i].option, &err);
        if (rc == 1) {
            for (int k = 0; strict[k]; k++)
                if (strcmp(strict[k], v[i].key) == 0) {
                    const solver_ops *const *l = solver_list(NULL);
                    char who[256] = "";
                    size_t off = 0;
                    for (int m = 0; l[m] && off < sizeof who; m++)
                        if (solver_field_find(l[m], v[i].key, NULL))
                            off += (size_t)snprintf(who + off, sizeof who - off, "%s%s", off ? ", " : "", l[m]->name);
                    fprintf(stderr, "scicap recon: %s is for %s\n", v[i].option, who);
                    return 2;
                }
            continue;
        }
        if (rc < 0) {
            fprintf(stderr, "scicap recon: %s\n", err.msg);
            return 2;
        }
    }
    return 0;
}

/* --set KEY=VALUE: any setting of the method by its key (result.json's "params" names them all). VALUE is read as
 * JSON (numbers, true/false) and otherwise as a string, so "--set spacing=log" needs no quotes. Through the
 * method's table, as a params file would be: range-checked; an unknown key is refused with the method's keys and
 * what each does. Returns 0, or 2 (usage) after the message. */
static int apply_sets(const recon_opts *o, const char *const *kv, int n)
{
    json_t *obj = json_object();
    int rc = obj ? 0 : -ENOMEM;
    for (int i = 0; i < n && rc == 0; i++) {
        const char *eq = strchr(kv[i], '=');
        char key[128];
        snprintf(key, sizeof key, "%.*s", (int)(eq - kv[i]), kv[i]);
        if (!solver_field_find(o->method, key, NULL)) {
            fprintf(stderr, "scicap recon: --set %s: %s has no such setting; its settings are:\n", key,
                    o->method->name);
            for (int g = 0; g < 2; g++)
                for (int k = 0; k < o->method->fields[g].n; k++)
                    fprintf(stderr, "  %-20s %s\n", o->method->fields[g].f[k].key, o->method->fields[g].f[k].help);
            json_decref(obj);
            return 2;
        }
        json_t *v = json_loads(eq + 1, JSON_DECODE_ANY, NULL);
        if (!v)
            v = json_string(eq + 1);
        rc = v ? json_object_set_new(obj, key, v) : -ENOMEM;
    }
    sci_error err = {0};
    if (rc == 0 && solver_settings_from_json(o->method, o->settings, obj, NULL, NULL, &err) < 0) {
        fprintf(stderr, "scicap recon: --set: %s\n", err.msg);
        rc = 2;
    } else if (rc) {
        fprintf(stderr, "scicap recon: out of memory\n");
        rc = 2;
    }
    json_decref(obj);
    return rc;
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

int cli_recon_main(int argc, char **argv)
{
    /* `scicap recon --capture ID` asks the daemon to reconstruct one of its captures. */
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "--capture") == 0 || strncmp(argv[i], "--capture=", 10) == 0)
            return cli_client_recon(argc, argv);
    recon_opts o = {.method = solver_list(NULL)[0]};
    const char *preset = NULL;
    int nf_patch = 0, nf_pps = 0, nf_samples = 0, nf_pose = -1, nf_seed = -1, nf_ablation = -1, ckpt_every = 100;
    const char *ckpt_path = NULL, *resume_path = NULL;
    double nf_lr = NAN, nf_net_lr = NAN, nf_dist = NAN, nf_prior_w = NAN, nf_dbias = NAN;
    const char *nf_spacing = NULL, *nf_pose_name = NULL;
    int nf_prior_steps = -1, nf_zero_gates = -1, nf_sh = 0, plain = 0;
    double gamma = NAN;
    const char *out = NULL;
    int force = 0, preview_auto = 0, snapshot = 0, threads = 0, iters = -1, tv_iters = -1, metrics_every = -1, ssim_every = -1;
    double lambda = NAN, tv_weight = NAN;
    enum { OPT_PLAIN = 256, OPT_METRICS, OPT_SSIM, OPT_PATCH, OPT_PPS, OPT_SAMPLES, OPT_LR, OPT_POSE, OPT_SEED, OPT_PRESET,
           OPT_ABLATION, OPT_CKPT, OPT_CKPT_EVERY, OPT_RESUME, OPT_NET_LR, OPT_SPACING, OPT_DIST, OPT_PRIOR_STEPS,
           OPT_PRIOR_W, OPT_DBIAS, OPT_ZERO_GATES, OPT_SH, OPT_MASK, OPT_MASK_VAR, OPT_MEAS_VAR, OPT_TRUTH_VAR,
           OPT_SCALE, OPT_CFA, OPT_DEMOSAIC, OPT_ALLOW_LARGE, OPT_SET, OPT_FRAMES, OPT_MASK_SCALE, OPT_PREVIEW };
    const char *set_kv[32]; /* --set KEY=VALUE, applied after every named option */
    int n_set = 0;
    const char *cfa_opt = NULL;
    sci_demosaic_method demosaic = SCI_DEMOSAIC_MHC;
    sci_mat_options mo = {0};
    sci_io_limits limits;
    sci_io_limits_default(&limits);
    mo.limits = &limits;
    static const struct option longopts[] = {
        {"method", required_argument, 0, 'm'},   {"output", required_argument, 0, 'o'},
        {"force", no_argument, 0, 'f'},          {"snapshot", required_argument, 0, 's'},
        {"iters", required_argument, 0, 'i'},    {"lambda", required_argument, 0, 'l'},
        {"tv-weight", required_argument, 0, 'w'}, {"tv-iters", required_argument, 0, 't'},
        {"plain", no_argument, 0, OPT_PLAIN},    {"gamma", required_argument, 0, 'g'},
        {"metrics-every", required_argument, 0, OPT_METRICS}, {"ssim-every", required_argument, 0, OPT_SSIM},
        {"threads", required_argument, 0, 'j'},  {"quiet", no_argument, 0, 'q'},
        {"patch", required_argument, 0, OPT_PATCH}, {"patches-per-step", required_argument, 0, OPT_PPS},
        {"samples", required_argument, 0, OPT_SAMPLES}, {"lr", required_argument, 0, OPT_LR},
        {"pose-mode", required_argument, 0, OPT_POSE}, {"seed", required_argument, 0, OPT_SEED},
        {"preset", required_argument, 0, OPT_PRESET}, {"ablation", required_argument, 0, OPT_ABLATION},
        {"checkpoint", required_argument, 0, OPT_CKPT}, {"checkpoint-every", required_argument, 0, OPT_CKPT_EVERY},
        {"resume", required_argument, 0, OPT_RESUME}, {"net-lr-scale", required_argument, 0, OPT_NET_LR},
        {"spacing", required_argument, 0, OPT_SPACING}, {"distortion", required_argument, 0, OPT_DIST},
        {"prior-steps", required_argument, 0, OPT_PRIOR_STEPS}, {"prior-weight", required_argument, 0, OPT_PRIOR_W},
        {"density-bias", required_argument, 0, OPT_DBIAS}, {"zero-gates", required_argument, 0, OPT_ZERO_GATES},
        {"sh-degree", required_argument, 0, OPT_SH},
        {"mask", required_argument, 0, OPT_MASK}, {"mask-var", required_argument, 0, OPT_MASK_VAR},
        {"meas-var", required_argument, 0, OPT_MEAS_VAR}, {"truth-var", required_argument, 0, OPT_TRUTH_VAR},
        {"scale", required_argument, 0, OPT_SCALE}, {"frames", required_argument, 0, OPT_FRAMES},
        {"mask-scale", required_argument, 0, OPT_MASK_SCALE}, {"preview-range", required_argument, 0, OPT_PREVIEW},
        {"cfa", required_argument, 0, OPT_CFA}, {"demosaic", required_argument, 0, OPT_DEMOSAIC},
        {"allow-large", no_argument, 0, OPT_ALLOW_LARGE}, {"set", required_argument, 0, OPT_SET},
        {"help", no_argument, 0, 'h'},           {0, 0, 0, 0},
    };
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, "m:o:fs:i:l:w:t:g:j:qh", longopts, NULL)) != -1) {
        int bad = 0;
        switch (c) {
        case 'm': {
            sci_error merr = {0};
            if (!(o.method = solver_find_err(optarg, &merr))) {
                fprintf(stderr, "scicap recon: %s\n", merr.msg);
                return 2;
            }
            break;
        }
        case 'o': out = optarg; break;
        case 'f': force = 1; break;
        case OPT_ALLOW_LARGE: sci_io_limits_none(&limits); break;
        case OPT_SET:
            if (!strchr(optarg, '=') || optarg[0] == '=') {
                fprintf(stderr, "scicap recon: --set wants KEY=VALUE, got '%s'\n", optarg);
                bad = -1;
            } else if (n_set == (int)(sizeof set_kv / sizeof set_kv[0])) {
                fprintf(stderr, "scicap recon: at most %d --set options\n", n_set);
                bad = -1;
            } else
                set_kv[n_set++] = optarg;
            break;
        case 's': bad = parse_int(optarg, "--snapshot", 1, 1 << 30, &snapshot); break;
        case 'i': bad = parse_int(optarg, "--iters", 1, 10000000, &iters); break;
        case 'l': bad = parse_double(optarg, "--lambda", &lambda); break;
        case 'w': bad = parse_double(optarg, "--tv-weight", &tv_weight); break;
        case 't': bad = parse_int(optarg, "--tv-iters", 1, 100000, &tv_iters); break;
        case OPT_PLAIN: plain = 1; break;
        case 'g': bad = parse_double(optarg, "--gamma", &gamma); break;
        case OPT_METRICS: bad = parse_int(optarg, "--metrics-every", 0, 1 << 30, &metrics_every); break;
        case OPT_SSIM: bad = parse_int(optarg, "--ssim-every", 0, 1 << 30, &ssim_every); break;
        case 'j': bad = parse_int(optarg, "--threads", 1, 1024, &threads); break;
        case OPT_PRESET: preset = optarg; break;
        case OPT_PATCH: bad = parse_int(optarg, "--patch", 2, 16, &nf_patch); break;
        case OPT_PPS: bad = parse_int(optarg, "--patches-per-step", 1, 4096, &nf_pps); break;
        case OPT_SAMPLES: bad = parse_int(optarg, "--samples", 2, 1024, &nf_samples); break;
        case OPT_LR: bad = parse_double(optarg, "--lr", &nf_lr); break;
        case OPT_POSE:
            if (strcmp(optarg, "known") == 0 || strcmp(optarg, "linear") == 0 || strcmp(optarg, "per-frame") == 0)
                nf_pose_name = optarg, nf_pose = 1;
            else {
                fprintf(stderr, "scicap recon: --pose-mode wants known, linear or per-frame, got '%s'\n", optarg);
                bad = -1;
            }
            break;
        case OPT_ABLATION: {
            /* the paper's steps; "+patch" … "+tv" (the ladder's labels) name the same */
            static const char *const steps[] = {"baseline", "patch", "inter", "intra", "tv"};
            const char *a = optarg[0] == '+' ? optarg + 1 : optarg;
            for (int k = 0; k < 5; k++)
                if (strcmp(a, steps[k]) == 0 && (k > 0 || a == optarg))
                    nf_ablation = k;
            if (nf_ablation < 0) {
                fprintf(stderr, "scicap recon: --ablation wants baseline, patch, inter, intra or tv, got '%s'\n",
                        optarg);
                bad = -1;
            }
            break;
        }
        case OPT_CKPT: ckpt_path = optarg; break;
        case OPT_CKPT_EVERY: bad = parse_int(optarg, "--checkpoint-every", 1, 1 << 30, &ckpt_every); break;
        case OPT_RESUME: resume_path = optarg; break;
        case OPT_NET_LR: bad = parse_double(optarg, "--net-lr-scale", &nf_net_lr); break;
        case OPT_SPACING:
            if (strcmp(optarg, "linear") == 0 || strcmp(optarg, "disparity") == 0 || strcmp(optarg, "log") == 0)
                nf_spacing = optarg;
            else {
                fprintf(stderr, "scicap recon: --spacing wants linear, disparity or log, got '%s'\n", optarg);
                bad = -1;
            }
            break;
        case OPT_DIST: bad = parse_double(optarg, "--distortion", &nf_dist); break;
        case OPT_PRIOR_STEPS: bad = parse_int(optarg, "--prior-steps", 0, 10000000, &nf_prior_steps); break;
        case OPT_PRIOR_W: bad = parse_double(optarg, "--prior-weight", &nf_prior_w); break;
        case OPT_DBIAS: bad = parse_double(optarg, "--density-bias", &nf_dbias); break;
        case OPT_ZERO_GATES: bad = parse_int(optarg, "--zero-gates", 0, 1, &nf_zero_gates); break;
        case OPT_SH: bad = parse_int(optarg, "--sh-degree", 1, 4, &nf_sh); break;
        case OPT_MASK: mo.mask_path = optarg; break;
        case OPT_MASK_VAR: mo.mask_var = optarg; break;
        case OPT_MEAS_VAR: mo.meas_var = optarg; break;
        case OPT_TRUTH_VAR: mo.truth_var = optarg; break;
        case OPT_SCALE:
            if (strcmp(optarg, "auto") == 0)
                mo.white = SCI_MAT_WHITE_AUTO;
            else if ((bad = parse_double(optarg, "--scale", &mo.white)) == 0 && !(mo.white > 0)) {
                fprintf(stderr, "scicap recon: --scale wants auto or a number > 0 (the value of white), got '%s'\n",
                        optarg);
                bad = -1;
            }
            break;
        case OPT_FRAMES: bad = parse_int(optarg, "--frames", 1, 1 << 16, &mo.frames); break;
        case OPT_MASK_SCALE:
            if (strcmp(optarg, "auto") == 0)
                mo.mask_white = 0;
            else if ((bad = parse_double(optarg, "--mask-scale", &mo.mask_white)) == 0 && !(mo.mask_white > 0)) {
                fprintf(stderr, "scicap recon: --mask-scale wants auto or a number > 0 (a fully open mask pixel), "
                                "got '%s'\n", optarg);
                bad = -1;
            }
            break;
        case OPT_PREVIEW:
            if (strcmp(optarg, "auto") == 0 || strcmp(optarg, "fixed") == 0)
                preview_auto = optarg[0] == 'a';
            else {
                fprintf(stderr, "scicap recon: --preview-range wants fixed or auto, got '%s'\n", optarg);
                bad = -1;
            }
            break;
        case OPT_CFA: {
            sci_cfa tmp;
            cfa_opt = optarg;
            if (sci_cfa_parse(optarg, &tmp) < 0) {
                fprintf(stderr, "scicap recon: --cfa wants RGGB, BGGR, GRBG, GBRG or none, got '%s'\n", optarg);
                bad = -1;
            }
            break;
        }
        case OPT_DEMOSAIC:
            if (sci_demosaic_parse(optarg, &demosaic) < 0) {
                fprintf(stderr, "scicap recon: --demosaic wants mhc or bilinear, got '%s'\n", optarg);
                bad = -1;
            }
            break;
        case OPT_SEED: {
            bad = parse_int(optarg, "--seed", 0, 1 << 30, &nf_seed);
            break;
        }
        case 'q': o.quiet = 1; break;
        case 'h':
            usage(stdout);
            printf("\nThrough the daemon (scicap recon --capture ID ...):\n\n");
            cli_client_usage(stdout, "reconstruct");
            return 0;
        default: usage(stderr); return 2;
        }
        if (bad)
            return 2;
    }
    /* Several inputs (or a folder of them, or a quoted glob): the batch of cli/batch.c, one scicap recon per input
     * into OUTDIR/NAME, resumable. getopt has moved the options before the inputs. */
    if (out && (optind < argc - 1 || (optind == argc - 1 && cli_batch_is_many(argv[optind]))))
        return cli_batch_recon(optind - 1, argv + 1, argc - optind, argv + optind);
    if (optind != argc - 1 || !out) {
        fprintf(stderr, "scicap recon: %s\n", !out ? "-o OUTDIR is required" : "exactly one INPUT is required");
        usage(stderr);
        return 2;
    }
    const char *input = argv[optind];
    /* The method's settings: its defaults, the preset, then the options given explicitly, in this order (the
     * ablation step sets tv_weight, which --tv-weight then overrides). */
    if (!(o.settings = solver_settings_new(o.method))) {
        fprintf(stderr, "scicap recon: out of memory\n");
        return 1;
    }
    if (preset) {
        solver_preset pr;
        int deprecated;
        sci_error perr = {0};
        if (solver_preset_parse(preset, &pr, &deprecated, &perr) < 0) {
            fprintf(stderr, "scicap recon: %s\n", perr.msg);
            solver_settings_free(o.settings);
            return 2;
        }
        if (deprecated)
            fprintf(stderr, "scicap recon: preset '%s' is deprecated: it is %s\n", preset, solver_preset_name(pr));
        solver_settings_preset(o.method, o.settings, pr);
    }
    opt_value ov[32];
    int nov = 0;
#define OPT_SET(k, opt, cond, val)                                                                                     \
    do {                                                                                                               \
        if (cond)                                                                                                      \
            ov[nov++] = (opt_value){k, opt, val};                                                                      \
    } while (0)
    OPT_SET("accelerate", "--plain", plain, json_false());
    OPT_SET("gamma", "--gamma", !isnan(gamma), json_real(gamma));
    OPT_SET("ablation", "--ablation", nf_ablation >= 0, json_integer(nf_ablation));
    OPT_SET("patch", "--patch", nf_patch, json_integer(nf_patch));
    OPT_SET("patches_per_step", "--patches-per-step", nf_pps, json_integer(nf_pps));
    OPT_SET("samples", "--samples", nf_samples, json_integer(nf_samples));
    OPT_SET("lr", "--lr", !isnan(nf_lr), json_real(nf_lr));
    OPT_SET("net_lr_scale", "--net-lr-scale", !isnan(nf_net_lr), json_real(nf_net_lr));
    OPT_SET("spacing", "--spacing", nf_spacing, json_string(nf_spacing));
    OPT_SET("distortion_weight", "--distortion", !isnan(nf_dist), json_real(nf_dist));
    OPT_SET("prior_steps", "--prior-steps", nf_prior_steps >= 0, json_integer(nf_prior_steps));
    OPT_SET("prior_weight", "--prior-weight", !isnan(nf_prior_w), json_real(nf_prior_w));
    OPT_SET("density_bias", "--density-bias", !isnan(nf_dbias), json_real(nf_dbias));
    OPT_SET("zero_gates", "--zero-gates", nf_zero_gates >= 0, json_integer(nf_zero_gates));
    OPT_SET("sh_degree", "--sh-degree", nf_sh, json_integer(nf_sh));
    OPT_SET("pose_mode", "--pose-mode", nf_pose >= 0, json_string(nf_pose_name));
    OPT_SET("seed", "--seed", nf_seed >= 0, json_integer(nf_seed));
    OPT_SET("iters", "--iters", iters > 0, json_integer(iters));
    OPT_SET("lambda", "--lambda", !isnan(lambda), json_real(lambda));
    OPT_SET("tv_weight", "--tv-weight", !isnan(tv_weight), json_real(tv_weight));
    OPT_SET("tv_iters", "--tv-iters", tv_iters > 0, json_integer(tv_iters));
    OPT_SET("metrics_every", "--metrics-every", metrics_every >= 0, json_integer(metrics_every));
    OPT_SET("ssim_every", "--ssim-every", ssim_every >= 0, json_integer(ssim_every));
#undef OPT_SET
    static const char *const strict[] = {"ablation", NULL};
    int arc = apply_options(&o, ov, nov, strict);
    for (int i = 0; i < nov; i++)
        json_decref(ov[i].value);
    if (arc == 0 && n_set)
        arc = apply_sets(&o, set_kv, n_set);
    if (threads)
        omp_set_num_threads(threads);
    sci_error err = {0};
    if (arc == 0 && solver_settings_check(o.method, o.settings, &err) < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        arc = 2;
    }
    char names[256];
    if (arc == 0 && (ckpt_path || resume_path) && !(o.method->caps & SOLVER_CHECKPOINTS)) {
        fprintf(stderr, "scicap recon: --checkpoint and --resume are for %s\n",
                methods_with(names, sizeof names, SOLVER_CHECKPOINTS, 1));
        arc = 2;
    }
    if (arc) {
        solver_settings_free(o.settings);
        return arc;
    }
    if (access(out, F_OK) == 0 && !force) {
        fprintf(stderr, "scicap recon: %s already exists (use --force to replace it)\n", out);
        return 1;
    }

    /* Limits before any work (io/limits.h): what the input declares, and what writing it would make. */
    long long dw, dh, dn, dk;
    int rrc = sci_source_probe(input, &mo, &dw, &dh, &dn, &dk, &err);
    if (rrc == 0) {
        double bytes, files;
        const long long nsel = snapshot ? 1 : dk;
        sci_recon_store_estimate(dw, dh, dn, nsel, &bytes, &files);
        char what[4400];
        snprintf(what, sizeof what, "%s (from %s: %lld snapshot(s) of %lldx%lld pixels, %lld frames each)", out,
                 input, nsel, dw, dh, dn);
        rrc = sci_io_limits_check_output(&limits, what, bytes, files + (nsel > 1), &err);
    }
    if (rrc < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        return rrc == -EINVAL ? 2 : 1;
    }
    /* The output's folder must be there and writable before hours of solving, not after. */
    {
        char parent[4096];
        snprintf(parent, sizeof parent, "%s", out);
        char *slash = strrchr(parent, '/');
        while (slash && slash > parent && slash[1] == 0) /* "out/" */
            *slash = 0, slash = strrchr(parent, '/');
        if (!slash)
            snprintf(parent, sizeof parent, ".");
        else
            slash[slash == parent] = 0; /* "/out" keeps "/" */
        if (access(parent, W_OK | X_OK) != 0) {
            fprintf(stderr, "scicap recon: cannot write %s: %s: %s\n", out, parent, strerror(errno));
            return 1;
        }
    }
    sci_problem **probs = NULL;
    int k = 0;
    sci_mat_info minfo = {0};
    rrc = sci_source_read_opts(input, &mo, &probs, &k, &minfo, &err);
    if (rrc < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        return rrc == -EINVAL ? 2 : 1;
    }
    if (minfo.how[0])
        fprintf(stderr, "scicap recon: scale: %s (override with --scale / --mask-scale)\n", minfo.how);
    if (minfo.warning[0])
        fprintf(stderr, "scicap recon: WARNING: %s\n", minfo.warning);
    /* Colour: a folder from a colour scene names its CFA and keeps the RGB truth; --cfa overrides (none: grey). */
    int cfa_i = SCI_CFA_NONE, kc = 0;
    sci_cube **truth_rgb = NULL;
    if (!sci_source_is_mat(input) && sci_problem_dir_read_color(input, &cfa_i, &truth_rgb, &kc, &err) < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        sci_problem_array_free(probs, k);
        return 1;
    }
    sci_cfa cfa = (sci_cfa)cfa_i;
    if (cfa_opt)
        sci_cfa_parse(cfa_opt, &cfa);
    if (cfa != SCI_CFA_NONE && (o.method->caps & SOLVER_NEEDS_CAMERA)) {
        char plain_methods[256];
        fprintf(stderr, "scicap recon: %s is a Bayer mosaic; colour reconstruction runs %s per CFA plane (--cfa none "
                        "reconstructs it as grey)\n", input,
                methods_with(plain_methods, sizeof plain_methods, SOLVER_NEEDS_CAMERA, 0));
        for (int j = 0; truth_rgb && j < kc; j++)
            sci_cube_free(truth_rgb[j]);
        free(truth_rgb);
        sci_problem_array_free(probs, k);
        return 2;
    }
    if (snapshot > k) {
        fprintf(stderr, "scicap recon: %s has %d snapshot(s); --snapshot %d is out of range\n", input, k, snapshot);
        sci_problem_array_free(probs, k);
        return 2;
    }
    int first = snapshot ? snapshot - 1 : 0, last = snapshot ? snapshot - 1 : k - 1, status = 0;
    if ((ckpt_path || resume_path) && first != last) {
        fprintf(stderr, "scicap recon: %s has %d snapshots; a checkpoint belongs to one (add --snapshot J)\n", input,
                k);
        sci_problem_array_free(probs, k);
        return 2;
    }
    ckpt_file ck = {.path = ckpt_path};
    solver_io io = {.progress = cli_progress_update};
    void *resume_blob = NULL;
    size_t resume_bytes = 0;
    if (resume_path) {
        if (sci_file_read(resume_path, (size_t)16 << 30, &resume_blob, &resume_bytes, &err) < 0) {
            fprintf(stderr, "scicap recon: --resume: %s\n", err.msg);
            sci_problem_array_free(probs, k);
            return 1;
        }
        io.resume = resume_blob;
        io.resume_bytes = resume_bytes;
    }
    if (ckpt_path) {
        io.checkpoint_fn = write_checkpoint;
        io.checkpoint_user = &ck;
        io.checkpoint_every = ckpt_every;
    }
    struct sigaction sa = {.sa_handler = on_stop_signal, .sa_flags = SA_RESETHAND}, old_sig[STOP_SIGNALS];
    sigemptyset(&sa.sa_mask);
    for (int i = 0; i < STOP_SIGNALS; i++)
        sigaction(stop_signals[i], &sa, &old_sig[i]);
    clean_stale_stages(out);
    json_t *params = params_json(&o, resume_blob != NULL), *input_info = input_json(&minfo);
    /* Several snapshots: all of them go into OUTDIR.tmp-PID, renamed to OUTDIR once the last is written (one alone
     * is staged by the store itself). Nothing is published on failure or on a signal. */
    char stage[4096] = "";
    if (first != last) {
        if (sci_staging_name(stage, sizeof stage, out) < 0 || mkdir(stage, 0755) != 0) {
            fprintf(stderr, "scicap recon: %s: %s\n", stage[0] ? stage : out, strerror(errno ? errno : ENAMETOOLONG));
            status = 1;
        }
    }
    for (int j = first; j <= last && status == 0; j++) {
        const sci_problem *p = probs[j];
        printf("%s: %s, %dx%d, %d frames per snapshot%s\n", p->name, o.method->name,
               p->mask->w, p->mask->h, p->mask->n, p->truth ? ", truth known" : "");
        fflush(stdout);
        cli_progress prog;
        const int total = solver_settings_iters(o.method, o.settings);
        cli_progress_init(&prog, o.quiet ? -1 : 2, total);
        prog.stop = &stop_requested;
        char dir[4096], shown[4096];
        snprintf(shown, sizeof shown, first == last ? "%s" : "%s/snap_%03d", out, j + 1);
        if (first == last)
            snprintf(dir, sizeof dir, "%s", out);
        else
            snprintf(dir, sizeof dir, "%s/snap_%03d", stage, j + 1);
        if (cfa != SCI_CFA_NONE) {
            const cli_color_job job = {.cfa = cfa, .demosaic = demosaic, .method = o.method, .settings = o.settings,
                                       .params = params, .quiet = o.quiet, .preview_auto = preview_auto,
                                       .extra = input_info, .stop = &stop_requested};
            int crc = cli_recon_color(&job, p, truth_rgb && j < kc ? truth_rgb[j] : NULL, dir, force, &err);
            if (crc == SCI_ECANCELED || stop_requested) {
                fprintf(stderr, "scicap recon: interrupted; %s not written\n", out);
                status = 1;
            } else if (crc < 0) {
                fprintf(stderr, "scicap recon: %s\n", err.msg);
                status = 1;
            } else {
                printf("  wrote %s/ (RGB: rgb_NNN.exr, preview_rgb_NNN.png)\n", shown);
            }
            continue;
        }
        sci_result r = {0};
        int64_t t0 = sci_clock_mono_ns();
        io.user = &prog;
        int rc = solver_run(o.method, p, o.settings, &io, &r);
        double secs = sci_clock_s(t0, sci_clock_mono_ns());
        cli_progress_done(&prog);
        if (rc == SCI_ECANCELED || (rc == 0 && stop_requested)) {
            fprintf(stderr, "scicap recon: interrupted after %d iterations; %s not written", r.iters_done, out);
            if (ck.written)
                fprintf(stderr, "; checkpoint of step %d in %s (continue with --resume %s)", ck.iter, ck.path,
                        ck.path);
            fprintf(stderr, "\n");
            sci_result_free_contents(&r);
            status = 1;
            break;
        }
        if (rc < 0) {
            fprintf(stderr, "scicap recon: %s\n", r.error.msg);
            sci_result_free_contents(&r);
            status = 1;
            break;
        }
        double solver_s = r.trace.len ? r.trace.e[r.trace.len - 1].wall_s : secs;
        printf("  %d iterations in %.3f s solver time (%.3f s with trace metrics), final residual %.3g\n",
               r.iters_done, solver_s, secs, r.trace.len ? r.trace.e[r.trace.len - 1].residual : NAN);
        print_levels(p, &r);
        if (p->truth)
            print_metrics(p, &r);
        const sci_recon_store_opts so = {.extra = input_info, .stop = &stop_requested, .preview_auto = preview_auto,
                                         .flags = first == last && force ? SCI_STAGING_OVERWRITE : 0};
        int wrc = sci_recon_store_write_with(dir, p, &r, params, &so, &err);
        if (wrc == SCI_ECANCELED) {
            fprintf(stderr, "scicap recon: interrupted while writing; %s not written\n", out);
            status = 1;
        } else if (wrc < 0) {
            fprintf(stderr, "scicap recon: %s\n", err.msg);
            status = 1;
        } else {
            printf("  wrote %s/\n", shown);
        }
        sci_result_free_contents(&r);
    }
    if (stage[0] && status == 0) {
        if (sci_staging_publish(stage, out, force ? SCI_STAGING_OVERWRITE : 0, &stop_requested, &err) < 0) {
            if (err.code != SCI_ECANCELED)
                fprintf(stderr, "scicap recon: %s\n", err.msg);
            status = 1;
        } else {
            printf("wrote %s/\n", out);
        }
    } else if (stage[0]) {
        sci_staging_remove(stage);
    }
    for (int i = 0; i < STOP_SIGNALS; i++)
        sigaction(stop_signals[i], &old_sig[i], NULL);
    const int sig = stop_requested;
    if (ckpt_path && ck.written && status == 0)
        printf("  checkpoint of step %d in %s\n", ck.iter, ckpt_path);
    json_decref(params);
    json_decref(input_info);
    for (int j = 0; truth_rgb && j < kc; j++)
        sci_cube_free(truth_rgb[j]);
    free(truth_rgb);
    free(resume_blob);
    solver_settings_free(o.settings);
    sci_problem_array_free(probs, k);
    if (sig) {
        fflush(NULL);
        signal(sig, SIG_DFL);
        raise(sig);
    }
    return status;
}
