/* cli/recon_color.h — `scicap recon` on a colour (Bayer) problem: a method with SOLVER_BAYER reconstructs the
 * mosaic whole and hands out RGB frames (recon/solver.h); any other method that needs no camera solves the four
 * CFA planes one after another (recon/bayer.h), demosaiced. RGB PSNR printed (mean over R, G, B), and the outputs
 * of a grey reconstruction (frames = the raw mosaic, trace, result.json) plus RGB ones:
 * rgb_NNN.exr (float, 3 channels), preview_rgb_NNN.png (colour, 8-bit), and a "color" record in result.json. */
#ifndef SCICAP_CLI_RECON_COLOR_H
#define SCICAP_CLI_RECON_COLOR_H

#include <jansson.h>
#include <signal.h>

#include "recon/bayer.h"
#include "recon/solver.h"

typedef struct cli_color_job {
    sci_cfa cfa;
    sci_demosaic_method demosaic;
    const solver_ops *method;           /* without SOLVER_NEEDS_CAMERA */
    const void *settings;               /* the method's settings (borrowed) */
    const json_t *params;               /* the run's parameters for result.json (borrowed) */
    int quiet;
    int preview_auto;                   /* previews auto-contrast (io/recon_store.h) */
    const json_t *extra;                /* added to result.json (borrowed, may be NULL): the input's scales */
    const volatile sig_atomic_t *stop;  /* set by a signal: stop (SCI_ECANCELED) */
} cli_color_job;

/* Reconstruct problem p (the raw mosaic) into dir; truth_rgb (may be NULL) gives the RGB PSNR. Prints to stdout.
 * Returns 0, SCI_ECANCELED, or an error with err set. */
int cli_recon_color(const cli_color_job *job, const sci_problem *p, const sci_cube *truth_rgb, const char *dir,
                    int force, sci_error *err);

#endif
