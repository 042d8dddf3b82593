/* recon/cnn/conv.h — 3×3 convolution layers for inference (stride 1, zero padding 1, as PyTorch's
 * Conv2d(kernel_size=3, padding=1)), with an optional per-channel bias and ReLU; planned once per image size,
 * executed without allocation.
 *
 *     cnn_conv *c;  cnn_conv_new(cin, cout, w, bias, CNN_RELU, &c, &err);  // weights copied; U = G g Gᵀ here
 *     cnn_act in, out;  cnn_act_init(&in, cin, h, wd, NULL) ... (caller allocates cnn_act_bytes)
 *     cnn_conv_ws *ws = cnn_conv_ws_new(cmax, threads);           // per-thread scratch, reused by every layer
 *     cnn_conv_run(c, &in, &out, ws);                             // out = relu(conv(in) + bias)
 *
 * Algorithm: Winograd F(4×4, 3×3) (Lavin & Gray 2016): each 4×4 output tile costs 36 products per input/output
 * channel pair instead of 144, and the products of all tiles of a block are 36 dense matrix products
 * U[ξ] (cout × cin) · V[ξ] (cin × tiles) through cblas_sgemm. Transforms in float; the weight transform in double.
 * On [0,1] images through FFDNet's 15 layers the result stays within 1e-5 of PyTorch's direct convolution
 * (tests/unit/test_cnn_ffdnet.c compares against PyTorch's outputs). cnn_conv_reference is the plain direct
 * convolution, for tests.
 *
 * Activations (cnn_act) are planar: c planes of h × w valid values, each stored in a frame of hs × ws floats with
 * the valid data at row 1, column 1 and zeros around it, sized so that every 6 × 6 input patch of a 4 × 4 tile lies
 * inside the frame: hs = 4⌈h/4⌉ + 2, ws = 4⌈w/4⌉ + 2. A layer writes only the valid values of its output, so a
 * zeroed output frame keeps its border zero for the next layer.
 *
 * Threading: cnn_conv_run splits the tiles into blocks over OpenMP threads; each thread uses its own scratch of
 * `ws` and calls sgemm single-threaded (call cnn_blas_single_thread() once: Debian's OpenBLAS is the pthread
 * build). Layers are immutable after cnn_conv_new and may be shared by threads; a workspace is used by one run at
 * a time.
 *
 * Errors: -EINVAL for bad sizes, -ENOMEM; the message names the layer's shape. cnn_*_free(NULL) is harmless.
 */
#ifndef SCICAP_RECON_CNN_CONV_H
#define SCICAP_RECON_CNN_CONV_H

#include <stddef.h>

#include "base/error.h"

typedef struct cnn_act {
    int c, h, w;   /* channels, valid rows and columns */
    int hs, ws;    /* stored rows and row stride of one plane */
    size_t plane;  /* hs · ws floats */
    float *data;   /* c planes, borrowed (the caller allocates cnn_act_floats(c, h, w) floats, zeroed) */
} cnn_act;

/* Floats an activation of c × h × w needs (with its border). */
size_t cnn_act_floats(int c, int h, int w);
/* Fill the geometry of `a` for c × h × w over `data` (borrowed; zeroed by the caller). */
void cnn_act_init(cnn_act *a, int c, int h, int w, float *data);
/* The valid value (channel k, row y, column x). */
static inline float *cnn_act_at(const cnn_act *a, int k, int y, int x)
{
    return a->data + (size_t)k * a->plane + (size_t)(y + 1) * a->ws + (x + 1);
}

enum { CNN_LINEAR = 0, CNN_RELU = 1 };

typedef struct cnn_conv cnn_conv;
typedef struct cnn_conv_ws cnn_conv_ws;

/* A layer of cout × cin × 3 × 3 weights (PyTorch's order), bias of cout values (NULL: none), activation
 * CNN_LINEAR or CNN_RELU. Copies what it needs. */
int cnn_conv_new(int cin, int cout, const float *weight, const float *bias, int activation, cnn_conv **out,
                 sci_error *err);
void cnn_conv_free(cnn_conv *c);
int cnn_conv_cin(const cnn_conv *c);
int cnn_conv_cout(const cnn_conv *c);

/* Scratch for layers of up to `cmax` channels in or out, for `threads` threads (the OpenMP team of the run). */
cnn_conv_ws *cnn_conv_ws_new(int cmax, int threads);
void cnn_conv_ws_free(cnn_conv_ws *ws);
/* on = 1: the tile products through cblas_sgemm even where the AVX-512 kernel would run (chosen at run time by
 * the CPU); both paths give the same results within float rounding. */
void cnn_conv_ws_portable(cnn_conv_ws *ws, int on);
/* What computes the products for this workspace: for reports. */
const char *cnn_conv_kernel(const cnn_conv_ws *ws);

/* out = act(conv(in) + bias). in: cin channels; out: cout channels of the same h × w, border zero; in ≠ out. */
void cnn_conv_run(const cnn_conv *c, const cnn_act *in, cnn_act *out, cnn_conv_ws *ws);
/* The same by the direct definition, in double: slow, for tests. */
void cnn_conv_reference(const cnn_conv *c, const cnn_act *in, cnn_act *out);

/* OpenBLAS to one thread (a process-wide setting of the library; the layers thread by tiles). */
void cnn_blas_single_thread(void);

#endif
