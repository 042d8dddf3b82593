/* recon/pnp_ffdnet.c — PnP-FFDNet (see pnp_ffdnet.h). */
#include "recon/pnp_ffdnet.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "recon/bayer.h"
#include "recon/cnn/ffdnet.h"
#include "recon/gaptv.h"
#include "recon/demosaic.h"
#include "recon/sci_ops.h"
#include "recon/tracer.h"

static const char *const projection_names[] = {"gap", "admm", NULL};

/* GAP-TV iterations that start the colour route when tv_init is auto (see start_point). */
#define PNP_TV_INIT_BAYER 50

void sci_pnp_params_default(sci_pnp_params *p)
{
    *p = (sci_pnp_params){.iters = 60, .sigma = {3, {50, 25, 12}},
                          .sigma_rgb = {3, {50, 40, 30}}, .tv_init = -1, .projection = SCI_PNP_GAP, .lambda = 1.0,
                          .accelerate = 1, .gamma = 0.01, .metrics_every = 1, .ssim_every = 10};
}

int sci_pnp_params_check(const sci_pnp_params *p, sci_error *err)
{
    if (p->sigma.n < 1 || p->sigma.n > SOLVER_LIST_MAX || p->sigma_rgb.n < 1 || p->sigma_rgb.n > SOLVER_LIST_MAX)
        return sci_error_set(err, -EINVAL, "pnp-ffdnet: sigma and sigma_rgb need 1 to %d stages (have %d, %d)",
                             SOLVER_LIST_MAX, p->sigma.n, p->sigma_rgb.n);
    if (p->iters < 1 || p->iters > 1000000)
        return sci_error_set(err, -EINVAL, "pnp-ffdnet: iters must be in [1, 1e6] (got %d)", p->iters);
    for (int i = 0; i < p->sigma.n; i++)
        if (!(p->sigma.v[i] > 0 && p->sigma.v[i] <= 255))
            return sci_error_set(err, -EINVAL, "pnp-ffdnet: sigma[%d] must be in (0, 255] (got %g)", i,
                                 p->sigma.v[i]);
    if (!(p->lambda > 0) || !isfinite(p->lambda))
        return sci_error_set(err, -EINVAL, "pnp-ffdnet: lambda must be > 0 (got %g)", p->lambda);
    if (!(p->gamma >= 0) || !isfinite(p->gamma))
        return sci_error_set(err, -EINVAL, "pnp-ffdnet: gamma must be >= 0 (got %g)", p->gamma);
    if (p->projection != SCI_PNP_GAP && p->projection != SCI_PNP_ADMM)
        return sci_error_set(err, -EINVAL, "pnp-ffdnet: projection must be gap or admm");
    if (p->tv_init < -1 || p->tv_init > 100000)
        return sci_error_set(err, -EINVAL, "pnp-ffdnet: tv_init must be in [-1 (auto), 1e5] (got %d)", p->tv_init);
    for (int i = 0; i < p->sigma_rgb.n; i++)
        if (!(p->sigma_rgb.v[i] > 0 && p->sigma_rgb.v[i] <= 255))
            return sci_error_set(err, -EINVAL, "pnp-ffdnet: sigma_rgb[%d] must be in (0, 255] (got %g)", i,
                                 p->sigma_rgb.v[i]);
    if (p->threads < 0 || p->threads > 1024 || p->metrics_every < 0 || p->ssim_every < 0)
        return sci_error_set(err, -EINVAL, "pnp-ffdnet: threads and metrics intervals must be >= 0");
    return 0;
}

int sci_pnp_weights_path(const sci_pnp_params *p, int colour, char *buf, size_t n, sci_error *err)
{
    const char *given = colour ? p->weights_rgb : p->weights, *file = colour ? "net_rgb.pth" : "net_gray.pth";
    if (given[0]) {
        snprintf(buf, n, "%s", given);
        return 0;
    }
    const char *data = getenv("SCICAP_DATA");
    char tried[2][SOLVER_STRING_MAX + 32];
    snprintf(tried[0], sizeof tried[0], "%s/ffdnet/%s", data && data[0] ? data : ".", file);
    snprintf(tried[1], sizeof tried[1], "%s/ffdnet/%s", SCICAP_DATADIR, file);
    for (int i = data && data[0] ? 0 : 1; i < 2; i++)
        if (access(tried[i], R_OK) == 0) {
            snprintf(buf, n, "%s", tried[i]);
            return 0;
        }
    return sci_error_set(err, -ENOENT,
                         "pnp-ffdnet: no FFDNet weights: give --set %s=PATH/%s (PnP-SCI's pretrained %s FFDNet; "
                         "docs/pnp-ffdnet.md, \"The weights\"); looked for %s%s%s",
                         colour ? "weights_rgb" : "weights", file, colour ? "colour" : "grey",
                         data && data[0] ? tried[0] : "", data && data[0] ? " and " : "", tried[1]);
}

/* Stage of iteration it (1-based) when `iters` split evenly over `stages`, the first taking the remainder. */
static int stage_of(int it, int iters, int stages)
{
    const int base = iters / stages, extra = iters % stages;
    int end = 0;
    for (int s = 0; s < stages; s++) {
        end += base + (s < extra);
        if (it <= end)
            return s;
    }
    return stages - 1;
}

/* What the denoising step needs besides x. */
typedef struct denoiser {
    cnn_ffdnet_plan *plan;
    double peak;
    int cfa, demosaic; /* a Bayer mosaic: demosaic, colour FFDNet, mosaic again (PnP-SCI's colour route) */
    float *buf;        /* one frame (grey) or three planes (colour) */
    sci_cube *rgb;     /* colour: the denoised RGB frames of the last iteration, w × h × 3N */
} denoiser;

/* Every frame of x through FFDNet at σ (0–255 scale), on the denoiser's [0, 1] scale. */
static void denoise_frames(denoiser *d, sci_cube *x, double sigma255)
{
    const size_t fs = sci_cube_frame_size(x);
    const float to01 = (float)(1.0 / d->peak), back = (float)d->peak, sigma = (float)(sigma255 / 255.0);
    for (int k = 0; k < x->n; k++) {
        float *xk = x->data + (size_t)k * fs;
        if (d->cfa == SCI_CFA_NONE) {
            for (size_t i = 0; i < fs; i++)
                d->buf[i] = xk[i] * to01;
            cnn_ffdnet_denoise(d->plan, d->buf, sigma, d->buf);
            for (size_t i = 0; i < fs; i++)
                xk[i] = d->buf[i] * back;
            continue;
        }
        float *rgb = d->rgb->data + (size_t)3 * k * fs;
        sci_demosaic((sci_cfa)d->cfa, (sci_demosaic_method)d->demosaic, xk, x->w, x->h, d->buf, d->buf + fs,
                     d->buf + 2 * fs);
        for (size_t i = 0; i < 3 * fs; i++)
            d->buf[i] *= to01;
        cnn_ffdnet_denoise(d->plan, d->buf, sigma, d->buf);
        for (size_t i = 0; i < 3 * fs; i++)
            rgb[i] = d->buf[i] * back;
        for (int y = 0; y < x->h; y++)
            for (int c = 0; c < x->w; c++) {
                const size_t i = (size_t)y * x->w + c;
                xk[i] = rgb[(size_t)sci_cfa_color((sci_cfa)d->cfa, c, y) * fs + i];
            }
    }
}

static int tv_plane(const sci_problem *plane, sci_result *r, void *user)
{
    return sci_gaptv_solve(plane, user, r, NULL, NULL);
}

/* x⁰: Aᵀy, or tv_init iterations of GAP-TV (per CFA plane for a mosaic) — the colour route needs it: from Aᵀy the
 * demosaiced half-empty frames lead the colour denoiser to a maze-patterned fixed point (≈ 8 dB on the colour scene). */
static int start_point(const sci_problem *p, const sci_pnp_params *q, int cfa, sci_cube *x, sci_error *err)
{
    const int k = q->tv_init >= 0 ? q->tv_init : cfa == SCI_CFA_NONE ? 0 : PNP_TV_INIT_BAYER;
    if (k == 0) {
        sci_op_adjoint(p->mask, p->meas, x);
        return 0;
    }
    sci_gaptv_params tv;
    sci_gaptv_params_default(&tv);
    tv.iters = k;
    tv.metrics_every = tv.ssim_every = 0;
    tv.tv_weight *= p->peak > 0 ? p->peak : 1.0; /* its weight is on the [0, 1] scale */
    sci_result r = {0}, planes[4] = {{0}};
    sci_cube *rgb = NULL, *raw = NULL;
    int rc = cfa == SCI_CFA_NONE ? sci_gaptv_solve(p, &tv, &r, NULL, NULL)
                                 : sci_bayer_solve(p, (sci_cfa)cfa, SCI_DEMOSAIC_MHC, tv_plane, &tv, &rgb, &raw, planes,
                                                   err);
    const sci_cube *got = cfa == SCI_CFA_NONE ? r.frames : raw;
    if (rc == 0 && got)
        memcpy(x->data, got->data, sci_cube_count(x) * sizeof *x->data);
    else if (cfa == SCI_CFA_NONE)
        sci_error_set(err, rc < 0 ? rc : -EINVAL, "pnp-ffdnet: GAP-TV start: %s", r.error.msg);
    sci_result_free_contents(&r);
    for (int i = 0; i < 4; i++)
        sci_result_free_contents(&planes[i]);
    sci_cube_free(rgb);
    sci_cube_free(raw);
    return rc < 0 ? rc : 0;
}

static int solve(const sci_problem *problem, const sci_pnp_params *params, int cfa, int demosaic, sci_cube **rgb_out,
                 sci_result *result, sci_progress_fn progress, void *user)
{
    snprintf(result->method, sizeof result->method, "pnp-ffdnet");
    sci_error *err = &result->error;
    char path[SOLVER_STRING_MAX + 32];
    const int colour = cfa != SCI_CFA_NONE;
    int rc = sci_pnp_params_check(params, err);
    if (rc == 0)
        rc = sci_problem_validate(problem, err);
    if (rc == 0 && colour && (problem->mask->w % 2 || problem->mask->h % 2))
        rc = sci_error_set(err, SCI_ESHAPE, "pnp-ffdnet: %s: a Bayer mosaic must have even sizes (%dx%d)",
                           problem->name, problem->mask->w, problem->mask->h);
    const solver_values *stages = colour ? &params->sigma_rgb : &params->sigma;
    if (rc == 0 && params->iters < stages->n)
        rc = sci_error_set(err, -EINVAL, "pnp-ffdnet: iters (%d) must be at least one per %s stage (%d)",
                           params->iters, colour ? "sigma_rgb" : "sigma", stages->n);
    if (rc == 0)
        rc = sci_pnp_weights_path(params, colour, path, sizeof path, err);
    if (rc < 0)
        return rc;
    const sci_cube *y = problem->meas, *mask = problem->mask;
    const int w = mask->w, h = mask->h, n = mask->n;
    const size_t fs = sci_cube_frame_size(mask), count = sci_cube_count(mask);
    const int admm = params->projection == SCI_PNP_ADMM;

    cnn_ffdnet *net = NULL;
    denoiser d = {.peak = problem->peak > 0 ? problem->peak : 1.0, .cfa = cfa, .demosaic = demosaic};
    sci_cube *x = NULL, *b = NULL, *v = NULL, *yhat = NULL, *ybar = NULL, *den = NULL, *r = NULL;
    double *rowbuf = NULL;
    if ((rc = cnn_ffdnet_load(path, &net, err)) < 0)
        return sci_error_prefix(err, "pnp-ffdnet: %s: ", colour ? "weights_rgb" : "weights");
    if (cnn_ffdnet_channels(net) != (colour ? 3 : 1)) {
        rc = sci_error_set(err, -EINVAL, "pnp-ffdnet: %s is the %s FFDNet; %s problems need %s", path,
                           colour ? "grey" : "colour", colour ? "Bayer" : "grey",
                           colour ? "net_rgb.pth" : "net_gray.pth");
        goto out;
    }
    if ((rc = cnn_ffdnet_plan_new(net, w, h, params->threads, &d.plan, err)) < 0)
        goto out;
    d.buf = malloc((colour ? 3 : 1) * fs * sizeof *d.buf);
    rowbuf = malloc(2 * (size_t)h * sizeof *rowbuf);
    if (!d.buf || !rowbuf || (rc = sci_cube_new(&x, w, h, n, err)) < 0 ||
        (rc = sci_cube_new(&yhat, w, h, 1, err)) < 0 || (rc = sci_cube_new(&den, w, h, 1, err)) < 0 ||
        (rc = sci_cube_new(&r, w, h, 1, err)) < 0 || (colour && (rc = sci_cube_new(&d.rgb, w, h, 3 * n, err)) < 0) ||
        (!admm && (rc = sci_cube_new(&ybar, w, h, 1, err)) < 0) ||
        (admm && ((rc = sci_cube_new(&b, w, h, n, err)) < 0 || (rc = sci_cube_new(&v, w, h, n, err)) < 0))) {
        if (rc >= 0)
            rc = sci_error_set(err, -ENOMEM, "pnp-ffdnet: out of memory");
        goto out;
    }
    sci_op_phi_sum(mask, den);
    if (admm)
        for (size_t i = 0; i < fs; i++)
            den->data[i] += (float)params->gamma;
    sci_tracer tr;
    sci_tracer_start(&tr, problem, result, progress, user, params->iters, params->metrics_every, params->ssim_every);
    if ((rc = start_point(problem, params, cfa, x, err)) < 0) /* x is θ for ADMM; its time counts in the trace's */
        goto out;
    for (int it = 1; it <= params->iters; it++) {
        const solver_values *sv = colour ? &params->sigma_rgb : &params->sigma;
        const double sigma = sv->v[stage_of(it, params->iters, sv->n)];
        const float lambda = (float)params->lambda;
        if (admm) {
            for (size_t i = 0; i < count; i++)
                v->data[i] = x->data[i] + b->data[i];
            sci_op_forward(mask, v, yhat);
            for (size_t i = 0; i < fs; i++)
                r->data[i] = (y->data[i] - yhat->data[i]) / den->data[i];
            for (int k = 0; k < n; k++) {
                const size_t o = (size_t)k * fs;
                for (size_t i = 0; i < fs; i++) {
                    v->data[o + i] += lambda * mask->data[o + i] * r->data[i];
                    x->data[o + i] = v->data[o + i] - b->data[o + i];
                }
            }
            denoise_frames(&d, x, sigma);
            for (size_t i = 0; i < count; i++)
                b->data[i] -= v->data[i] - x->data[i];
        } else {
            sci_op_forward(mask, x, yhat);
            for (size_t i = 0; i < fs; i++) {
                if (params->accelerate)
                    ybar->data[i] += y->data[i] - yhat->data[i];
                r->data[i] = ((params->accelerate ? ybar->data[i] : y->data[i]) - yhat->data[i]) / den->data[i];
            }
            for (int k = 0; k < n; k++) {
                const size_t o = (size_t)k * fs;
                for (size_t i = 0; i < fs; i++)
                    x->data[o + i] += lambda * mask->data[o + i] * r->data[i];
            }
            denoise_frames(&d, x, sigma);
        }
        const double res = sci_op_forward_residual(mask, x, y, NULL, rowbuf);
        if ((rc = sci_tracer_record(&tr, it, x, res, NAN)) != 0)
            break;
    }
    if (rc != SCI_EDIVERGED) {
        result->frames = x; /* never hand out a diverged estimate */
        x = NULL;
        if (rgb_out) {
            *rgb_out = d.rgb;
            d.rgb = NULL;
        }
    }
out:
    free(d.buf);
    free(rowbuf);
    cnn_ffdnet_plan_free(d.plan);
    cnn_ffdnet_free(net);
    sci_cube_free(d.rgb);
    sci_cube_free(x);
    sci_cube_free(b);
    sci_cube_free(v);
    sci_cube_free(yhat);
    sci_cube_free(ybar);
    sci_cube_free(den);
    sci_cube_free(r);
    return rc;
}

int sci_pnp_solve(const sci_problem *problem, const sci_pnp_params *params, sci_result *result,
                  sci_progress_fn progress, void *user)
{
    return solve(problem, params, SCI_CFA_NONE, 0, NULL, result, progress, user);
}

int sci_pnp_solve_bayer(const sci_problem *problem, const sci_pnp_params *params, int cfa, int demosaic,
                        sci_cube **rgb, sci_result *result, sci_progress_fn progress, void *user)
{
    return solve(problem, params, cfa, demosaic, rgb, result, progress, user);
}

/* --- the method's row in the solver table (recon/solver.h) ------------------------------------------------ */

#define PNP_FIELD(k, t, f, lo, hi, names, help) {k, t, offsetof(sci_pnp_params, f), lo, hi, names, 0, help}
static const solver_field pnp_fields[] = {
    PNP_FIELD("iters", SOLVER_FIELD_INT, iters, 1, 1e6, NULL, "iterations over all sigma stages"),
    PNP_FIELD("sigma", SOLVER_FIELD_LIST, sigma, 0.001, 255, NULL,
              "denoiser sigma of each stage on the 0-255 scale, e.g. 50,25,12,6"),
    PNP_FIELD("projection", SOLVER_FIELD_ENUM, projection, 0, 0, projection_names, "gap or admm"),
    PNP_FIELD("lambda", SOLVER_FIELD_DOUBLE, lambda, 0, 1e6, NULL, "step size λ (> 0)"),
    PNP_FIELD("accelerate", SOLVER_FIELD_BOOL, accelerate, 0, 1, NULL, "GAP: accelerated (ȳ accumulation)"),
    PNP_FIELD("gamma", SOLVER_FIELD_DOUBLE, gamma, 0, 1e6, NULL, "ADMM: added to the mask energy"),
    PNP_FIELD("weights", SOLVER_FIELD_STRING, weights, 0, 0, NULL,
              "FFDNet weights file (net_gray.pth); empty: $SCICAP_DATA/ffdnet/"),
    PNP_FIELD("weights_rgb", SOLVER_FIELD_STRING, weights_rgb, 0, 0, NULL,
              "colour FFDNet weights (net_rgb.pth) for Bayer problems; empty: $SCICAP_DATA/ffdnet/"),
    PNP_FIELD("tv_init", SOLVER_FIELD_INT, tv_init, -1, 1e5, NULL,
              "GAP-TV iterations for the starting point (per CFA plane for Bayer); 0: Aᵀy; -1: 0 grey, 50 Bayer"),
    PNP_FIELD("sigma_rgb", SOLVER_FIELD_LIST, sigma_rgb, 0.001, 255, NULL,
              "Bayer problems: the colour denoiser's sigma of each stage, e.g. 50,40,30"),
    PNP_FIELD("threads", SOLVER_FIELD_INT, threads, 0, 1024, NULL, "denoiser threads (0: all)"),
    PNP_FIELD("metrics_every", SOLVER_FIELD_INT, metrics_every, 0, 1e9, NULL, "PSNR in the trace every k iterations"),
    PNP_FIELD("ssim_every", SOLVER_FIELD_INT, ssim_every, 0, 1e9, NULL, "SSIM in the trace every k iterations"),
};

static void pnp_defaults(void *s) { sci_pnp_params_default(s); }

/* From the measured curves (docs/pnp-ffdnet.md; PSNR peak = frame max at 36 … 160 iterations over σ 50, 25, 12 and
 * 50, 25, 12, 6): on drop40 the plateau is 40.29 dB (80 at four σ); the last stage, σ 6, gains nothing there and
 * costs 1–2 dB on the sensor-noise scene, so every preset stops at 12. fast = 40 iterations (39.70, within 1 dB of
 * drop40's plateau and of the layers scene's), balanced = 60 (40.27, within 0.3 on drop40, the layers and the
 * sensor-noise scenes), best = 80 (40.22 on drop40, the best of all on the sensor-noise scene: 26.57 against 25.28
 * at 60). The defaults are balanced. */
static void pnp_preset(void *s, solver_preset p)
{
    static const int iters[SOLVER_PRESET_COUNT] = {40, 60, 80};
    sci_pnp_params *q = s;
    q->iters = iters[p];
    q->sigma = (solver_values){3, {50, 25, 12}};
}

static int pnp_check(const void *s, sci_error *err) { return sci_pnp_params_check(s, err); }

static int pnp_run(const sci_problem *p, const void *s, const solver_io *io, sci_result *r)
{
    return solve(p, s, io->cfa, io->demosaic, io->rgb_out, r, io->progress, io->user);
}

/* The bench grid: whole σ stages of about ten iterations, then the presets. */
static const char *const pnp_bench_quick[] = {"{\"iters\":5,\"sigma\":[50]}", NULL};
static const char *const pnp_bench_full[] = {"{\"iters\":10,\"sigma\":[50]}", "{\"iters\":20,\"sigma\":[50,25]}",
                                             "{\"preset\":\"fast\"}", "{\"preset\":\"balanced\"}",
                                             "{\"preset\":\"best\"}", NULL};

const solver_ops sci_pnp_ffdnet_solver = {
    .name = "pnp-ffdnet",
    .summary = "plug-and-play GAP/ADMM with the pretrained FFDNet denoiser (needs its weights file)",
    .caps = SOLVER_BAYER,
    .settings_size = sizeof(sci_pnp_params),
    .fields = {{pnp_fields, sizeof pnp_fields / sizeof pnp_fields[0], 0}},
    .defaults = pnp_defaults,
    .preset = pnp_preset,
    .check = pnp_check,
    .run = pnp_run,
    .bench_quick = pnp_bench_quick,
    .bench_full = pnp_bench_full,
};
