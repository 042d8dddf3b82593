/* recon/nerf/posenc.c — frequency encoding (see posenc.h). */
#include "recon/nerf/posenc.h"

#include <math.h>
#include <stddef.h>

void nerf_posenc_forward(int n, int D, int K, int include_input, const float *x, float *y, int ldy)
{
    for (int i = 0; i < n; i++) {
        const float *xi = x + (size_t)i * D;
        float *yi = y + (size_t)i * ldy;
        int o = 0;
        if (include_input)
            for (int d = 0; d < D; d++) yi[o++] = xi[d];
        for (int k = 0; k < K; k++) {
            double f = ldexp(1.0, k);
            for (int d = 0; d < D; d++) yi[o + d] = (float)sin(f * xi[d]);
            for (int d = 0; d < D; d++) yi[o + D + d] = (float)cos(f * xi[d]);
            o += 2 * D;
        }
    }
}

void nerf_posenc_backward(int n, int D, int K, int include_input, const float *x, const float *dy, int lddy,
                          float *dx, int accumulate)
{
    for (int i = 0; i < n; i++) {
        const float *xi = x + (size_t)i * D, *gi = dy + (size_t)i * lddy;
        for (int d = 0; d < D; d++) {
            double g = include_input ? gi[d] : 0.0;
            int o = include_input ? D : 0;
            for (int k = 0; k < K; k++) {
                double f = ldexp(1.0, k);
                g += f * (cos(f * xi[d]) * gi[o + d] - sin(f * xi[d]) * gi[o + D + d]);
                o += 2 * D;
            }
            dx[(size_t)i * D + d] = accumulate ? dx[(size_t)i * D + d] + (float)g : (float)g;
        }
    }
}
