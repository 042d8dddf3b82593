/* recon/nerf/act.h — elementwise activations with forward and backward.
 *
 * Every function works on n contiguous floats; forward writes y (may alias x), backward writes dx (may alias dy)
 * from the forward's *input* x (or output y where named) and the upstream gradient dy. Pure functions of their
 * arguments: reentrant and thread-safe on disjoint outputs; the caller splits rows between threads.
 *
 *   relu      y = max(x, 0)                       dy·[x > 0]
 *   gelu      y = x·Φ(x) (erf form)               dy·(Φ(x) + x·φ(x))          erf to 3e-7 absolute (fastmath.h)
 *   softplus  y = log(1 + e^x), = x above 20      dy·sigmoid(x)
 *   trunc_exp y = exp(min(x, 88))                 dy·exp(clamp(x, −15, 15))   (instant-ngp / torch-ngp density)
 *   sigmoid   y = 1/(1 + e^−x)                    dy·y·(1 − y)                backward takes the output y
 */
#ifndef SCICAP_RECON_NERF_ACT_H
#define SCICAP_RECON_NERF_ACT_H

#include <stddef.h>

typedef enum nerf_act {
    NERF_ACT_NONE = 0,
    NERF_ACT_RELU,
    NERF_ACT_GELU,
    NERF_ACT_SOFTPLUS,
    NERF_ACT_TRUNC_EXP,
    NERF_ACT_SIGMOID,
} nerf_act;

/* Clamp of the trunc_exp backward (instant-ngp nerf_device.cuh; torch-ngp activation.py). */
#define NERF_TRUNC_EXP_CLAMP 15.0f

void nerf_act_forward(nerf_act a, size_t n, const float *x, float *y);
/* x: the forward input; y: the forward output (only sigmoid reads it; may be NULL for the others). */
void nerf_act_backward(nerf_act a, size_t n, const float *x, const float *y, const float *dy, float *dx);
/* GELU and its derivative in one pass (one exp and one division per element, shared by erf and the density):
 * y = GELU(x), dydx = Φ(x) + x·φ(x). y may alias x. For layers that keep dydx instead of recomputing GELU in
 * the backward. */
void nerf_act_gelu_with_grad(size_t n, const float *x, float *y, float *dydx);
/* Name for printouts ("relu", ...). */
const char *nerf_act_name(nerf_act a);

#endif
