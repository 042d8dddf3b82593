/* recon/nerf/mlp.h — the SCINeRF-style field: position encoding → ReLU MLP trunk → density and features →
 * colour head on [features, direction encoding] (NeRF / nerf-pytorch architecture, as SCINeRF uses it; with the
 * hash encoding and a narrow trunk it is the Instant-NGP-style variant).
 *
 *   u    = (x − aabb_min)/(aabb_max − aabb_min)              x: sample position (world units)
 *   e    = freq(2u − 1)  (3 + 6·pos_freqs, input included)  or  hashgrid(clamp(u, 0, 1))  (levels·features)
 *   h₀   = ReLU(W₀ e + b₀),  h_l = ReLU(W_l [h_{l−1}, e if l = skip] + b_l),  l < depth   (width W)
 *   σ    = act(w_σ·h_{depth−1} + b_σ + density_bias)         act: ReLU (NeRF) or trunc_exp (Instant-NGP)
 *   f    = W_f h_{depth−1} + b_f                              feature_dim, no activation (NeRF's "feature")
 *   rgb  = sigmoid(W_c2 ReLU(W_c1 [f, enc(d)] + b_c1) + b_c2)  color_hidden = 0: sigmoid(W_c2 [f, enc(d)] + b_c2)
 *   enc(d) = freq(d) (3 + 6·dir_freqs) or SH of degree sh_degree (degree²), d the unit view direction.
 *
 * A batch is any n points; point i takes the direction dir[(i / dir_every)·3]: dir_every = 1 gives a direction
 * per point, dir_every = samples per ray one per ray.
 *
 * Parameters: one float array (nerf_mlp_param_count), the hash table first (if any; nerf_mlp_hash_param_count
 * floats, for Adam's lazy range) then the layers in the order above, each W (out×in, row-major) then b.
 * Workspace: saved activations for max_points (nerf_mlp_ws_bytes; e.g. 8·256-wide trunk ≈ 9.5 KiB per point) and
 * per-thread scratch and gradient buffers.
 * Threads: forward and backward run an OpenMP team of n_threads over contiguous point ranges, rows in chunks of
 * NERF_MLP_CHUNK through sgemm (single-threaded inside the team); each thread accumulates into its own gradient
 * buffer and the buffers are summed in thread order: bitwise identical results for the same inputs, parameters
 * and thread count. The object is immutable after _new (thread-safe); a workspace serves one call at a time.
 * Errors: _new returns SCI_ECONFIG naming the field, -ENOMEM; forward/backward -EINVAL for n outside
 * 1 … max_points (or a backward without a forward); nothing else fails after _new.
 *
 * Usage:
 *     nerf_mlp_config cfg = nerf_mlp_config_scinerf();
 *     nerf_mlp *net;  nerf_mlp_ws *ws;
 *     nerf_mlp_new(&net, &cfg, &err);
 *     nerf_mlp_init(net, params, seed);
 *     nerf_mlp_ws_new(&ws, net, max_points, n_threads, &err);
 *     nerf_mlp_forward(net, params, ws, n, pos, dir, samples_per_ray, sigma, rgb);
 *     ... render, loss, render backward → d_sigma, d_rgb ...
 *     nerf_mlp_backward(net, params, ws, d_sigma, d_rgb, grad, d_pos, d_dir);
 */
#ifndef SCICAP_RECON_NERF_MLP_H
#define SCICAP_RECON_NERF_MLP_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "recon/nerf/act.h"
#include "recon/nerf/hashgrid.h"

#define NERF_MLP_MAX_DEPTH 16
#define NERF_MLP_CHUNK 512 /* rows per sgemm call inside a thread's range */

typedef enum nerf_mlp_pos_enc { NERF_MLP_POS_FREQ = 0, NERF_MLP_POS_HASH = 1 } nerf_mlp_pos_enc;
typedef enum nerf_mlp_dir_enc { NERF_MLP_DIR_FREQ = 0, NERF_MLP_DIR_SH = 1 } nerf_mlp_dir_enc;

typedef struct nerf_mlp_config {
    nerf_mlp_pos_enc pos_enc;
    int pos_freqs;             /* frequency encoding: 2^0 … 2^(K−1), 1 … 16 (SCINeRF 10) */
    nerf_hashgrid_config grid; /* hash encoding */
    int depth;                 /* trunk layers, 1 … 16 (SCINeRF 8) */
    int width;                 /* trunk width, 1 … 1024 (SCINeRF 256) */
    int skip;                  /* layer whose input also gets e (SCINeRF 4); −1: none; 1 … depth−1 */
    nerf_act density_act;      /* NERF_ACT_RELU or NERF_ACT_TRUNC_EXP */
    int feature_dim;           /* 1 … 1024 (SCINeRF 256) */
    nerf_mlp_dir_enc dir_enc;
    int dir_freqs;             /* 1 … 16 (SCINeRF 4) */
    int sh_degree;             /* 1 … 4 */
    int color_hidden;          /* 0 … 1024 (SCINeRF 128) */
    float aabb_min[3], aabb_max[3];
    float density_bias;
} nerf_mlp_config;

/* SCINeRF / nerf-pytorch: freq 10, 8 × 256 with the skip at 4, ReLU density, 256 features, freq 4 directions,
 * colour 128; aabb [−1, 1]³. */
nerf_mlp_config nerf_mlp_config_scinerf(void);
/* The fast variant: hash grid 16 × 2 (2^16 entries, 16 … 1024), 2 × 64, trunc_exp density, 15 features, SH 4,
 * colour 64. */
nerf_mlp_config nerf_mlp_config_hash(void);

typedef struct nerf_mlp nerf_mlp;
typedef struct nerf_mlp_ws nerf_mlp_ws;

int nerf_mlp_new(nerf_mlp **out, const nerf_mlp_config *cfg, sci_error *err);
void nerf_mlp_free(nerf_mlp *net);
const nerf_mlp_config *nerf_mlp_config_of(const nerf_mlp *net);
size_t nerf_mlp_param_count(const nerf_mlp *net);
size_t nerf_mlp_hash_param_count(const nerf_mlp *net); /* 0 for the frequency encoding */
const nerf_hashgrid *nerf_mlp_grid(const nerf_mlp *net); /* NULL for the frequency encoding */
int nerf_mlp_enc_dim(const nerf_mlp *net);               /* width of e */
int nerf_mlp_dir_dim(const nerf_mlp *net);               /* width of enc(d) */

/* Where each layer sits in the parameter array (floats). The trunk layer l has W at trunk_w[l], b at trunk_b[l]
 * and fan-in trunk_in[l]. wc1/bc1 are unused when color_hidden = 0. */
typedef struct nerf_mlp_layout {
    size_t hash, trunk_w[NERF_MLP_MAX_DEPTH], trunk_b[NERF_MLP_MAX_DEPTH];
    int trunk_in[NERF_MLP_MAX_DEPTH];
    size_t ws, bs, wf, bf, wc1, bc1, wc2, bc2, total;
} nerf_mlp_layout;
nerf_mlp_layout nerf_mlp_layout_of(const nerf_mlp *net);

/* Seeded init: hash U(±1e-4), ReLU layers Kaiming-uniform (gain √2), linear outputs gain 1, biases 0. */
void nerf_mlp_init(const nerf_mlp *net, float *params, uint64_t seed);

int nerf_mlp_ws_new(nerf_mlp_ws **out, const nerf_mlp *net, int max_points, int n_threads, sci_error *err);
void nerf_mlp_ws_free(nerf_mlp_ws *ws);
size_t nerf_mlp_ws_bytes(const nerf_mlp_ws *ws);
/* Saved floats per point (the memory that scales with the batch). */
size_t nerf_mlp_saved_floats_per_point(const nerf_mlp *net);

/* pos n×3, dir ceil(n/dir_every)×3 (unit vectors) → sigma (n), rgb (n×3); saves what the backward needs.
 * dir is borrowed: it must stay valid and unchanged until the backward on this ws. */
int nerf_mlp_forward(const nerf_mlp *net, const float *params, nerf_mlp_ws *ws, int n, const float *pos,
                     const float *dir, int dir_every, float *sigma, float *rgb);
/* After a forward on the same ws: d_sigma (n), d_rgb (n×3) (either NULL = 0) → grad (param_count, overwritten),
 * d_pos (n×3) and d_dir (ceil(n/dir_every)×3, summed over the points sharing a direction), each NULL to skip. */
int nerf_mlp_backward(const nerf_mlp *net, const float *params, nerf_mlp_ws *ws, const float *d_sigma,
                      const float *d_rgb, float *grad, float *d_pos, float *d_dir);

#endif
