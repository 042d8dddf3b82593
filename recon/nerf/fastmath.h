/* recon/nerf/fastmath.h — vectorisable exp and erf for the NeRF kernels.
 *
 * Why: glibc's expf/erff are scalar calls; attention softmax and GELU call them ~10^8 times per training step
 * and without -ffast-math gcc cannot vectorise them. These are plain arithmetic, so loops over them vectorise
 * under `#pragma omp simd`, and they give bitwise identical results on every run (no table, no state).
 *
 * nerf_expf: |relative error| <= 2e-7 (about 2 ulp) on [-87.3, 88.3]; returns 0 below -87.3 and e^88.3 above
 * 88.3 (callers never feed larger values: softmax arguments are <= 0, trunc_exp clamps first). NaN propagates.
 * nerf_erff: Abramowitz–Stegun 7.1.26 with the exp above, |absolute error| <= 3e-7.
 */
#ifndef SCICAP_RECON_NERF_FASTMATH_H
#define SCICAP_RECON_NERF_FASTMATH_H

#include <stdint.h>
#include <string.h>

#pragma omp declare simd
static inline float nerf_expf(float x)
{
    const float lo = -87.3f, hi = 88.3f;
    float xc = x < lo ? lo : (x > hi ? hi : x);
    /* round-to-nearest by the 1.5·2^23 trick (SSE2 has no roundps) */
    float n = (xc * 1.44269504088896341f + 12582912.0f) - 12582912.0f;
    float r = xc - n * 0.693145751953125f;   /* ln2 split into hi + lo for an exact product */
    r = r - n * 1.42860682030941723212e-6f;
    float p = 1.0f / 720.0f;
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    int32_t bits = (int32_t)((uint32_t)((int32_t)n + 127) << 23); /* unsigned shift: a negative left shift is UB */
    float s;
    memcpy(&s, &bits, sizeof s);
    float y = p * s;
    y = x < lo ? 0.0f : y;
    return x != x ? x : y;
}

#pragma omp declare simd
static inline float nerf_erff(float x)
{
    float ax = x < 0.0f ? -x : x;
    float t = 1.0f / (1.0f + 0.3275911f * ax);
    float poly = t * (0.254829592f + t * (-0.284496736f + t * (1.421413741f + t * (-1.453152027f + t * 1.061405429f))));
    float y = 1.0f - poly * nerf_expf(-ax * ax);
    return x < 0.0f ? -y : y;
}

#endif
