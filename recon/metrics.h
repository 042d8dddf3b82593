/* recon/metrics.h — image quality against a known truth (docs/conventions.md §6).
 *
 * PSNR is computed per frame and averaged over frames, in one of two peak conventions, which every printout
 * names:
 *   SCI_PEAK_FRAME_MAX  p = max of the truth frame (MATLAB gapdenoise_cacti.m; the golden 34.63 dB figure);
 *   SCI_PEAK_FIXED      p = a fixed peak, 1 on /255-scaled data (PnP-SCI_python, ucaswangls/cacti).
 * No clipping of the estimate. A frame equal to its truth gives +Inf.
 *
 * SSIM follows Wang et al. 2004 as MATLAB's ssim computes it: Gaussian window σ = 1.5 truncated to 11×11
 * (radius ceil(3σ)), replicate padding, K1 = 0.01, K2 = 0.03, data range L, the map averaged over every pixel.
 *
 * All sums in double. Thread-safe; OpenMP over frames inside, deterministic for a given thread count.
 */
#ifndef SCICAP_RECON_METRICS_H
#define SCICAP_RECON_METRICS_H

#include "base/cube.h"

typedef enum sci_peak { SCI_PEAK_FRAME_MAX, SCI_PEAK_FIXED } sci_peak;

/* PSNR of one frame of n values, dB. */
double sci_psnr_frame(const float *x, const float *ref, size_t n, double peak);
/* Mean PSNR over frames; per_frame (may be NULL) receives x->n values. `peak` is used for SCI_PEAK_FIXED. */
double sci_psnr(const sci_cube *x, const sci_cube *truth, sci_peak conv, double peak, double *per_frame);
/* SSIM of one w×h frame with data range L. */
double sci_ssim_frame(const float *x, const float *ref, int w, int h, double range);
/* Mean SSIM over frames; per_frame (may be NULL) receives x->n values. */
double sci_ssim(const sci_cube *x, const sci_cube *truth, double range, double *per_frame);
/* Colour PSNR as the colour SCI literature reports it: per frame, the mean over R, G and B of each full-resolution
 * channel's PSNR, then the mean over frames. x and truth are RGB cubes (recon/bayer.h: frame f's channel c is
 * frame 3f + c, n = 3N). SCI_PEAK_FRAME_MAX takes each channel's own maximum. per_frame (may be NULL) receives N
 * values. */
double sci_psnr_rgb(const sci_cube *x, const sci_cube *truth, sci_peak conv, double peak, double *per_frame);
/* Name of a convention for printouts: "peak=frame max" or "peak=1" style text written into buf. */
const char *sci_peak_name(sci_peak conv, double peak, char *buf, size_t n);

#endif
