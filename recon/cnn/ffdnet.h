/* recon/cnn/ffdnet.h — the FFDNet denoiser (Zhang, Zuo, Zhang, IEEE TIP 2018; the IPOL implementation of
 * M. Tassano whose trained weights PnP-SCI uses), for inference on the CPU.
 *
 *     cnn_ffdnet *net;   cnn_ffdnet_load("net_gray.pth", &net, &err);        // grey or colour, from the shapes
 *     cnn_ffdnet_plan *p; cnn_ffdnet_plan_new(net, w, h, threads, &p, &err); // buffers for one image size
 *     cnn_ffdnet_denoise(p, noisy, 25 / 255.0f, clean);                      // planar c × h × w, any number of times
 *     cnn_ffdnet_plan_free(p); cnn_ffdnet_free(net);
 *
 * The network: the image (c = 1 grey or 3 colour channels, values on [0, 1]) is split into its four 2×2 phases
 * (pixel unshuffle: channel 4·ch + k holds colour ch at row offset k/2, column offset k%2), a noise map of c
 * channels filled with σ is put in front, and L 3×3 convolutions of F features (ReLU after each but the last,
 * batch norm folded into the convolutions at load) estimate the noise, which is shuffled back and subtracted:
 * denoised = x − net(x, σ), not clamped (PnP-SCI's use). Grey: F = 64, L = 15; colour: F = 96, L = 12. Odd sizes
 * are padded by repeating the last row or column and cropped back, as the reference does.
 *
 * Weights: a PyTorch state dict in the legacy serialisation (recon/cnn/weights.h), keys
 * [module.]intermediate_dncnn.itermediate_dncnn.<i>.{weight,bias,running_mean,running_var}. A missing tensor or
 * one of the wrong shape is refused with the file and the tensor named.
 *
 * σ is on the image's [0, 1] scale (25/255 for the reference's "25"). A network is immutable after loading and
 * may be shared; a plan holds the buffers of one run and is used by one thread at a time (its run is threaded
 * inside, by OpenMP). Errors: negative codes with a message; nothing prints.
 */
#ifndef SCICAP_RECON_CNN_FFDNET_H
#define SCICAP_RECON_CNN_FFDNET_H

#include <stddef.h>

#include "base/error.h"

typedef struct cnn_ffdnet cnn_ffdnet;
typedef struct cnn_ffdnet_plan cnn_ffdnet_plan;

int cnn_ffdnet_load(const char *path, cnn_ffdnet **out, sci_error *err);
void cnn_ffdnet_free(cnn_ffdnet *net);
/* 1 (grey) or 3 (colour). */
int cnn_ffdnet_channels(const cnn_ffdnet *net);
/* Convolution layers and features, for messages. */
int cnn_ffdnet_layers(const cnn_ffdnet *net);
int cnn_ffdnet_features(const cnn_ffdnet *net);
/* Multiply-adds of one pass over a w × h image (for GFLOP/s figures). */
double cnn_ffdnet_macs(const cnn_ffdnet *net, int w, int h);

/* Buffers for w × h images (w, h ≥ 1), `threads` OpenMP threads (≤ 0: omp_get_max_threads()). The plan borrows
 * net, which must outlive it. */
int cnn_ffdnet_plan_new(const cnn_ffdnet *net, int w, int h, int threads, cnn_ffdnet_plan **out, sci_error *err);
void cnn_ffdnet_plan_free(cnn_ffdnet_plan *p);
/* on = 1: the convolutions' products through OpenBLAS even where the AVX-512 kernel would run (cnn_conv_ws_portable). */
void cnn_ffdnet_plan_portable(cnn_ffdnet_plan *p, int on);
/* What computes the convolutions (for reports). */
const char *cnn_ffdnet_plan_kernel(const cnn_ffdnet_plan *p);
/* Bytes the plan holds (activations and scratch). */
size_t cnn_ffdnet_plan_bytes(const cnn_ffdnet_plan *p);

/* out = in − net(in, sigma): planar c × h × w floats, row stride w. in == out is allowed. No allocation. */
void cnn_ffdnet_denoise(cnn_ffdnet_plan *p, const float *in, float sigma, float *out);

#endif
