/* recon/metrics_ssim.h — the SSIM of one frame over a given Gaussian filter, so that a filter can be checked
 * against another on the very same SSIM arithmetic (sci_ssim_frame is this with the library's own filter). */
#ifndef SCICAP_RECON_METRICS_SSIM_H
#define SCICAP_RECON_METRICS_SSIM_H

#define SCI_SSIM_RADIUS 5 /* ceil(3 σ) for σ = 1.5: an 11×11 window */

/* Separable Gaussian of a w×h frame with edge replication: in → out, tmp (w·h doubles) as scratch; g holds the
 * 2·SCI_SSIM_RADIUS + 1 normalised taps. */
typedef void (*sci_ssim_filter)(const double *in, double *out, double *tmp, int w, int h, const double *g);

/* sci_ssim_frame (recon/metrics.h) with `filter` for every local mean; NAN when out of memory. */
double sci_ssim_frame_filtered(const float *x, const float *ref, int w, int h, double range, sci_ssim_filter filter);

#endif
