/* scicap recon — reconstruct SCI snapshots from a .mat benchmark file or a problem folder. */
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
#include "recon/admmtv.h"
#include "recon/gaptv.h"
#include "recon/metrics.h"
#include "recon/nerf/rayformer_solve.h"
#include "recon/nerf/scinerf_solve.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: scicap recon [OPTIONS] INPUT -o OUTDIR\n"
            "       scicap recon --capture ID [--method M] [--wait]   (ask scicapd; see scicap status)\n"
            "\n"
            "Reconstruct the N frames of each SCI snapshot in INPUT: a .mat file (MATLAB v5 or v7.3; by default the\n"
            "benchmark's variables mask, meas, orig with values divided by 255) or a problem folder written by\n"
            "'scicap sim' or by scicapd.\n"
            "Writes OUTDIR (OUTDIR/snap_NNN/ when INPUT has several snapshots) with float EXR frames, PNG and GIF\n"
            "previews, trace.csv (time against accuracy per iteration) and result.json. When the truth is known\n"
            "it prints per-frame and mean PSNR in both peak conventions, and SSIM.\n"
            "\n"
            "  -m, --method NAME      gap-tv (default), admm-tv, rayformer or scinerf (the last two need a static\n"
            "                         scene with a camera, e.g. from a static3d scene; see docs/nerf-methods.md)\n"
            "  -o, --output DIR       output folder (required); replaced only with --force\n"
            "  -f, --force            replace an existing output folder\n"
            "      --allow-large      lift the size limits checked before any work: %.0f GB of input in memory,\n"
            "                         %.0f GB or %zu files of output (a small file can declare huge sizes)\n"
            "  -s, --snapshot J       reconstruct only snapshot J (1-based); default all\n"
            "  -i, --iters N          outer iterations (default 100)\n"
            "  -l, --lambda X         step size lambda (default 1)\n"
            "  -w, --tv-weight X      TV weight on the data's [0, peak] scale (default 0.07)\n"
            "  -t, --tv-iters N       TV denoiser passes per iteration (default 5)\n"
            "      --plain            gap-tv: plain GAP instead of accelerated\n"
            "  -g, --gamma X          admm-tv: gamma added to the mask energy (default 1e-3)\n"
            "  rayformer, scinerf:  --preset fast|balanced|best (default balanced; the options below override it)\n"
            "              --samples L (per ray)  --lr X  --pose-mode known|linear|per-frame  --seed S\n"
            "              (--iters applies too; rayformer also --patch P (2,4,8,16) --patches-per-step B --tv-weight)\n"
            "              --net-lr-scale X  rayformer: the transformer learns at lr × X, the hash table at lr\n"
            "              --ablation STEP   rayformer: the paper's ladder, baseline|patch|inter|intra|tv (tv: the\n"
            "                                full method; each step adds its switch to the ones before)\n"
            "              --checkpoint FILE write a checkpoint every --checkpoint-every K steps (default 100), at\n"
            "                                the end, and when interrupted (Ctrl-C, SIGTERM)\n"
            "              --resume FILE     continue a run from its checkpoint (same input and options)\n"
            "              --checkpoint-every K  steps between checkpoints (default 100)\n"
            "              recipe knobs (all off by default, results unchanged):\n"
            "              --spacing linear|disparity|log  how the coarse samples divide [near, far]\n"
            "              --distortion X    weight of the distortion loss on the coarse weights (0: off)\n"
            "              --prior-steps K   GAP-TV warm start: the first K steps also pull the frames toward\n"
            "                                GAP-TV's reconstruction, --prior-weight X falling linearly to 0\n"
            "              --density-bias X  added to the density before its activation\n"
            "              --zero-gates 0|1  rayformer: each block's output projections start at zero\n"
            "              --sh-degree D     spherical-harmonics degree of the view direction encoding (1-4)\n"
            "  .mat input:  --mask FILE        the masks are in FILE (its only variable, or --mask-var)\n"
            "              --mask-var NAME    the masks' variable (default mask): H×W×N shared, H×W×N×k per snapshot\n"
            "              --meas-var NAME    the measurements' variable (default meas), H×W×k\n"
            "              --truth-var NAME   the truth's variable (default orig, optional), H×W×(k·N)\n"
            "              --scale auto|N     the value of white in the file (default 255); meas and truth are\n"
            "                                 divided by it; auto reads the data's range and says what it chose\n"
            "  colour:      --cfa PATTERN      RGGB, BGGR, GRBG or GBRG: the Bayer pattern of a raw mosaic input (a\n"
            "                                 colour folder from 'scicap sim' names its own); none: treat it as grey\n"
            "              --demosaic M       mhc (default, Malvar-He-Cutler) or bilinear, after the 4 CFA planes\n"
            "                                 are solved; writes rgb_NNN.exr, colour preview_rgb_NNN.png, RGB PSNR\n"
            "      --metrics-every K  PSNR against truth in the trace every K iterations (default 1)\n"
            "      --ssim-every K     SSIM in the trace every K iterations (default 10; 0 = last only)\n"
            "  -j, --threads N        OpenMP threads (default: all cores)\n"
            "  -q, --quiet            no progress on stderr\n"
            "  -h, --help             this text\n"
            "\n"
            "Defaults are the PnP-SCI benchmark settings (accelerated GAP, lambda 1, 100 iterations, TV weight\n"
            "0.07, 5 TV passes). PSNR 'peak = frame max' uses each truth frame's maximum (the MATLAB reference's\n"
            "convention); 'peak = 1' uses the data's white level. Exit status: 0 ok, 1 failure, 2 usage; on\n"
            "SIGINT/SIGTERM it stops, removes what it had begun to write, and dies of that signal: OUTDIR appears\n"
            "only once complete (written as OUTDIR.tmp-PID and renamed).\n",
            (double)SCI_IO_LIMIT_INPUT_BYTES / 1e9, (double)SCI_IO_LIMIT_OUTPUT_BYTES / 1e9,
            (size_t)SCI_IO_LIMIT_OUTPUT_FILES);
}

typedef struct recon_opts {
    int method; /* 0 gap-tv, 1 admm-tv, 2 rayformer, 3 scinerf */
    sci_gaptv_params gap;
    sci_admmtv_params admm;
    sci_rayformer_params rf;
    sci_scinerf_params sn;
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

static json_t *params_json(const recon_opts *o)
{
    if (o->method == 0)
        return json_pack("{s:s, s:i, s:f, s:b, s:f, s:i}", "method", "gap-tv", "iters", o->gap.iters, "lambda",
                         o->gap.lambda, "accelerate", o->gap.accelerate, "tv_weight", o->gap.tv_weight, "tv_iters",
                         o->gap.tv_iters);
    if (o->method == 3)
        return json_pack("{s:s, s:i, s:i, s:i, s:i, s:f, s:i, s:I, s:b}", "method", "scinerf", "iters", o->sn.iters,
                         "rays_per_step", o->sn.rays_per_step, "samples", o->sn.samples, "fine_samples",
                         o->sn.fine_samples, "lr", o->sn.lr, "pose_mode", (int)o->sn.pose_mode, "seed",
                         (json_int_t)o->sn.seed, "resumed", o->sn.resume != NULL);
    if (o->method == 2)
        return json_pack("{s:s, s:i, s:i, s:i, s:i, s:i, s:f, s:f, s:f, s:b, s:b, s:b, s:i, s:I, s:b}", "method",
                         "rayformer", "iters", o->rf.iters, "patch", o->rf.patch, "patches_per_step",
                         o->rf.patches_per_step, "samples", o->rf.samples, "log2_table", o->rf.log2_table, "lr",
                         o->rf.lr, "net_lr_scale", o->rf.net_lr_scale > 0 ? o->rf.net_lr_scale : 1, "tv_weight", o->rf.tv_weight, "patch_sampling", o->rf.patch_sampling, "inter_ray",
                         o->rf.inter_ray, "intra_ray", o->rf.intra_ray, "pose_mode", (int)o->rf.pose_mode, "seed",
                         (json_int_t)o->rf.seed, "resumed", o->rf.resume != NULL);
    return json_pack("{s:s, s:i, s:f, s:f, s:f, s:i}", "method", "admm-tv", "iters", o->admm.iters, "lambda",
                     o->admm.lambda, "gamma", o->admm.gamma, "tv_weight", o->admm.tv_weight, "tv_iters",
                     o->admm.tv_iters);
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

int cli_recon_main(int argc, char **argv)
{
    /* `scicap recon --capture ID` asks the daemon to reconstruct one of its captures. */
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "--capture") == 0 || strncmp(argv[i], "--capture=", 10) == 0)
            return cli_client_recon(argc, argv);
    recon_opts o = {0};
    sci_gaptv_params_default(&o.gap);
    sci_admmtv_params_default(&o.admm);
    sci_rayformer_params_default(&o.rf);
    sci_scinerf_params_default(&o.sn);
    const char *preset = NULL;
    int nf_patch = 0, nf_pps = 0, nf_samples = 0, nf_pose = -1, nf_seed = -1, nf_ablation = -1, ckpt_every = 100;
    const char *ckpt_path = NULL, *resume_path = NULL;
    double nf_lr = NAN, nf_net_lr = NAN, nf_dist = NAN, nf_prior_w = NAN, nf_dbias = NAN;
    int nf_spacing = -1, nf_prior_steps = -1, nf_zero_gates = -1, nf_sh = 0;
    const char *out = NULL;
    int force = 0, snapshot = 0, threads = 0, iters = -1, tv_iters = -1, metrics_every = -1, ssim_every = -1;
    double lambda = NAN, tv_weight = NAN;
    enum { OPT_PLAIN = 256, OPT_METRICS, OPT_SSIM, OPT_PATCH, OPT_PPS, OPT_SAMPLES, OPT_LR, OPT_POSE, OPT_SEED, OPT_PRESET,
           OPT_ABLATION, OPT_CKPT, OPT_CKPT_EVERY, OPT_RESUME, OPT_NET_LR, OPT_SPACING, OPT_DIST, OPT_PRIOR_STEPS,
           OPT_PRIOR_W, OPT_DBIAS, OPT_ZERO_GATES, OPT_SH, OPT_MASK, OPT_MASK_VAR, OPT_MEAS_VAR, OPT_TRUTH_VAR,
           OPT_SCALE, OPT_CFA, OPT_DEMOSAIC, OPT_ALLOW_LARGE };
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
        {"scale", required_argument, 0, OPT_SCALE},
        {"cfa", required_argument, 0, OPT_CFA}, {"demosaic", required_argument, 0, OPT_DEMOSAIC},
        {"allow-large", no_argument, 0, OPT_ALLOW_LARGE},
        {"help", no_argument, 0, 'h'},           {0, 0, 0, 0},
    };
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, "m:o:fs:i:l:w:t:g:j:qh", longopts, NULL)) != -1) {
        int bad = 0;
        switch (c) {
        case 'm':
            if (strcmp(optarg, "gap-tv") == 0)
                o.method = 0;
            else if (strcmp(optarg, "admm-tv") == 0)
                o.method = 1;
            else if (strcmp(optarg, "rayformer") == 0)
                o.method = 2;
            else if (strcmp(optarg, "scinerf") == 0)
                o.method = 3;
            else {
                fprintf(stderr, "scicap recon: unknown method '%s' (gap-tv, admm-tv, rayformer, scinerf)\n", optarg);
                return 2;
            }
            break;
        case 'o': out = optarg; break;
        case 'f': force = 1; break;
        case OPT_ALLOW_LARGE: sci_io_limits_none(&limits); break;
        case 's': bad = parse_int(optarg, "--snapshot", 1, 1 << 30, &snapshot); break;
        case 'i': bad = parse_int(optarg, "--iters", 1, 10000000, &iters); break;
        case 'l': bad = parse_double(optarg, "--lambda", &lambda); break;
        case 'w': bad = parse_double(optarg, "--tv-weight", &tv_weight); break;
        case 't': bad = parse_int(optarg, "--tv-iters", 1, 100000, &tv_iters); break;
        case OPT_PLAIN: o.gap.accelerate = 0; break;
        case 'g': bad = parse_double(optarg, "--gamma", &o.admm.gamma); break;
        case OPT_METRICS: bad = parse_int(optarg, "--metrics-every", 0, 1 << 30, &metrics_every); break;
        case OPT_SSIM: bad = parse_int(optarg, "--ssim-every", 0, 1 << 30, &ssim_every); break;
        case 'j': bad = parse_int(optarg, "--threads", 1, 1024, &threads); break;
        case OPT_PRESET: preset = optarg; break;
        case OPT_PATCH: bad = parse_int(optarg, "--patch", 2, 16, &nf_patch); break;
        case OPT_PPS: bad = parse_int(optarg, "--patches-per-step", 1, 4096, &nf_pps); break;
        case OPT_SAMPLES: bad = parse_int(optarg, "--samples", 2, 1024, &nf_samples); break;
        case OPT_LR: bad = parse_double(optarg, "--lr", &nf_lr); break;
        case OPT_POSE:
            if (strcmp(optarg, "known") == 0)
                nf_pose = NERF_POSES_KNOWN;
            else if (strcmp(optarg, "linear") == 0)
                nf_pose = NERF_POSES_LINEAR;
            else if (strcmp(optarg, "per-frame") == 0)
                nf_pose = NERF_POSES_PER_FRAME;
            else {
                fprintf(stderr, "scicap recon: --pose-mode wants known, linear or per-frame, got '%s'\n", optarg);
                bad = -1;
            }
            break;
        case OPT_ABLATION: {
            static const char *const steps[] = {"baseline", "patch", "inter", "intra", "tv"};
            for (int k = 0; k < 5; k++)
                if (strcmp(optarg, steps[k]) == 0 || strcmp(optarg, sci_rayformer_ablation_names[k]) == 0)
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
            if (strcmp(optarg, "linear") == 0)
                nf_spacing = NERF_SPACING_LINEAR;
            else if (strcmp(optarg, "disparity") == 0)
                nf_spacing = NERF_SPACING_DISPARITY;
            else if (strcmp(optarg, "log") == 0)
                nf_spacing = NERF_SPACING_LOG;
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
    if (optind != argc - 1 || !out) {
        fprintf(stderr, "scicap recon: %s\n", !out ? "-o OUTDIR is required" : "exactly one INPUT is required");
        usage(stderr);
        return 2;
    }
    const char *input = argv[optind];
    /* NeRF methods: the preset first, then the options given explicitly. */
    if (preset && (sci_rayformer_params_preset(&o.rf, preset) < 0 || sci_scinerf_params_preset(&o.sn, preset) < 0)) {
        fprintf(stderr, "scicap recon: unknown preset '%s' (fast, balanced, best)\n", preset);
        return 2;
    }
    if (nf_ablation >= 0)
        sci_rayformer_params_ablation(&o.rf, nf_ablation, o.rf.tv_weight);
    if (nf_patch)
        o.rf.patch = nf_patch;
    if (nf_pps)
        o.rf.patches_per_step = nf_pps;
    if (nf_samples)
        o.rf.samples = o.sn.samples = nf_samples;
    if (!isnan(nf_lr))
        o.rf.lr = o.sn.lr = nf_lr;
    if (!isnan(nf_net_lr))
        o.rf.net_lr_scale = nf_net_lr;
    if (nf_spacing >= 0)
        o.rf.recipe.spacing = o.sn.recipe.spacing = (nerf_spacing)nf_spacing;
    if (!isnan(nf_dist))
        o.rf.recipe.distortion_weight = o.sn.recipe.distortion_weight = nf_dist;
    if (nf_prior_steps >= 0)
        o.rf.recipe.prior_steps = o.sn.recipe.prior_steps = nf_prior_steps;
    if (!isnan(nf_prior_w))
        o.rf.recipe.prior_weight = o.sn.recipe.prior_weight = nf_prior_w;
    if (!isnan(nf_dbias))
        o.rf.recipe.density_bias = o.sn.recipe.density_bias = nf_dbias;
    if (nf_zero_gates >= 0)
        o.rf.zero_gates = nf_zero_gates;
    if (nf_sh)
        o.rf.sh_degree = o.sn.sh_degree = nf_sh;
    if (nf_pose >= 0)
        o.rf.pose_mode = o.sn.pose_mode = (nerf_poses_mode)nf_pose;
    if (nf_seed >= 0)
        o.rf.seed = o.sn.seed = (unsigned long long)nf_seed;
    if (threads)
        omp_set_num_threads(threads);
    /* Common options map onto whichever method runs. */
    if (iters > 0)
        o.gap.iters = o.admm.iters = o.rf.iters = o.sn.iters = iters;
    if (!isnan(lambda))
        o.gap.lambda = o.admm.lambda = lambda;
    if (!isnan(tv_weight))
        o.gap.tv_weight = o.admm.tv_weight = o.rf.tv_weight = tv_weight;
    if (tv_iters > 0)
        o.gap.tv_iters = o.admm.tv_iters = tv_iters;
    if (metrics_every >= 0)
        o.gap.metrics_every = o.admm.metrics_every = o.rf.metrics_every = o.sn.metrics_every = metrics_every;
    if (ssim_every >= 0)
        o.gap.ssim_every = o.admm.ssim_every = o.rf.ssim_every = o.sn.ssim_every = ssim_every;
    sci_error err = {0};
    int chk = o.method == 0   ? sci_gaptv_params_check(&o.gap, &err)
              : o.method == 1 ? sci_admmtv_params_check(&o.admm, &err)
              : o.method == 2 ? sci_rayformer_params_check(&o.rf, &err)
                              : sci_scinerf_params_check(&o.sn, &err);
    if (chk < 0) {
        fprintf(stderr, "scicap recon: %s\n", err.msg);
        return 2;
    }
    if ((ckpt_path || resume_path) && o.method < 2) {
        fprintf(stderr, "scicap recon: --checkpoint and --resume are for rayformer and scinerf\n");
        return 2;
    }
    if (nf_ablation >= 0 && o.method != 2) {
        fprintf(stderr, "scicap recon: --ablation is for rayformer\n");
        return 2;
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
    if (mo.white == SCI_MAT_WHITE_AUTO)
        fprintf(stderr, "scicap recon: --scale auto: %s; values divided by %g\n", minfo.how, minfo.white);
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
    if (cfa != SCI_CFA_NONE && o.method > 1) {
        fprintf(stderr, "scicap recon: %s is a Bayer mosaic; colour reconstruction runs gap-tv or admm-tv per CFA "
                        "plane (--cfa none reconstructs it as grey)\n", input);
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
    void *resume_blob = NULL;
    size_t resume_bytes = 0;
    if (resume_path) {
        if (sci_file_read(resume_path, (size_t)16 << 30, &resume_blob, &resume_bytes, &err) < 0) {
            fprintf(stderr, "scicap recon: --resume: %s\n", err.msg);
            sci_problem_array_free(probs, k);
            return 1;
        }
        o.rf.resume = o.sn.resume = resume_blob;
        o.rf.resume_bytes = o.sn.resume_bytes = resume_bytes;
    }
    if (ckpt_path) {
        o.rf.checkpoint_fn = o.sn.checkpoint_fn = write_checkpoint;
        o.rf.checkpoint_user = o.sn.checkpoint_user = &ck;
        o.rf.checkpoint_every = o.sn.checkpoint_every = ckpt_every;
    }
    struct sigaction sa = {.sa_handler = on_stop_signal, .sa_flags = SA_RESETHAND}, old_int, old_term;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old_int);
    sigaction(SIGTERM, &sa, &old_term);
    json_t *params = params_json(&o);
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
        static const char *const names[] = {"gap-tv", "admm-tv", "rayformer", "scinerf"};
        printf("%s: %s, %dx%d, %d frames per snapshot%s\n", p->name, names[o.method],
               p->mask->w, p->mask->h, p->mask->n, p->truth ? ", truth known" : "");
        fflush(stdout);
        cli_progress prog;
        const int total = o.method == 0 ? o.gap.iters : o.method == 1 ? o.admm.iters : o.method == 2 ? o.rf.iters : o.sn.iters;
        cli_progress_init(&prog, o.quiet ? -1 : 2, total);
        prog.stop = &stop_requested;
        char dir[4096], shown[4096];
        snprintf(shown, sizeof shown, first == last ? "%s" : "%s/snap_%03d", out, j + 1);
        if (first == last)
            snprintf(dir, sizeof dir, "%s", out);
        else
            snprintf(dir, sizeof dir, "%s/snap_%03d", stage, j + 1);
        if (cfa != SCI_CFA_NONE) {
            const cli_color_job job = {.cfa = cfa, .demosaic = demosaic, .method = o.method, .gap = &o.gap,
                                       .admm = &o.admm, .params = params, .quiet = o.quiet, .stop = &stop_requested};
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
        int rc = o.method == 0   ? sci_gaptv_solve(p, &o.gap, &r, cli_progress_update, &prog)
                 : o.method == 1 ? sci_admmtv_solve(p, &o.admm, &r, cli_progress_update, &prog)
                 : o.method == 2 ? sci_rayformer_solve(p, &o.rf, &r, cli_progress_update, &prog)
                                 : sci_scinerf_solve(p, &o.sn, &r, cli_progress_update, &prog);
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
        if (p->truth)
            print_metrics(p, &r);
        int wrc = sci_recon_store_write_opt(dir, p, &r, params, first == last ? force : 0, &stop_requested, &err);
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
        if (sci_staging_publish(stage, out, force, &stop_requested, &err) < 0) {
            if (err.code != SCI_ECANCELED)
                fprintf(stderr, "scicap recon: %s\n", err.msg);
            status = 1;
        } else {
            printf("wrote %s/\n", out);
        }
    } else if (stage[0]) {
        sci_staging_remove(stage);
    }
    sigaction(SIGINT, &old_int, NULL);
    sigaction(SIGTERM, &old_term, NULL);
    const int sig = stop_requested;
    if (ckpt_path && ck.written && status == 0)
        printf("  checkpoint of step %d in %s\n", ck.iter, ckpt_path);
    json_decref(params);
    for (int j = 0; truth_rgb && j < kc; j++)
        sci_cube_free(truth_rgb[j]);
    free(truth_rgb);
    free(resume_blob);
    sci_problem_array_free(probs, k);
    if (sig) {
        fflush(NULL);
        signal(sig, SIG_DFL);
        raise(sig);
    }
    return status;
}
