/* recon/blockmatch.c — block matching for video patch groups (see blockmatch.h). */
#include "recon/blockmatch.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "base/error.h"

/* 8 floats (and their comparison mask): one AVX2 register, two SSE ones in the baseline clone; loaded by a macro so
 * that no function passes or returns one (gcc would warn about the baseline clone's ABI). */
typedef float v8 __attribute__((vector_size(32)));
typedef int32_t v8i __attribute__((vector_size(32)));
#define V8_LOAD(v, p) memcpy(&(v), (p), sizeof(v8))

/* clang before 16 exports a target_clones function as NAME.ifunc, which other files' calls do not link to
 * (the fuzzers are built with clang): a single version there */
#if defined(__clang__) && __clang_major__ < 16
#define CLONES
#else
#define CLONES __attribute__((target_clones("avx2", "default")))
#endif

struct sci_blockmatch {
    int w, h, n, p, k, window;
    int rows, cols;       /* positions per frame: h − p + 1, w − p + 1 */
    int *grow, *gcol;     /* key grid rows and columns */
    int ngr, ngc;
    int keys;
    uint32_t *idx;        /* keys × k members */
    float *dist;          /* keys × k squared distances (a max-heap per key while matching) */
    int *colkey;          /* w: the key column index of pixel column c, or -1 */
    int band, span;       /* key rows per task; pixel rows a band's patches cover, at most */
    float *scratch;       /* per thread: span × w squared differences, w column sums, w box sums, then band × w
                             heap tops by pixel column (−∞ where no key) and w ints of hits */
    size_t scratch_floats;
    int threads_alloc;
};

/* Key rows per task: a band's squared differences are computed once for all its key rows, whose patches overlap
 * by p − step rows; 16 rows keep the band's heaps and its difference rows in cache. */
#define BM_BAND 16

/* Grid of positions 0, step, 2·step, … ≤ last, then every position after the grid's last one (neighborind.m's
 * "residual steps"). Returns the count; out may be NULL to count. */
static int grid(int last, int step, int *out)
{
    int c = 0, v = 0;
    for (; v <= last; v += step)
        if (out)
            out[c++] = v;
        else
            c++;
    for (int u = v - step + 1; u <= last; u++)
        if (out)
            out[c++] = u;
        else
            c++;
    return c;
}

int sci_blockmatch_new(sci_blockmatch **out, int w, int h, int n, const sci_blockmatch_params *p, sci_error *err)
{
    *out = NULL;
    if (w < 1 || h < 1 || n < 1)
        return sci_error_set(err, -EINVAL, "blockmatch: frames of %dx%dx%d", w, h, n);
    if (p->patch < 1 || p->patch > w || p->patch > h)
        return sci_error_set(err, -EINVAL, "blockmatch: patch %d does not fit frames of %dx%d", p->patch, w, h);
    if (p->group < 1 || p->step < 1 || p->window < 0)
        return sci_error_set(err, -EINVAL, "blockmatch: group %d, step %d, window %d (need >= 1, >= 1, >= 0)",
                             p->group, p->step, p->window);
    if ((double)w * h * n >= 4294967295.0)
        return sci_error_set(err, -EINVAL, "blockmatch: %dx%dx%d pixels overflow 32-bit indices", w, h, n);
    sci_blockmatch *bm = calloc(1, sizeof *bm);
    if (!bm)
        return sci_error_set(err, -ENOMEM, "blockmatch: out of memory");
    bm->w = w, bm->h = h, bm->n = n, bm->p = p->patch, bm->window = p->window;
    bm->rows = h - p->patch + 1, bm->cols = w - p->patch + 1;
    bm->ngr = grid(bm->rows - 1, p->step, NULL);
    bm->ngc = grid(bm->cols - 1, p->step, NULL);
    bm->keys = n * bm->ngr * bm->ngc;
    /* the smallest window is a corner key's: window + 1 positions each way (or the whole frame) */
    const long cand = (long)n * ((bm->rows - 1 < p->window ? bm->rows - 1 : p->window) + 1) *
                      ((bm->cols - 1 < p->window ? bm->cols - 1 : p->window) + 1);
    bm->k = p->group < cand ? p->group : (int)cand;
    bm->threads_alloc = omp_get_max_threads();
    if (bm->threads_alloc < 1)
        bm->threads_alloc = 1;
    bm->grow = malloc((size_t)bm->ngr * sizeof *bm->grow);
    bm->gcol = malloc((size_t)bm->ngc * sizeof *bm->gcol);
    bm->idx = malloc((size_t)bm->keys * bm->k * sizeof *bm->idx);
    bm->dist = malloc((size_t)bm->keys * bm->k * sizeof *bm->dist);
    bm->colkey = malloc((size_t)w * sizeof *bm->colkey);
    if (bm->grow && bm->gcol) {
        grid(bm->rows - 1, p->step, bm->grow);
        grid(bm->cols - 1, p->step, bm->gcol);
        bm->band = BM_BAND;
        for (int b = 0; b < bm->ngr; b += bm->band) {
            const int last = b + bm->band < bm->ngr ? b + bm->band - 1 : bm->ngr - 1;
            const int span = bm->grow[last] - bm->grow[b] + bm->p;
            bm->span = span > bm->span ? span : bm->span;
        }
        bm->scratch_floats = ((size_t)bm->span + 3 + bm->band) * w + 16;
        bm->scratch = malloc((size_t)bm->threads_alloc * bm->scratch_floats * sizeof *bm->scratch);
    }
    if (!bm->grow || !bm->gcol || !bm->idx || !bm->dist || !bm->colkey || !bm->scratch) {
        const int keys = bm->keys, k = bm->k;
        sci_blockmatch_free(bm);
        return sci_error_set(err, -ENOMEM, "blockmatch: out of memory (%d groups of %d)", keys, k);
    }
    for (int c = 0; c < w; c++)
        bm->colkey[c] = -1;
    for (int j = 0; j < bm->ngc; j++)
        bm->colkey[bm->gcol[j]] = j;
    *out = bm;
    return 0;
}

void sci_blockmatch_free(sci_blockmatch *bm)
{
    if (!bm)
        return;
    free(bm->grow);
    free(bm->gcol);
    free(bm->idx);
    free(bm->dist);
    free(bm->colkey);
    free(bm->scratch);
    free(bm);
}

int sci_blockmatch_keys(const sci_blockmatch *bm) { return bm->keys; }
int sci_blockmatch_group_size(const sci_blockmatch *bm) { return bm->k; }
const uint32_t *sci_blockmatch_group(const sci_blockmatch *bm, int g) { return bm->idx + (size_t)g * bm->k; }
const float *sci_blockmatch_distances(const sci_blockmatch *bm, int g) { return bm->dist + (size_t)g * bm->k; }

uint32_t sci_blockmatch_key(const sci_blockmatch *bm, int g)
{
    const int f = g / (bm->ngr * bm->ngc), r = (g / bm->ngc) % bm->ngr, c = g % bm->ngc;
    return (uint32_t)(((size_t)f * bm->h + bm->grow[r]) * bm->w + bm->gcol[c]);
}

/* dd[r·w + c] = (a[r·w + c] − b[r·w + c])² for r < nrows, c < len: the squared differences of a band. */
CLONES static void square_differences(const float *restrict a, const float *restrict b, int w, int nrows, int len,
                                      float *restrict dd)
{
    for (int r = 0; r < nrows; r++) {
        const float *ra = a + (size_t)r * w, *rb = b + (size_t)r * w;
        float *o = dd + (size_t)r * w;
        for (int c = 0; c < len; c++) {
            const float d = ra[c] - rb[c];
            o[c] = d * d;
        }
    }
}

/* box[c] = Σ_{i<p, t<p} dd[i·w + c + t] for c ≤ len − p: the p × p sums of one key row (v: len floats). */
CLONES static void box_sums(const float *restrict dd, int w, int p, int len, float *restrict v, float *restrict box)
{
    for (int c = 0; c < len; c++)
        v[c] = dd[c];
    for (int i = 1; i < p; i++) {
        const float *row = dd + (size_t)i * w;
        for (int c = 0; c < len; c++)
            v[c] += row[c];
    }
    const int nb = len - p + 1;
    for (int c = 0; c < nb; c++)
        box[c] = v[c];
    for (int t = 1; t < p; t++)
        for (int c = 0; c < nb; c++)
            box[c] += v[c + t];
}

/* The columns c < n with box[c] < tops[c], into hits; returns how many. Eight at a time: a block of eight is
 * looked at one by one only when one of them passes, which after the first offsets is rare. */
CLONES static int below_tops(const float *restrict box, const float *restrict tops, int n, int *restrict hits)
{
    int nh = 0, c = 0;
    for (; c + 8 <= n; c += 8) {
        v8 b, t;
        V8_LOAD(b, box + c);
        V8_LOAD(t, tops + c);
        const v8i lt = b < t;
        uint64_t any[4];
        memcpy(any, &lt, sizeof any);
        if ((any[0] | any[1] | any[2] | any[3]) == 0)
            continue;
        for (int l = 0; l < 8; l++)
            if (box[c + l] < tops[c + l])
                hits[nh++] = c + l;
    }
    for (; c < n; c++)
        if (box[c] < tops[c])
            hits[nh++] = c;
    return nh;
}

/* Replace the largest entry of a max-heap of k (distance, index) pairs and restore the heap. */
static void heap_replace_top(float *d, uint32_t *ix, int k, float nd, uint32_t ni)
{
    int i = 0;
    for (;;) {
        int l = 2 * i + 1, r = l + 1, m = i;
        float dm = nd;
        if (l < k && d[l] > dm)
            m = l, dm = d[l];
        if (r < k && d[r] > dm)
            m = r, dm = d[r];
        if (m == i)
            break;
        d[i] = d[m], ix[i] = ix[m];
        i = m;
    }
    d[i] = nd, ix[i] = ni;
}

/* The keys of frame f0, key rows gr0 … gr1 − 1: every candidate offset in a fixed order (the key's own frame
 * first, offsets 0, −1, +1, −2, … so that the key itself is the first candidate, at distance 0). Per offset, the
 * squared differences of the band's rows once, then the p × p sums of each key row. */
static void match_band(sci_blockmatch *bm, const float *frames, int f0, int gr0, int gr1, float *scratch)
{
    const int w = bm->w, p = bm->p, k = bm->k, W = bm->window, ngc = bm->ngc;
    const size_t plane = (size_t)w * bm->h;
    float *dd = scratch, *v = scratch + (size_t)bm->span * w, *box = v + w, *tops = box + w;
    int *hits = (int *)(tops + (size_t)bm->band * w);
    const size_t g0 = ((size_t)f0 * bm->ngr + gr0) * ngc, gn = (size_t)(gr1 - gr0) * ngc;
    for (size_t i = 0; i < gn * k; i++)
        bm->dist[g0 * k + i] = INFINITY, bm->idx[g0 * k + i] = 0;
    for (int gr = gr0; gr < gr1; gr++)
        for (int c = 0; c < w; c++)
            tops[(size_t)(gr - gr0) * w + c] = bm->colkey[c] >= 0 ? INFINITY : -INFINITY;
    const float *x0 = frames + (size_t)f0 * plane;
    for (int fi = 0; fi < bm->n; fi++) {
        const int f1 = fi == 0 ? f0 : fi <= f0 ? fi - 1 : fi;
        const float *x1 = frames + (size_t)f1 * plane;
        for (int oy = 0; oy <= 2 * W; oy++) {
            const int dy = oy == 0 ? 0 : oy & 1 ? -((oy + 1) / 2) : oy / 2;
            /* the band's key rows whose candidate row ky + dy is a patch row */
            int ra = gr0, rb = gr1 - 1;
            while (ra <= rb && bm->grow[ra] + dy < 0)
                ra++;
            while (rb >= ra && bm->grow[rb] + dy > bm->rows - 1)
                rb--;
            if (ra > rb)
                continue;
            const int r0 = bm->grow[ra], nrows = bm->grow[rb] + p - r0;
            for (int ox = 0; ox <= 2 * W; ox++) {
                const int dx = ox == 0 ? 0 : ox & 1 ? -((ox + 1) / 2) : ox / 2;
                /* columns c with c and c + dx both inside the frame; keys at c0 … c1 − p */
                const int c0 = dx < 0 ? -dx : 0, c1 = dx > 0 ? w - dx : w;
                if (c1 - c0 < p)
                    continue;
                square_differences(x0 + (size_t)r0 * w + c0, x1 + (size_t)(r0 + dy) * w + c0 + dx, w, nrows,
                                   c1 - c0, dd);
                for (int gr = ra; gr <= rb; gr++) {
                    const int ky = bm->grow[gr];
                    box_sums(dd + (size_t)(ky - r0) * w, w, p, c1 - c0, v, box);
                    const size_t grow0 = ((size_t)f0 * bm->ngr + gr) * ngc;
                    const uint32_t base = (uint32_t)((size_t)f1 * plane + (size_t)(ky + dy) * w + dx);
                    float *trow = tops + (size_t)(gr - gr0) * w;
                    const int nh = below_tops(box, trow + c0, c1 - c0 - p + 1, hits);
                    for (int i = 0; i < nh; i++) {
                        const int kx = c0 + hits[i];
                        const size_t g = grow0 + bm->colkey[kx];
                        heap_replace_top(bm->dist + g * k, bm->idx + g * k, k, box[hits[i]], base + (uint32_t)kx);
                        trow[kx] = bm->dist[g * k];
                    }
                }
            }
        }
    }
    /* the key first: it is in the group (distance 0, visited first, never displaced by a tie) */
    for (int gr = gr0; gr < gr1; gr++)
        for (int j = 0; j < ngc; j++) {
            const size_t g = ((size_t)f0 * bm->ngr + gr) * ngc + j;
            const uint32_t key = (uint32_t)((size_t)f0 * plane + (size_t)bm->grow[gr] * w + bm->gcol[j]);
            float *dj = bm->dist + g * k;
            uint32_t *ij = bm->idx + g * k;
            for (int i = 0; i < k; i++)
                if (ij[i] == key && dj[i] == 0.0f) {
                    const float td = dj[0];
                    const uint32_t ti = ij[0];
                    dj[0] = dj[i], ij[0] = ij[i];
                    dj[i] = td, ij[i] = ti;
                    break;
                }
        }
}

int sci_blockmatch_run(sci_blockmatch *bm, const float *frames, int threads, const atomic_int *cancel)
{
    const int bands = (bm->ngr + bm->band - 1) / bm->band, tasks = bm->n * bands;
    int nt = threads > 0 ? threads : omp_get_max_threads();
    if (nt > bm->threads_alloc)
        nt = bm->threads_alloc;
    atomic_int stop = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(nt)
    for (int t = 0; t < tasks; t++) {
        if (atomic_load_explicit(&stop, memory_order_relaxed))
            continue;
        if (cancel && atomic_load(cancel)) {
            atomic_store(&stop, 1);
            continue;
        }
        const int b = t % bands, gr0 = b * bm->band, gr1 = gr0 + bm->band < bm->ngr ? gr0 + bm->band : bm->ngr;
        match_band(bm, frames, t / bands, gr0, gr1, bm->scratch + (size_t)omp_get_thread_num() * bm->scratch_floats);
    }
    return stop ? SCI_ECANCELED : 0;
}
