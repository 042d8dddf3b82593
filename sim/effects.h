/* sim/effects.h — the physical effects between the scene and the recorded snapshot, applied only when listed.
 *
 * The simulator's scale: scene frames X and masks M lie in [0, 1], and with no effects the measurement is exactly
 * the plain forward model y = Σ_f M_f ⊙ X_f (recon/sci_ops.h, sci_op_forward), so y lies in [0, N] and a problem's
 * peak is 1. Sensor effects work in electrons: a white scene point seen through an open mirror for one sub-frame
 * gives `photons_white` electrons, i.e. electrons = y · photons_white; after the sensor effects the result is
 * divided by photons_white again, so noisy and clean measurements share one scale and PSNRs stay comparable.
 *
 * The fixed physical order (each effect its own slot; unlisted ones are skipped entirely):
 *   scene      1 motion_blur      each frame = mean of `samples` renders across its sub-frame (temporal supersampling)
 *   optics     2 blur             Gaussian PSF (sigma_px) or a PSF image, normalised to sum 1, edges clamped
 *              3 vignetting       cos⁴ fall-off, (1 + (r/f)²)⁻², f chosen so the corners get `corner` of the centre
 *   DMD        4 dmd_contrast     M' = fill_factor · (leakage + (1 − leakage)·M): off mirrors leak, mirrors gap
 *              5 misregistration  the sensor sees the mask shifted by (dx, dy) px and rotated by rotation_rad about
 *                                 the frame centre: bilinear resampling, outside the DMD is dark
 *              6 jitter           each mask's share of the exposure w_f = max(0, 1 + sigma·n_f), rescaled so
 *                                 Σ w_f = N (the total exposure is kept): y = Σ w_f M_f ⊙ X_f
 *   (forward model)
 *   sensor     7 shot_noise       electrons ~ Poisson(electrons)
 *              8 dark_offset      + dark_e electrons (a bias: not subtracted afterwards)
 *              9 saturation       min(electrons, full_well_e) — the well fills before readout
 *             10 read_noise       + Normal(0, sigma_e²) electrons
 *             11 quantization     DN = clamp(round(electrons / gain_e_per_dn), 0, 2^bit_depth − 1), back to electrons
 * Effects 2–6 change what the sensor sees, not what the problem records: the problem keeps the sharp truth and the
 * nominal masks, as a reconstruction on real hardware would have them.
 *
 * Randomness: each effect draws from its own streams, sci_rng_seed(seed, id) with id built from the effect, the
 * snapshot and the row, so turning one effect on or off never moves another's draws, and results do not depend on
 * the thread count. Costs: an unlisted effect allocates nothing, makes no pass and draws nothing; sim_stats
 * counts passes and draws per effect so tests can check it. With nothing listed, measuring is one call of
 * sci_op_forward.
 */
#ifndef SCICAP_SIM_EFFECTS_H
#define SCICAP_SIM_EFFECTS_H

#include <stddef.h>
#include <stdint.h>

#include "base/cube.h"
#include "base/json.h"

typedef enum sim_fx {
    SIM_FX_MOTION_BLUR,
    SIM_FX_BLUR,
    SIM_FX_VIGNETTING,
    SIM_FX_DMD_CONTRAST,
    SIM_FX_MISREGISTRATION,
    SIM_FX_JITTER,
    SIM_FX_SHOT_NOISE,
    SIM_FX_DARK_OFFSET,
    SIM_FX_SATURATION,
    SIM_FX_READ_NOISE,
    SIM_FX_QUANTIZATION,
    SIM_FX_COUNT
} sim_fx;

/* JSON key of an effect ("shot_noise", ...); NULL outside the range. */
const char *sim_fx_name(int fx);

typedef struct sim_effects_spec {
    unsigned listed;            /* bit (1u << fx) set for each listed effect */
    int motion_samples;         /* renders per sub-frame, >= 2 */
    double blur_sigma_px;       /* Gaussian PSF, pixels (0 when a PSF image is used) */
    sci_cube *psf;              /* PSF image, odd sides, sums to 1; owned */
    double vignetting_corner;   /* relative illumination at the corners, (0, 1] */
    double leakage, fill_factor;
    double misreg_dx_px, misreg_dy_px, misreg_rotation_rad;
    double jitter_sigma;        /* relative std of each mask's exposure share */
    double dark_e, read_sigma_e;
    double photons_white;       /* electrons from white through an open mirror for one sub-frame */
    double full_well_e;
    double gain_e_per_dn;
    int bit_depth;
} sim_effects_spec;

/* Parse "effects" and "sensor" of the scene root (both optional). n = frames per snapshot, bit_depth from the
 * scene. Sensor defaults: photons_white 1000, full_well_e = photons_white·n, gain = full_well_e/(2^bit_depth − 1). */
int sim_effects_parse(const sci_json_doc *doc, const json_t *root, const char *base_dir, int n, int bit_depth,
                      sim_effects_spec *out, sci_error *err);
void sim_effects_spec_clear(sim_effects_spec *s);
static inline int sim_fx_listed(const sim_effects_spec *s, int fx) { return (s->listed >> fx) & 1u; }

/* What measuring cost, per effect (accumulated over calls; zero it yourself). */
typedef struct sim_stats {
    long long passes[SIM_FX_COUNT];   /* passes over a snapshot's data (one per snapshot per listed effect) */
    long long draws[SIM_FX_COUNT];    /* random variates drawn */
    uint64_t draw_hash[SIM_FX_COUNT]; /* XOR over variates of a hash of (value, position): same draws ⇔ same hash */
    size_t work_bytes;                /* working memory the plan holds */
} sim_stats;

/* Renders the scene at time t (frames; frame g is t = g) into out (w×h floats). Returns 0 or a negative code.
 * Needed only by motion_blur. */
typedef int (*sim_render_fn)(void *user, double t, float *out);

typedef struct sim_effects sim_effects;

/* Plan: check sizes and allocate the working memory the listed effects need (none when nothing is listed).
 * `spec` is borrowed and must outlive the plan. */
int sim_effects_new(sim_effects **out, const sim_effects_spec *spec, int w, int h, int n, uint64_t seed,
                    sci_error *err);
void sim_effects_free(sim_effects *fx);
size_t sim_effects_work_bytes(const sim_effects *fx);

/* Measure snapshot `snapshot` (0-based; selects the random streams and, for motion blur, the frames
 * snapshot·N … snapshot·N + N − 1): y (w×h×1) from truth and mask (w×h×N). `render` may be NULL unless motion_blur
 * is listed. stats (may be NULL) accumulates counts. Allocation-free; one call at a time per plan. */
int sim_effects_measure(sim_effects *fx, int snapshot, const sci_cube *truth, const sci_cube *mask,
                        sim_render_fn render, void *user, sci_cube *y, sim_stats *stats, sci_error *err);

/* The jitter weights of a snapshot (n values summing to n), as sim_effects_measure uses them. */
void sim_effects_jitter_weights(const sim_effects_spec *s, uint64_t seed, int snapshot, int n, double *w,
                                sim_stats *stats);

#endif
