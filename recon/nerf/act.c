/* recon/nerf/act.c — elementwise activations (see act.h). */
/* Loops over nerf_expf/nerf_erff vectorise only when comparisons may be if-converted; this changes no value
 * (IEEE results are the same), it only lets gcc assume no FP trap is enabled (the project never enables one). */
#pragma GCC optimize("no-trapping-math")

#include "recon/nerf/act.h"

#include <math.h>

#include "recon/nerf/fastmath.h"

#define INV_SQRT2 0.70710678118654752440f
/* clang before 16 exports a target_clones function as NAME.ifunc, which other files' calls do not link to
 * (the fuzzers are built with clang): a single version there */
#if defined(__clang__) && __clang_major__ < 16
#define CLONES
#else
#define CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#endif
#define INV_SQRT2PI 0.39894228040143267794f

CLONES void nerf_act_forward(nerf_act a, size_t n, const float *x, float *y)
{
    switch (a) {
    case NERF_ACT_NONE:
        if (y != x) memcpy(y, x, n * sizeof *y);
        break;
    case NERF_ACT_RELU:
#pragma omp simd
        for (size_t i = 0; i < n; i++) y[i] = x[i] > 0.0f ? x[i] : 0.0f;
        break;
    case NERF_ACT_GELU:
#pragma omp simd
        for (size_t i = 0; i < n; i++) y[i] = 0.5f * x[i] * (1.0f + nerf_erff(x[i] * INV_SQRT2));
        break;
    case NERF_ACT_SOFTPLUS:
        for (size_t i = 0; i < n; i++) y[i] = x[i] > 20.0f ? x[i] : log1pf(expf(x[i]));
        break;
    case NERF_ACT_TRUNC_EXP:
        for (size_t i = 0; i < n; i++) y[i] = expf(x[i] < 88.0f ? x[i] : 88.0f);
        break;
    case NERF_ACT_SIGMOID:
        for (size_t i = 0; i < n; i++) y[i] = 1.0f / (1.0f + expf(-x[i]));
        break;
    }
}

CLONES void nerf_act_backward(nerf_act a, size_t n, const float *x, const float *y, const float *dy, float *dx)
{
    switch (a) {
    case NERF_ACT_NONE:
        if (dx != dy) memcpy(dx, dy, n * sizeof *dx);
        break;
    case NERF_ACT_RELU:
#pragma omp simd
        for (size_t i = 0; i < n; i++) dx[i] = x[i] > 0.0f ? dy[i] : 0.0f;
        break;
    case NERF_ACT_GELU:
#pragma omp simd
        for (size_t i = 0; i < n; i++) {
            float cdf = 0.5f * (1.0f + nerf_erff(x[i] * INV_SQRT2));
            float pdf = INV_SQRT2PI * nerf_expf(-0.5f * x[i] * x[i]);
            dx[i] = dy[i] * (cdf + x[i] * pdf);
        }
        break;
    case NERF_ACT_SOFTPLUS:
        for (size_t i = 0; i < n; i++) dx[i] = dy[i] / (1.0f + expf(-x[i]));
        break;
    case NERF_ACT_TRUNC_EXP:
        for (size_t i = 0; i < n; i++) {
            float c = x[i] < -NERF_TRUNC_EXP_CLAMP ? -NERF_TRUNC_EXP_CLAMP
                      : (x[i] > NERF_TRUNC_EXP_CLAMP ? NERF_TRUNC_EXP_CLAMP : x[i]);
            dx[i] = dy[i] * expf(c);
        }
        break;
    case NERF_ACT_SIGMOID:
        for (size_t i = 0; i < n; i++) dx[i] = dy[i] * y[i] * (1.0f - y[i]);
        break;
    }
}

CLONES void nerf_act_gelu_with_grad(size_t n, const float *x, float *y, float *dydx)
{
#pragma omp simd
    for (size_t i = 0; i < n; i++) {
        /* nerf_erff(z) spelled out so that its exp(−z²) = exp(−x²/2) also gives the normal density */
        float xi = x[i], z = xi * INV_SQRT2, az = z < 0.0f ? -z : z;
        float t = 1.0f / (1.0f + 0.3275911f * az);
        float poly = t * (0.254829592f + t * (-0.284496736f + t * (1.421413741f + t * (-1.453152027f + t * 1.061405429f))));
        float e = nerf_expf(-az * az);
        float erf = 1.0f - poly * e;
        erf = z < 0.0f ? -erf : erf;
        float cdf = 0.5f * (1.0f + erf);
        y[i] = 0.5f * xi * (1.0f + erf);
        dydx[i] = cdf + xi * (INV_SQRT2PI * e);
    }
}

const char *nerf_act_name(nerf_act a)
{
    switch (a) {
    case NERF_ACT_NONE: return "none";
    case NERF_ACT_RELU: return "relu";
    case NERF_ACT_GELU: return "gelu";
    case NERF_ACT_SOFTPLUS: return "softplus";
    case NERF_ACT_TRUNC_EXP: return "trunc_exp";
    case NERF_ACT_SIGMOID: return "sigmoid";
    }
    return "?";
}
