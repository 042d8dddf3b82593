/* recon/nerf/block.c — I²R transformer block (see block.h). */
#include "recon/nerf/block.h"

#include <math.h>
#include <string.h>

#include "recon/nerf/act.h"
#include "recon/nerf/layernorm.h"
#include "recon/nerf/linear.h"

nerf_block_offsets nerf_block_layout(const nerf_block_shape *s)
{
    const size_t C = (size_t)s->att.C, Hf = (size_t)s->hidden;
    nerf_block_offsets o;
    size_t k = 0;
    o.ln1_g = k; k += C;
    o.ln1_b = k; k += C;
    o.w_qkv = k; k += 3 * C * C;
    o.b_qkv = k; k += 3 * C;
    o.w_o = k; k += C * C;
    o.b_o = k; k += C;
    o.ln2_g = k; k += C;
    o.ln2_b = k; k += C;
    o.w_1 = k; k += Hf * C;
    o.b_1 = k; k += Hf;
    o.w_2 = k; k += C * Hf;
    o.b_2 = k; k += C;
    o.gate = k; k += s->inter_gate ? (size_t)s->att.heads : 0;
    o.total = k;
    return o;
}

size_t nerf_block_saved_floats(const nerf_block_shape *s)
{
    const size_t C = (size_t)s->att.C;
    return C + 1 + 3 * C + 2 * (size_t)s->att.heads + C + C + 1 + 2 * (size_t)s->hidden;
}

void nerf_block_saved_bind(const nerf_block_shape *s, size_t rows, float *mem, nerf_block_saved *sv)
{
    const size_t C = (size_t)s->att.C;
    sv->xhat1 = mem; mem += rows * C;
    sv->rstd1 = mem; mem += rows;
    sv->qkv = mem; mem += rows * 3 * C;
    sv->lse = mem; mem += rows * 2 * (size_t)s->att.heads;
    sv->att = mem; mem += rows * C;
    sv->xhat2 = mem; mem += rows * C;
    sv->rstd2 = mem; mem += rows;
    sv->h = mem; mem += rows * (size_t)s->hidden;
    sv->dgelu = mem;
}

size_t nerf_block_scratch_floats(const nerf_block_shape *s, size_t rows)
{
    const size_t C = (size_t)s->att.C, Hf = (size_t)s->hidden;
    return rows * (C + Hf + C + 3 * C + C) + nerf_i2r_scratch_floats(&s->att);
}

void nerf_block_init(const nerf_block_shape *s, float *params, int depth, sci_rng *rng)
{
    const int C = s->att.C, Hf = s->hidden;
    nerf_block_offsets o = nerf_block_layout(s);
    for (int c = 0; c < C; c++) {
        params[o.ln1_g + c] = params[o.ln2_g + c] = 1.0f;
        params[o.ln1_b + c] = params[o.ln2_b + c] = 0.0f;
    }
    double res = 1.0 / sqrt(2.0 * (depth > 0 ? depth : 1));
    nerf_linear_init(C, 3 * C, params + o.w_qkv, params + o.b_qkv, 1.0, rng);
    nerf_linear_init(C, C, params + o.w_o, params + o.b_o, res, rng);
    nerf_linear_init(C, Hf, params + o.w_1, params + o.b_1, sqrt(2.0), rng);
    nerf_linear_init(Hf, C, params + o.w_2, params + o.b_2, res, rng);
    for (size_t h = o.gate; h < o.total; h++)
        params[h] = 0.0f;
}

/* The inter-ray channels [C/2, C) of the attention output as W_o reads them: v + g_h·(o − v) (block.h). */
static void gate_apply(const nerf_block_shape *s, const float *gate, int n, const float *qkv, const float *att,
                       float *og)
{
    const int C = s->att.C, half = C / 2, d = half / s->att.heads;
    for (size_t r = 0; r < (size_t)n; r++) {
        const float *v = qkv + r * 3 * C + 2 * C, *a = att + r * C;
        float *o = og + r * C;
        for (int c = 0; c < half; c++) o[c] = a[c];
        for (int h = 0; h < s->att.heads; h++) { /* one gate per head: no division per channel */
            const float g = gate[h];
            for (int c = half + h * d; c < half + (h + 1) * d; c++) o[c] = v[c] + g * (a[c] - v[c]);
        }
    }
}

/* Backward of gate_apply: dy (rows × C) holds ∂/∂og; on return its inter-ray channels hold ∂/∂o (g_h·dy), the
 * pass-through part (1 − g_h)·dy is in keep (same channels; the caller adds it to dv after the attention's
 * backward), and the gates' gradient is added to G_gate. */
static void gate_backward(const nerf_block_shape *s, const float *gate, int n, const float *qkv, const float *att,
                          float *dy, float *keep, float *G_gate)
{
    const int C = s->att.C, half = C / 2, H = s->att.heads, d = half / H;
    for (int h = 0; h < H; h++) {
        const int c0 = half + h * d;
        const float g = gate[h];
        double dg = 0.0;
        for (size_t r = 0; r < (size_t)n; r++) {
            const float *v = qkv + r * 3 * C + 2 * C, *a = att + r * C;
            float *t = dy + r * C, *k = keep + r * C;
            for (int c = c0; c < c0 + d; c++) {
                dg += (double)t[c] * (a[c] - v[c]);
                k[c] = (1.0f - g) * t[c];
                t[c] *= g;
            }
        }
        G_gate[h] += (float)dg;
    }
}

void nerf_block_forward(const nerf_block_shape *s, const float *P, int n_patches, size_t row0, const float *x,
                        float *out, const nerf_block_saved *sv, float *scratch)
{
    const int C = s->att.C, Hf = s->hidden, H = s->att.heads;
    const int n = n_patches * s->att.R * s->att.L;
    nerf_block_offsets o = nerf_block_layout(s);
    float *y = scratch, *att_scr = y + (size_t)n * C;
    const float *xr = x + row0 * C;
    float *outr = out + row0 * C;
    float *xhat1 = sv->xhat1 + row0 * C, *rstd1 = sv->rstd1 + row0, *qkv = sv->qkv + row0 * 3 * C;
    float *lse = sv->lse + row0 * 2 * H, *att = sv->att + row0 * C, *xhat2 = sv->xhat2 + row0 * C;
    float *rstd2 = sv->rstd2 + row0, *h = sv->h + row0 * Hf, *dgelu = sv->dgelu + row0 * Hf;

    nerf_layernorm_forward(n, C, P + o.ln1_g, P + o.ln1_b, xr, C, y, C, xhat1, rstd1);
    nerf_linear_forward(n, C, 3 * C, P + o.w_qkv, P + o.b_qkv, y, C, qkv, 3 * C);
    nerf_i2r_forward(&s->att, n_patches, qkv, 3 * C, att, C, lse, att_scr);
    memcpy(outr, xr, (size_t)n * C * sizeof *outr);
    const float *wo_in = att;
    if (s->inter_gate) { /* y (LN1's output) is spent: it holds the gated output until LN2 */
        gate_apply(s, P + o.gate, n, qkv, att, y);
        wo_in = y;
    }
    nerf_linear_forward_add(n, C, C, P + o.w_o, P + o.b_o, wo_in, C, outr, C);
    nerf_layernorm_forward(n, C, P + o.ln2_g, P + o.ln2_b, outr, C, y, C, xhat2, rstd2);
    nerf_linear_forward(n, C, Hf, P + o.w_1, P + o.b_1, y, C, h, Hf);
    nerf_act_gelu_with_grad((size_t)n * Hf, h, h, dgelu);
    nerf_linear_forward_add(n, Hf, C, P + o.w_2, P + o.b_2, h, Hf, outr, C);
}

void nerf_block_backward(const nerf_block_shape *s, const float *P, int n_patches, size_t row0,
                         const nerf_block_saved *sv, const float *d_out, float *d_in, float *G, float *scratch)
{
    const int C = s->att.C, Hf = s->hidden, H = s->att.heads;
    const int n = n_patches * s->att.R * s->att.L;
    nerf_block_offsets o = nerf_block_layout(s);
    float *y = scratch, *dh = y + (size_t)n * C, *dy = dh + (size_t)n * Hf;
    float *dqkv = dy + (size_t)n * C, *dx1 = dqkv + (size_t)n * 3 * C, *att_scr = dx1 + (size_t)n * C;
    const float *g = d_out + row0 * C;
    float *din = d_in + row0 * C;
    const float *xhat1 = sv->xhat1 + row0 * C, *rstd1 = sv->rstd1 + row0, *qkv = sv->qkv + row0 * 3 * C;
    const float *lse = sv->lse + row0 * 2 * H, *att = sv->att + row0 * C, *xhat2 = sv->xhat2 + row0 * C;
    const float *rstd2 = sv->rstd2 + row0, *h = sv->h + row0 * Hf, *dgelu = sv->dgelu + row0 * Hf;

    /* feed-forward branch; in place (d_in == d_out, as the network calls it) the gradient plane itself carries
     * dx1, saving two copies of n×C: g is last read by the FFN's linear backward, before dx1 changes */
    if (din == g) dx1 = din;
    else memcpy(dx1, g, (size_t)n * C * sizeof *dx1);
    nerf_layernorm_apply(n, C, P + o.ln2_g, P + o.ln2_b, xhat2, y, C);
    nerf_linear_backward(n, Hf, C, P + o.w_2, h, Hf, g, C, dh, Hf, 0, G + o.w_2, G + o.b_2);
    for (size_t i = 0; i < (size_t)n * Hf; i++) dh[i] *= dgelu[i];
    nerf_linear_backward(n, C, Hf, P + o.w_1, y, C, dh, Hf, dy, C, 0, G + o.w_1, G + o.b_1);
    nerf_layernorm_backward(n, C, P + o.ln2_g, xhat2, rstd2, dy, C, dx1, C, 1, G + o.ln2_g, G + o.ln2_b);
    /* attention branch */
    if (s->inter_gate) {
        gate_apply(s, P + o.gate, n, qkv, att, y); /* W_o's input, recomputed into y (spent after W_1) */
        nerf_linear_backward(n, C, C, P + o.w_o, y, C, dx1, C, dy, C, 0, G + o.w_o, G + o.b_o);
        gate_backward(s, P + o.gate, n, qkv, att, dy, y, G + o.gate);
    } else {
        nerf_linear_backward(n, C, C, P + o.w_o, att, C, dx1, C, dy, C, 0, G + o.w_o, G + o.b_o);
    }
    nerf_i2r_backward(&s->att, n_patches, qkv, 3 * C, att, C, lse, dy, C, dqkv, 3 * C, att_scr);
    if (s->inter_gate) /* the pass-through's share reaches v directly */
        for (size_t r = 0; r < (size_t)n; r++)
            for (int c = C / 2; c < C; c++)
                dqkv[r * 3 * C + 2 * C + c] += y[r * C + c];
    nerf_layernorm_apply(n, C, P + o.ln1_g, P + o.ln1_b, xhat1, y, C);
    nerf_linear_backward(n, C, 3 * C, P + o.w_qkv, y, C, dqkv, 3 * C, dy, C, 0, G + o.w_qkv, G + o.b_qkv);
    nerf_layernorm_backward(n, C, P + o.ln1_g, xhat1, rstd1, dy, C, dx1, C, 1, G + o.ln1_g, G + o.ln1_b);
    if (dx1 != din) memcpy(din, dx1, (size_t)n * C * sizeof *din);
}
