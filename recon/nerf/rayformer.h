/* recon/nerf/rayformer.h — the RayFormer network (the RayFormer paper): hash grid + SH directions + I²R transformer
 * blocks → density and geometry features → colour head on [geometry, SH(dir)].
 *
 *   u   = (x − aabb_min)/(aabb_max − aabb_min)           x: sample position (world units), clamped to [0, 1]³
 *   h₀  = hashgrid(u)                                    L·F = width channels
 *   h_b = block_b(h_{b−1}),  b = 1 … n_blocks            I²R-MSA + FFN, pre-norm (block.h)
 *   [s, geo] = W_h·LN_f(h_B) + b_h                       1 + geo_dim outputs (head_hidden = 0, the paper's FC)
 *   [s, geo] = W_h·ReLU(W_h1·LN_f(h_B) + b_h1) + b_h     head_hidden > 0: a hidden layer first
 *   σ   = trunc_exp(s + density_bias)                    (act.h: backward clamped at ±15)
 *   rgb = sigmoid(MLP([geo, SH₄(d)]))                    ReLU hidden layer of color_hidden (0: a single FC layer)
 *
 * Batches are whole patches: patch p, ray r = y·patch_w + x, sample s at point (p·R + r)·L + s, R = patch_w·
 * patch_h, L = samples; one direction per ray (unit vector, world frame). Poses of one snapshot are just more
 * patches.
 *
 * Usage (with the trainer, recon/nerf/trainer.h):
 *     nerf_rayformer *net;  nerf_rayformer_ws *ws;
 *     nerf_rayformer_new(&net, &cfg, &err);
 *     float *params = malloc(nerf_rayformer_param_count(net) * 4), *grad = ...same size...;
 *     nerf_rayformer_init(net, params, seed);
 *     nerf_rayformer_ws_new(&ws, net, max_patches, n_threads, &err);
 *     nerf_rayformer_forward(net, params, ws, n_patches, pos, dir, sigma, rgb);
 *     ... render, loss, render backward → d_sigma, d_rgb ...
 *     nerf_rayformer_backward(net, params, ws, d_sigma, d_rgb, grad, d_pos, d_dir);
 *     adam step: [0, hash_params) lazy without decay, the rest with (nerf_rayformer_hash_param_count).
 *
 * Parameters: one float array; the hash table first, then the blocks, the final LN, the head and the colour MLP.
 * Workspace: activations for max_patches (nerf_rayformer_ws_bytes) and one gradient slice per group of patches for
 * the parameters after the hash table (~75 KB each for the default network).
 * Threads: forward/backward run an OpenMP team of n_threads. The hash encoding is split by level (levels write
 * disjoint columns and, backward, disjoint slices of the table gradient, points in order); the rest of the network
 * takes groups of patches of about 1024 rows (8 patches of 2 × 2 rays × 32 samples, one of 8 × 8 × 32)
 * dynamically, so a thread whose core is shared with another job takes less work. Each group writes its own
 * gradient slice, summed in group order: bitwise identical results for the same inputs whatever the thread count
 * and schedule (the grouping depends only on the patch shape). Both set OpenBLAS to one thread (its pthread pool
 * would oversubscribe inside the team).
 * The network object is immutable after _new (thread-safe); a workspace serves one call at a time.
 * Errors: -EINVAL for n_patches outside 1 … max_patches; nothing else fails after _new.
 */
#ifndef SCICAP_RECON_NERF_RAYFORMER_H
#define SCICAP_RECON_NERF_RAYFORMER_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "recon/nerf/hashgrid.h"

typedef struct nerf_rayformer_config {
    nerf_hashgrid_config grid; /* n_levels·n_features must equal width */
    int width;                 /* C, 32 */
    int n_blocks;              /* 2 */
    int heads;                 /* per attention path, 2 (C/2 divisible by heads) */
    int ffn_hidden;            /* 64 */
    int geo_dim;               /* 15 */
    int sh_degree;             /* 1 … 4 (4: 16 outputs) */
    int color_hidden;          /* 32; 0: colour is one FC layer */
    int patch_w, patch_h;      /* 8 × 8 rays per patch */
    int samples;               /* L, samples per ray, 32 */
    float aabb_min[3], aabb_max[3];
    float density_bias;        /* added before trunc_exp */
    int intra_ray, inter_ray;  /* 1: the attention path; 0: pass-through (o = V, per point) — the paper's ablation */
    float intra_slope;         /* intra-ray distance bias (attention.h; 0: none, the paper's attention) */
    float inter_slope;         /* inter-ray distance bias over pixel offsets in the window (attention.h; 0: none;
                                  > 0 needs patch_w a power of two) */
    int head_hidden;           /* 0: density and geometry from one FC layer on LN_f(h) (the paper); > 0: a ReLU
                                  hidden layer of this width first, as SCINeRF's density MLP (the recipe: with the
                                  blocks starting as the identity, one FC layer on normalised hash features fits
                                  slower per point than SCINeRF's field) */
    int final_norm;            /* 1: LN_f before the head (pre-norm transformers, the default); 0: the head reads h_B
                                  as it is, as SCINeRF's MLP reads the hash features */
    int zero_gates;            /* init: 1 zeroes each block's attention and FFN output projections, so every block
                                  starts as the identity and mixes rays only as far as that lowers the loss */
    int inter_gate;            /* 1: a learned gate per inter-ray head, 0 at init, between the path's pass-through
                                  and its attention (block.h); needs inter_ray (ignored without). 0 here, 1 in
                                  the solver's defaults (rayformer_solve.c) */
} nerf_rayformer_config;

/* The defaults named above; the grid: 16 levels × 2 features, 2^16 entries, resolution 16 … 1024; aabb [−1, 1]³;
 * both attention paths on. */
nerf_rayformer_config nerf_rayformer_config_default(void);

typedef struct nerf_rayformer nerf_rayformer;
typedef struct nerf_rayformer_ws nerf_rayformer_ws;

int nerf_rayformer_new(nerf_rayformer **out, const nerf_rayformer_config *cfg, sci_error *err);
void nerf_rayformer_free(nerf_rayformer *net);
const nerf_rayformer_config *nerf_rayformer_config_of(const nerf_rayformer *net);
size_t nerf_rayformer_param_count(const nerf_rayformer *net);
size_t nerf_rayformer_hash_param_count(const nerf_rayformer *net); /* the first this many params are the table */
const nerf_hashgrid *nerf_rayformer_grid(const nerf_rayformer *net);
/* Where each part sits in the parameter array (floats). wc1/bc1 are unused when color_hidden = 0, wh1/bh1 when
 * head_hidden = 0. */
typedef struct nerf_rayformer_layout {
    size_t hash, block[8], lnf_g, lnf_b, wh1, bh1, wh, bh, wc1, bc1, wc2, bc2, total;
} nerf_rayformer_layout;
nerf_rayformer_layout nerf_rayformer_layout_of(const nerf_rayformer *net);
/* Seeded initialisation (hash U(±1e-4), linear Kaiming-uniform, LN identity, zero biases). */
void nerf_rayformer_init(const nerf_rayformer *net, float *params, uint64_t seed);

int nerf_rayformer_ws_new(nerf_rayformer_ws **out, const nerf_rayformer *net, int max_patches, int n_threads,
                          sci_error *err);
void nerf_rayformer_ws_free(nerf_rayformer_ws *ws);
size_t nerf_rayformer_ws_bytes(const nerf_rayformer_ws *ws);

/* Coarse-to-fine (BARF's ramp over hash levels, docs/conventions.md §14): level l's features are multiplied by
 * (1 − cos(π·clamp(alpha − l, 0, 1)))/2 in this workspace's forward and backward; alpha >= n_levels (the default
 * after _ws_new) uses every level fully. Values below 1 are taken as 1 (level 0 always on). */
void nerf_rayformer_ws_set_levels(nerf_rayformer_ws *ws, double alpha);

/* pos: N×3 (N = n_patches·R·L), dir: n_patches·R × 3. Writes sigma (N) and rgb (N×3); saves what the backward
 * needs in ws. */
int nerf_rayformer_forward(const nerf_rayformer *net, const float *params, nerf_rayformer_ws *ws, int n_patches,
                           const float *pos, const float *dir, float *sigma, float *rgb);
/* After a forward on the same ws: d_sigma (N), d_rgb (N×3) → grad (param_count, overwritten), d_pos (N×3) and
 * d_dir (n_patches·R × 3), each NULL to skip. */
int nerf_rayformer_backward(const nerf_rayformer *net, const float *params, nerf_rayformer_ws *ws,
                            const float *d_sigma, const float *d_rgb, float *grad, float *d_pos, float *d_dir);

#endif
