/* recon/pnp_ffdnet.h — PnP-FFDNet: plug-and-play GAP or ADMM with the pretrained FFDNet denoiser, frame by frame
 * (Yuan, Liu, Suo, Dai, "Plug-and-play algorithms for large-scale snapshot compressive imaging", CVPR 2020;
 * liuyang12/PnP-SCI_python pnp_sci.py). The projections are GAP-TV's and ADMM-TV's (recon/gaptv.h,
 * recon/admmtv.h) with the TV step replaced by FFDNet (recon/cnn/ffdnet.h):
 *
 *   GAP:  x⁰ = Aᵀy, ȳ = 0; each iteration: ŷ = A(x); ȳ ← ȳ + (y − ŷ) (accelerated);
 *         x ← x + λ Aᵀ((ȳ − ŷ) ⊘ Φ_sum);  x ← FFDNet(x, σ_stage)                          → returns x
 *   ADMM: θ = Aᵀy, b = 0; each iteration: v = (θ + b) + λ Aᵀ((y − A(θ + b)) ⊘ (Φ_sum + γ));
 *         θ = FFDNet(v − b, σ_stage); b ← b − (v − θ)                                        → returns θ
 *
 * σ runs through `sigma` (on the 0–255 scale of 8-bit data: 50, 25, 12, 6 is PnP-SCI's grey schedule), the
 * iterations split evenly over the stages (the first stages take the remainder). The denoiser sees each frame
 * divided by the problem's peak (its [0, 1] scale) and its output is scaled back; no clamping, as the reference.
 *
 * Colour: a Bayer mosaic (solver_io.cfa) follows PnP-SCI's colour route (sci_pnp_solve_bayer below).
 *
 * Weights: `weights` names the grey FFDNet state dict (net_gray.pth of PnP-SCI; docs/pnp-ffdnet.md says where to get it).
 * Empty: $SCICAP_DATA/ffdnet/net_gray.pth, then SCICAP_DATADIR/ffdnet/net_gray.pth (where `make install` puts
 * nothing: the weights are not ours to ship). A missing or bad file is an error naming it and what was tried.
 *
 * Contract as recon/gaptv.h: validates, fills result->frames and the trace (residual, PSNR/SSIM with truth, wall
 * time), calls progress after every iteration, returns 0, SCI_ECANCELED, SCI_EDIVERGED or an error. Blocks;
 * OpenMP threads inside (`threads`, 0: all).
 */
#ifndef SCICAP_RECON_PNP_FFDNET_H
#define SCICAP_RECON_PNP_FFDNET_H

#include "recon/problem.h"
#include "recon/solver.h"

typedef enum sci_pnp_projection { SCI_PNP_GAP, SCI_PNP_ADMM } sci_pnp_projection;

typedef struct sci_pnp_params {
    int iters;                        /* total iterations over all σ stages, >= number of stages */
    solver_values sigma;                /* σ per stage on the 0–255 scale, each in (0, 255] */
    int projection;                   /* sci_pnp_projection */
    double lambda;                    /* step size λ, > 0 */
    int accelerate;                   /* GAP: accumulate ȳ */
    double gamma;                     /* ADMM: added to Φ_sum */
    char weights[SOLVER_STRING_MAX];  /* grey FFDNet weights file; "" = the default search above */
    char weights_rgb[SOLVER_STRING_MAX]; /* colour FFDNet (net_rgb.pth), for Bayer problems; "" = as above */
    solver_values sigma_rgb;          /* Bayer problems: σ per stage of the colour denoiser (50, 40, 30) */
    int tv_init;                      /* GAP-TV iterations for the starting point (0: x⁰ = Aᵀy; -1: 0 for grey,
                                         50 for Bayer, whose route needs it) */
    int threads;                      /* OpenMP threads of the denoiser; 0 = all */
    int metrics_every, ssim_every;    /* as sci_gaptv_params */
} sci_pnp_params;

void sci_pnp_params_default(sci_pnp_params *p);
int sci_pnp_params_check(const sci_pnp_params *p, sci_error *err);
/* The weights file a run would read (params->weights, or weights_rgb when colour, or the default search) into
 * buf; -ENOENT naming what was tried when none exists. */
int sci_pnp_weights_path(const sci_pnp_params *p, int colour, char *buf, size_t n, sci_error *err);

int sci_pnp_solve(const sci_problem *problem, const sci_pnp_params *params, sci_result *result,
                  sci_progress_fn progress, void *user);

/* A raw Bayer mosaic (cfa a sci_cfa, recon/demosaic.h), PnP-SCI's colour route: after each projection every frame
 * is demosaiced (`demosaic`, a sci_demosaic_method), denoised by the colour FFDNet and mosaicked again. result
 * holds the mosaic frames; *rgb (may be NULL) receives the last denoised RGB frames, w × h × 3N (caller frees). */
int sci_pnp_solve_bayer(const sci_problem *problem, const sci_pnp_params *params, int cfa, int demosaic,
                        sci_cube **rgb, sci_result *result, sci_progress_fn progress, void *user);

/* The method's row in the solver table (settings: sci_pnp_params). */
extern const solver_ops sci_pnp_ffdnet_solver;

#endif
