/* recon/nerf/render.h — volume rendering along rays (colour, depth, opacity) with an O(1)-memory backward.
 *
 * Ray k has L sample slots: σ (density, >= 0), c (3 channels), δ (segment length, >= 0; δ_i = (t_{i+1} − t_i)·‖d‖)
 * and optionally t (depth of the sample, for the depth output), all [ray][sample] row-major; n_valid[k] <= L says
 * how many slots of ray k are real (NULL: all L). Per sample, in double:
 *   τ_i = σ_i δ_i,  log T_i = −Σ_{j<i} τ_j (log-space transmittance),  α_i = −expm1(−τ_i),  w_i = T_i α_i,
 *   C = Σ w_i c_i,  D = Σ w_i t_i,  O = Σ w_i = 1 − T_end.
 * Early termination: the march stops after the first sample with T_{i+1} < t_stop (1e-4 as in instant-ngp;
 * 0 disables), and the stopped samples get zero gradient — the backward differentiates the same truncated sum.
 * No "δ_last = 1e10" and no cumprod(1 − α + 1e-10) (docs/conventions.md §10).
 *
 * Backward (instant-ngp): ∂C/∂τ_i = T_{i+1} c_i − (C − C_{≤i}), likewise for D, and ∂O/∂τ_i = T_end; then
 * ∂/∂σ_i = δ_i ∂/∂τ_i, ∂/∂δ_i = σ_i ∂/∂τ_i, ∂C/∂c_i = w_i. It stores nothing per sample: it replays the march
 * twice in double (totals, then gradients), so transmittance is never stored at all.
 * σ = 1e6 (opaque at the first sample), σ = 0 everywhere and δ from 1e-8 to 1e3 stay finite and exact.
 * Runs on the calling thread over the given rays; reentrant.
 */
#ifndef SCICAP_RECON_NERF_RENDER_H
#define SCICAP_RECON_NERF_RENDER_H

#define NERF_RENDER_T_STOP 1e-4f

typedef struct nerf_render_rays {
    int n_rays, L;
    const float *sigma; /* n_rays × L */
    const float *rgb;   /* n_rays × L × 3 */
    const float *delta; /* n_rays × L */
    const float *t;     /* n_rays × L sample depths, or NULL (no depth output) */
    const int *n_valid; /* n_rays, or NULL */
    float t_stop;       /* early-termination transmittance (NERF_RENDER_T_STOP), 0 = march to the end */
} nerf_render_rays;

/* color: n_rays × 3; depth, opacity: n_rays (each may be NULL); n_used: samples marched per ray (may be NULL). */
void nerf_render_forward(const nerf_render_rays *r, float *color, float *depth, float *opacity, int *n_used);
/* d_color n_rays × 3 (NULL = 0), d_depth and d_opacity n_rays (NULL = 0). Outputs overwritten:
 * d_sigma n_rays × L, d_rgb n_rays × L × 3, d_delta n_rays × L (NULL: skip). Unmarched samples get 0. */
void nerf_render_backward(const nerf_render_rays *r, const float *d_color, const float *d_depth,
                          const float *d_opacity, float *d_sigma, float *d_rgb, float *d_delta);

#endif
