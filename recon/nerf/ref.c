/* recon/nerf/ref.c — double reference forwards (see ref.h). */
#include "recon/nerf/ref.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "recon/nerf/shenc.h"

void nerf_ref_hashgrid_forward(const nerf_hashgrid *g, const double *table, int n, const double *x, double *y)
{
    static const uint32_t PR[3] = {1u, 2654435761u, 805459861u};
    const nerf_hashgrid_config *cf = nerf_hashgrid_config_of(g);
    const int L = cf->n_levels, F = cf->n_features, D = L * F;
    const uint64_t T = (uint64_t)1 << cf->log2_table;
    for (int i = 0; i < n; i++) {
        size_t off = 0;
        for (int l = 0; l < L; l++) {
            double scale;
            uint64_t res;
            size_t e;
            int dense;
            nerf_hashgrid_level(g, l, &scale, &res, &e, &dense);
            uint32_t cell[3];
            double fr[3];
            for (int d = 0; d < 3; d++) {
                double xd = x[3 * i + d];
                xd = xd < 0 ? 0 : (xd > 1 ? 1 : xd);
                double p = scale * xd + 0.5, fl = floor(p);
                cell[d] = (uint32_t)fl;
                fr[d] = p - fl;
            }
            for (int f = 0; f < F; f++) y[(size_t)i * D + l * F + f] = 0.0;
            for (int k = 0; k < 8; k++) {
                uint32_t q[3];
                double w = 1.0;
                for (int d = 0; d < 3; d++) {
                    int bit = (k >> d) & 1;
                    q[d] = cell[d] + (uint32_t)bit;
                    w *= bit ? fr[d] : 1.0 - fr[d];
                }
                uint64_t id = dense ? (uint64_t)q[0] + (uint64_t)q[1] * res + (uint64_t)q[2] * res * res
                                    : (uint64_t)((q[0] * PR[0]) ^ (q[1] * PR[1]) ^ (q[2] * PR[2])) & (T - 1);
                for (int f = 0; f < F; f++) y[(size_t)i * D + l * F + f] += w * table[(off + id) * F + f];
            }
            off += e;
        }
    }
}

void nerf_ref_layernorm(int n, int C, const double *gamma, const double *beta, const double *x, double *y)
{
    for (int i = 0; i < n; i++) {
        double mu = 0, v = 0;
        for (int c = 0; c < C; c++) mu += x[(size_t)i * C + c];
        mu /= C;
        for (int c = 0; c < C; c++) v += (x[(size_t)i * C + c] - mu) * (x[(size_t)i * C + c] - mu);
        double r = 1.0 / sqrt(v / C + 1e-5);
        for (int c = 0; c < C; c++) y[(size_t)i * C + c] = (x[(size_t)i * C + c] - mu) * r * gamma[c] + beta[c];
    }
}

void nerf_ref_linear(int n, int in, int out, const double *W, const double *b, const double *x, double *y)
{
    for (int i = 0; i < n; i++)
        for (int o = 0; o < out; o++) {
            double s = b ? b[o] : 0.0;
            for (int k = 0; k < in; k++) s += W[(size_t)o * in + k] * x[(size_t)i * in + k];
            y[(size_t)i * out + o] = s;
        }
}

double nerf_ref_gelu(double x) { return 0.5 * x * (1.0 + erf(x / sqrt(2.0))); }

/* Tokens in raster order in rows ww wide; the bias is −slope × the city-block distance. */
static void ref_group(int n, int d, size_t base, size_t stride, int c0, int C, double slope, int ww,
                      const double *qkv, double *o)
{
    double *p = malloc((size_t)n * sizeof *p);
    for (int i = 0; i < n; i++) {
        const double *q = qkv + (base + (size_t)i * stride) * 3 * C + c0;
        double m = -INFINITY;
        for (int j = 0; j < n; j++) {
            const double *k = qkv + (base + (size_t)j * stride) * 3 * C + C + c0;
            double s = 0;
            for (int c = 0; c < d; c++) s += q[c] * k[c];
            p[j] = s / sqrt((double)d) - slope * (abs(i % ww - j % ww) + abs(i / ww - j / ww));
            m = p[j] > m ? p[j] : m;
        }
        double sum = 0;
        for (int j = 0; j < n; j++) sum += (p[j] = exp(p[j] - m));
        for (int c = 0; c < d; c++) {
            double s = 0;
            for (int j = 0; j < n; j++) s += p[j] * qkv[(base + (size_t)j * stride) * 3 * C + 2 * C + c0 + c];
            o[(base + (size_t)i * stride) * C + c0 + c] = s / sum;
        }
    }
    free(p);
}

void nerf_ref_i2r_forward(const nerf_i2r_shape *s, int n_patches, const double *qkv, double *o)
{
    const int C = s->C, H = s->heads, L = s->L, R = s->R, d = C / (2 * H);
    for (int pa = 0; pa < n_patches; pa++) {
        size_t p0 = (size_t)pa * R * L;
        for (int h = 0; h < H; h++) {
            for (int r = 0; r < R && !s->intra_off; r++)
                ref_group(L, d, p0 + (size_t)r * L, 1, h * d, C, ldexp(s->intra_slope, -h), 1, qkv, o);
            for (int t = 0; t < L && !s->inter_off; t++)
                ref_group(R, d, p0 + t, (size_t)L, C / 2 + h * d, C, ldexp(s->inter_slope, -h),
                          s->win_w > 1 ? s->win_w : 1, qkv, o);
        }
        for (size_t i = p0; i < p0 + (size_t)R * L; i++) /* switched-off paths pass V through */
            for (int c = 0; c < C; c++)
                if (c < C / 2 ? s->intra_off : s->inter_off) o[i * C + c] = qkv[i * 3 * C + 2 * C + c];
    }
}

void nerf_ref_block_forward(const nerf_block_shape *s, const double *P, int n_patches, const double *x, double *out)
{
    const int C = s->att.C, Hf = s->hidden;
    const size_t n = (size_t)n_patches * s->att.R * s->att.L;
    nerf_block_offsets o = nerf_block_layout(s);
    double *y = calloc(n * C, sizeof *y), *qkv = calloc(n * 3 * C, sizeof *qkv), *a = calloc(n * C, sizeof *a);
    double *h = calloc(n * Hf, sizeof *h), *t = calloc(n * C, sizeof *t);
    nerf_ref_layernorm((int)n, C, P + o.ln1_g, P + o.ln1_b, x, y);
    nerf_ref_linear((int)n, C, 3 * C, P + o.w_qkv, P + o.b_qkv, y, qkv);
    nerf_ref_i2r_forward(&s->att, n_patches, qkv, a);
    if (s->inter_gate) /* v + g_h·(o − v) on the inter-ray channels */
        for (size_t i = 0; i < n; i++)
            for (int c = C / 2; c < C; c++) {
                const double v = qkv[i * 3 * C + 2 * C + c], g = P[o.gate + (c - C / 2) / (C / 2 / s->att.heads)];
                a[i * C + c] = v + g * (a[i * C + c] - v);
            }
    nerf_ref_linear((int)n, C, C, P + o.w_o, P + o.b_o, a, t);
    for (size_t i = 0; i < n * C; i++) out[i] = x[i] + t[i];
    nerf_ref_layernorm((int)n, C, P + o.ln2_g, P + o.ln2_b, out, y);
    nerf_ref_linear((int)n, C, Hf, P + o.w_1, P + o.b_1, y, h);
    for (size_t i = 0; i < n * Hf; i++) h[i] = nerf_ref_gelu(h[i]);
    nerf_ref_linear((int)n, Hf, C, P + o.w_2, P + o.b_2, h, t);
    for (size_t i = 0; i < n * C; i++) out[i] += t[i];
    free(y), free(qkv), free(a), free(h), free(t);
}

void nerf_ref_rayformer_forward(const nerf_rayformer *net, const double *P, int n_patches, const double *pos,
                                const double *dir, double *sigma, double *rgb)
{
    const nerf_rayformer_config *cf = nerf_rayformer_config_of(net);
    nerf_rayformer_layout lo = nerf_rayformer_layout_of(net);
    const int C = cf->width, G = cf->geo_dim, S = nerf_sh_dim(cf->sh_degree), Hc = cf->color_hidden;
    const int R = cf->patch_w * cf->patch_h, L = cf->samples, Ci = G + S;
    const size_t n = (size_t)n_patches * R * L;
    nerf_block_shape bs = {.att = {.C = C, .heads = cf->heads, .L = L, .R = R, .intra_off = !cf->intra_ray,
                                   .inter_off = !cf->inter_ray, .intra_slope = cf->intra_slope,
                                   .inter_slope = cf->inter_slope, .win_w = cf->patch_w},
                           .hidden = cf->ffn_hidden, .inter_gate = cf->inter_gate && cf->inter_ray};
    double *u = malloc(n * 3 * sizeof *u), *a = malloc(n * C * sizeof *a), *b = malloc(n * C * sizeof *b);
    double *ho = malloc(n * (G + 1) * sizeof *ho), *ci = calloc(n * Ci, sizeof *ci);
    double *c1 = malloc(n * (Hc ? Hc : 1) * sizeof *c1), *rp = malloc(n * 3 * sizeof *rp);
    for (size_t i = 0; i < n; i++)
        for (int d = 0; d < 3; d++)
            u[3 * i + d] = (pos[3 * i + d] - cf->aabb_min[d]) / ((double)cf->aabb_max[d] - cf->aabb_min[d]);
    nerf_ref_hashgrid_forward(nerf_rayformer_grid(net), P, (int)n, u, a);
    for (int k = 0; k < cf->n_blocks; k++) {
        nerf_ref_block_forward(&bs, P + lo.block[k], n_patches, a, b);
        memcpy(a, b, n * C * sizeof *a);
    }
    if (cf->final_norm)
        nerf_ref_layernorm((int)n, C, P + lo.lnf_g, P + lo.lnf_b, a, b);
    else
        memcpy(b, a, n * C * sizeof *b);
    if (cf->head_hidden) {
        const int Hh = cf->head_hidden;
        double *hh = malloc(n * Hh * sizeof *hh);
        nerf_ref_linear((int)n, C, Hh, P + lo.wh1, P + lo.bh1, b, hh);
        for (size_t i = 0; i < n * Hh; i++) hh[i] = hh[i] > 0 ? hh[i] : 0;
        nerf_ref_linear((int)n, Hh, G + 1, P + lo.wh, P + lo.bh, hh, ho);
        free(hh);
    } else {
        nerf_ref_linear((int)n, C, G + 1, P + lo.wh, P + lo.bh, b, ho);
    }
    for (size_t i = 0; i < n; i++) {
        double s = ho[i * (G + 1)] + cf->density_bias;
        sigma[i] = exp(s < 88 ? s : 88);
        for (int g = 0; g < G; g++) ci[i * Ci + g] = ho[i * (G + 1) + 1 + g];
        double sh[16], shg[16][3];
        nerf_sh_eval(dir[3 * (i / L)], dir[3 * (i / L) + 1], dir[3 * (i / L) + 2], sh, shg);
        for (int k = 0; k < S; k++) ci[i * Ci + G + k] = sh[k];
    }
    if (Hc) {
        nerf_ref_linear((int)n, Ci, Hc, P + lo.wc1, P + lo.bc1, ci, c1);
        for (size_t i = 0; i < n * Hc; i++) c1[i] = c1[i] > 0 ? c1[i] : 0;
        nerf_ref_linear((int)n, Hc, 3, P + lo.wc2, P + lo.bc2, c1, rp);
    } else {
        nerf_ref_linear((int)n, Ci, 3, P + lo.wc2, P + lo.bc2, ci, rp);
    }
    for (size_t i = 0; i < n * 3; i++) rgb[i] = 1.0 / (1.0 + exp(-rp[i]));
    free(u), free(a), free(b), free(ho), free(ci), free(c1), free(rp);
}

static void ref_freq(int K, const double *x, double *y)
{
    int o = 0;
    for (int d = 0; d < 3; d++) y[o++] = x[d];
    for (int k = 0; k < K; k++) {
        double f = ldexp(1.0, k);
        for (int d = 0; d < 3; d++) y[o + d] = sin(f * x[d]);
        for (int d = 0; d < 3; d++) y[o + 3 + d] = cos(f * x[d]);
        o += 6;
    }
}

void nerf_ref_mlp_forward(const nerf_mlp *net, const double *P, int n, const double *pos, const double *dir,
                          int dir_every, double *sigma, double *rgb)
{
    const nerf_mlp_config *c = nerf_mlp_config_of(net);
    nerf_mlp_layout lo = nerf_mlp_layout_of(net);
    const int E = nerf_mlp_enc_dim(net), Dd = nerf_mlp_dir_dim(net), W = c->width, F = c->feature_dim;
    const int Ch = c->color_hidden, Ci = F + Dd, wide = (W + E > Ci ? W + E : Ci) + 1;
    double *e = malloc(E * sizeof *e), *a = malloc(wide * sizeof *a), *b = malloc(wide * sizeof *b);
    double *ci = malloc(Ci * sizeof *ci), *c1 = malloc((Ch ? Ch : 1) * sizeof *c1), rp[3], s;
    for (int i = 0; i < n; i++) {
        double u[3];
        for (int d = 0; d < 3; d++)
            u[d] = (pos[3 * i + d] - c->aabb_min[d]) / ((double)c->aabb_max[d] - c->aabb_min[d]);
        if (c->pos_enc == NERF_MLP_POS_HASH) {
            nerf_ref_hashgrid_forward(nerf_mlp_grid(net), P, 1, u, e);
        } else {
            double x[3] = {2 * u[0] - 1, 2 * u[1] - 1, 2 * u[2] - 1};
            ref_freq(c->pos_freqs, x, e);
        }
        memcpy(a, e, E * sizeof *a);
        for (int l = 0; l < c->depth; l++) {
            int in = lo.trunk_in[l];
            if (l == c->skip && l > 0) memcpy(a + W, e, E * sizeof *a); /* [h, e] */
            nerf_ref_linear(1, in, W, P + lo.trunk_w[l], P + lo.trunk_b[l], a, b);
            for (int k = 0; k < W; k++) a[k] = b[k] > 0 ? b[k] : 0;
        }
        nerf_ref_linear(1, W, 1, P + lo.ws, P + lo.bs, a, &s);
        s += c->density_bias;
        sigma[i] = c->density_act == NERF_ACT_RELU ? (s > 0 ? s : 0) : exp(s < 88 ? s : 88);
        nerf_ref_linear(1, W, F, P + lo.wf, P + lo.bf, a, ci);
        const double *d = dir + 3 * (size_t)(i / dir_every);
        if (c->dir_enc == NERF_MLP_DIR_SH) {
            double sh[16], shg[16][3];
            nerf_sh_eval(d[0], d[1], d[2], sh, shg);
            for (int k = 0; k < Dd; k++) ci[F + k] = sh[k];
        } else {
            ref_freq(c->dir_freqs, d, ci + F);
        }
        if (Ch) {
            nerf_ref_linear(1, Ci, Ch, P + lo.wc1, P + lo.bc1, ci, c1);
            for (int k = 0; k < Ch; k++) c1[k] = c1[k] > 0 ? c1[k] : 0;
            nerf_ref_linear(1, Ch, 3, P + lo.wc2, P + lo.bc2, c1, rp);
        } else {
            nerf_ref_linear(1, Ci, 3, P + lo.wc2, P + lo.bc2, ci, rp);
        }
        for (int k = 0; k < 3; k++) rgb[3 * (size_t)i + k] = 1.0 / (1.0 + exp(-rp[k]));
    }
    free(e), free(a), free(b), free(ci), free(c1);
}

void nerf_ref_render(int n_rays, int L, const double *sigma, const double *rgb, const double *delta,
                     const double *t, const int *n_valid, double t_stop, double *color, double *depth,
                     double *opacity)
{
    for (int k = 0; k < n_rays; k++) {
        int n = n_valid ? n_valid[k] : L;
        double T = 1.0, c[3] = {0, 0, 0}, D = 0;
        for (int i = 0; i < n; i++) {
            size_t s = (size_t)k * L + i;
            double a = 1.0 - exp(-sigma[s] * delta[s]);
            double w = T * a;
            for (int q = 0; q < 3; q++) c[q] += w * rgb[3 * s + q];
            if (t) D += w * t[s];
            T *= exp(-sigma[s] * delta[s]);
            if (T < t_stop) break;
        }
        for (int q = 0; q < 3; q++) color[3 * k + q] = c[q];
        if (depth) depth[k] = D;
        if (opacity) opacity[k] = 1.0 - T;
    }
}
