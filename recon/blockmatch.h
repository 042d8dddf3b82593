/* recon/blockmatch.h — block matching for video patch groups (DeSCI's vblockmatch.m and neighborind.m): for every
 * key patch, the `group` most similar p×p patches (squared Euclidean distance) within ±window positions around it,
 * searched in every frame of the video.
 *
 *     sci_blockmatch *bm;
 *     rc = sci_blockmatch_new(&bm, w, h, n, &(sci_blockmatch_params){.patch = 9, .group = 140, .step = 3,
 *                                                                    .window = 30}, err);
 *     sci_blockmatch_run(bm, frames, threads, cancel);      // frames: w×h×n, frame-major (base/cube.h)
 *     for (int g = 0; g < sci_blockmatch_keys(bm); g++) {
 *         const uint32_t *m = sci_blockmatch_group(bm, g);  // group size = sci_blockmatch_group_size(bm)
 *         ... m[i] = f·w·h + y·w + x: the top-left corner (x, y) of a member in frame f ...
 *     }
 *     sci_blockmatch_free(bm);
 *
 * Key patches: in every frame, the top-left positions on a grid of `step` pixels from 0 in both directions, plus
 * every position after the grid's last one (so that the bottom and right edges are covered, as neighborind.m
 * does). Positions run over 0 … w − p and 0 … h − p. The search window of a key at (kx, ky) is clipped at the
 * borders (not shifted): x in [max(kx − window, 0), min(kx + window, w − p)], the same in y, in all n frames.
 *
 * The key patch itself is always a member (its distance 0 is visited first and ties never displace it): the
 * reference code sorts all candidates with frame 1 first, so in a flat area a key of another frame could lose its
 * place to equal-distance patches of frame 1 and leave pixels that no group covers (they came out 0 there).
 * The group size is clamped to the number of candidates of the smallest window (a corner key's); the reference
 * code would index past its candidate list instead.
 *
 * Cost: for every frame pair and offset, the squared differences of a band of 16 key rows once (one per pixel)
 * and about 2p additions per pixel of each key row, vectorised (AVX2 where the CPU has it); a candidate reaches its
 * key's heap only when it beats the heap's largest distance, tested eight columns at a time. On 256×256×8 with the
 * σ ≤ 20 parameters (p 6, step 2, window 30: 127,008 groups of 70 among up to 29,768 candidates) about 7 s at 2
 * threads. OpenMP over (frame, band) tasks; each key's candidates are visited in a fixed order by one thread, so the
 * result does not depend on the thread count. Distances in float.
 *
 * Plan/execute: all memory is allocated by sci_blockmatch_new; sci_blockmatch_run allocates nothing. One plan
 * must not be run by two callers at once. Errors: 0 or -EINVAL (sizes, a patch larger than the frame, index
 * overflow), -ENOMEM, with a message naming the value at fault.
 */
#ifndef SCICAP_RECON_BLOCKMATCH_H
#define SCICAP_RECON_BLOCKMATCH_H

#include <stdatomic.h>
#include <stdint.h>

#include "base/error.h"

typedef struct sci_blockmatch_params {
    int patch;  /* patch side p in pixels, >= 1, <= the frame's width and height */
    int group;  /* patches per group (the key included), >= 1 (clamped to the smallest window's candidates) */
    int step;   /* key grid step in pixels, >= 1 */
    int window; /* search radius in pixel positions, >= 0 */
} sci_blockmatch_params;

typedef struct sci_blockmatch sci_blockmatch;

int sci_blockmatch_new(sci_blockmatch **out, int w, int h, int n, const sci_blockmatch_params *p, sci_error *err);
void sci_blockmatch_free(sci_blockmatch *bm);

/* Match on `frames` (w×h×n floats, frame-major; only read). threads: OpenMP threads, 0 = the default. cancel
 * (nullable): when it becomes nonzero the run stops early and returns SCI_ECANCELED, leaving the groups
 * undefined until the next complete run. Returns 0 otherwise. */
int sci_blockmatch_run(sci_blockmatch *bm, const float *frames, int threads, const atomic_int *cancel);

/* Number of key patches (= groups): n × key rows × key columns. */
int sci_blockmatch_keys(const sci_blockmatch *bm);
/* Members per group (the clamped `group`). */
int sci_blockmatch_group_size(const sci_blockmatch *bm);
/* Group g's members as f·w·h + y·w + x, the key first; borrowed, valid until the next run or free. Unordered
 * after the key. Undefined before the first complete run. */
const uint32_t *sci_blockmatch_group(const sci_blockmatch *bm, int g);
/* The member's squared distance to the key (same order as sci_blockmatch_group): for tests and diagnostics. */
const float *sci_blockmatch_distances(const sci_blockmatch *bm, int g);
/* Group g's key as f·w·h + y·w + x. */
uint32_t sci_blockmatch_key(const sci_blockmatch *bm, int g);

#endif
