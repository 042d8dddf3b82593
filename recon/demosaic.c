#include "recon/demosaic.h"

#include <assert.h>
#include <errno.h>
#include <string.h>
#include <strings.h>

/* Colour index of the 2×2 tile positions (0,0) (1,0) (0,1) (1,1), per pattern. */
static const unsigned char tile[5][4] = {
    [SCI_CFA_RGGB] = {0, 1, 1, 2},
    [SCI_CFA_BGGR] = {2, 1, 1, 0},
    [SCI_CFA_GRBG] = {1, 0, 2, 1},
    [SCI_CFA_GBRG] = {1, 2, 0, 1},
};

int sci_cfa_color(sci_cfa cfa, int x, int y)
{
    assert(cfa > SCI_CFA_NONE && cfa <= SCI_CFA_GBRG);
    return tile[cfa][(x & 1) | (y & 1) << 1];
}

int sci_demosaic_parse(const char *s, sci_demosaic_method *out)
{
    if (strcasecmp(s, "bilinear") == 0)
        *out = SCI_DEMOSAIC_BILINEAR;
    else if (strcasecmp(s, "mhc") == 0 || strcasecmp(s, "malvar") == 0)
        *out = SCI_DEMOSAIC_MHC;
    else
        return -EINVAL;
    return 0;
}

const char *sci_demosaic_name(sci_demosaic_method m)
{
    return m == SCI_DEMOSAIC_MHC ? "mhc" : "bilinear";
}

/* Reflect-101 keeps the parity of the index for even sizes, so a mirrored pixel has the colour the missing one
 * would have had; the clamp covers sizes below 3. */
static inline int mirror(int i, int n)
{
    if (i < 0)
        i = -i;
    if (i >= n)
        i = 2 * n - 2 - i;
    return i < 0 ? 0 : i >= n ? n - 1 : i;
}

#define P(dx, dy) raw[(size_t)mirror(y + (dy), h) * w + mirror(x + (dx), w)]

void sci_demosaic(sci_cfa cfa, sci_demosaic_method m, const float *raw, int w, int h, float *r, float *g,
                  float *b)
{
    assert(w >= 2 && h >= 2);
    float *out[3] = {r, g, b};
#pragma omp parallel for schedule(static)
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const size_t i = (size_t)y * w + x;
            const int c = sci_cfa_color(cfa, x, y);
            const float v = raw[i];
            float cross, diag, horiz, vert;
            if (m == SCI_DEMOSAIC_BILINEAR) {
                cross = 0.25f * (P(-1, 0) + P(1, 0) + P(0, -1) + P(0, 1));
                diag = 0.25f * (P(-1, -1) + P(1, -1) + P(-1, 1) + P(1, 1));
                horiz = 0.5f * (P(-1, 0) + P(1, 0));
                vert = 0.5f * (P(0, -1) + P(0, 1));
            } else {
                /* Malvar–He–Cutler kernels (×1/8): each bilinear estimate plus a gain times the Laplacian of the
                 * colour sampled here, which carries the edge the sparser colour cannot see. */
                const float axial2 = P(-2, 0) + P(2, 0) + P(0, -2) + P(0, 2);
                const float c4 = P(-1, 0) + P(1, 0) + P(0, -1) + P(0, 1);
                const float d4 = P(-1, -1) + P(1, -1) + P(-1, 1) + P(1, 1);
                cross = (4 * v + 2 * c4 - axial2) / 8;
                diag = (6 * v + 2 * d4 - 1.5f * axial2) / 8;
                /* At a G site: the colour of the row neighbours (horiz) and of the column neighbours (vert). */
                horiz = (5 * v + 4 * (P(-1, 0) + P(1, 0)) - (P(-2, 0) + P(2, 0)) - d4 + 0.5f * (P(0, -2) + P(0, 2))) / 8;
                vert = (5 * v + 4 * (P(0, -1) + P(0, 1)) - (P(0, -2) + P(0, 2)) - d4 + 0.5f * (P(-2, 0) + P(2, 0))) / 8;
            }
            out[c][i] = v;
            if (c == 1) {
                const int ch = sci_cfa_color(cfa, x + 1, y); /* R or B along the row */
                out[ch][i] = horiz;
                out[2 - ch][i] = vert;
            } else {
                out[1][i] = cross;
                out[2 - c][i] = diag;
            }
        }
}
