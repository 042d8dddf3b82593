/* base/rng.h — seeded pseudo-random streams (xoshiro256**).
 *
 * A stream is a small value type: seed it with (seed, stream id) and every draw is reproducible. Independent
 * parts of the program (each simulator effect, each NeRF initialiser) take their own stream id, so turning one
 * of them on or off never shifts the draws of another. Not thread-safe per object: give each thread its own
 * stream (sci_rng_seed with a distinct stream id, or sci_rng_jump).
 */
#ifndef SCICAP_BASE_RNG_H
#define SCICAP_BASE_RNG_H

#include <stdint.h>

typedef struct sci_rng {
    uint64_t s[4];
} sci_rng;

/* Seed from a 64-bit seed and a stream id; distinct (seed, stream) pairs give unrelated sequences. */
void sci_rng_seed(sci_rng *rng, uint64_t seed, uint64_t stream);
/* Advance by 2^128 draws: a non-overlapping sub-stream (e.g. one per thread). */
void sci_rng_jump(sci_rng *rng);

uint64_t sci_rng_u64(sci_rng *rng);
/* Uniform on [0, 1) with 53 (double) or 24 (float) random bits. */
double sci_rng_uniform(sci_rng *rng);
float sci_rng_uniformf(sci_rng *rng);
/* Uniform integer on [0, n), n > 0, without modulo bias. */
uint64_t sci_rng_below(sci_rng *rng, uint64_t n);
/* Standard normal N(0, 1) (Marsaglia polar method; no cached state, so draws stay independent of call order). */
double sci_rng_normal(sci_rng *rng);
/* Poisson(lambda), lambda >= 0. Exact: inversion for lambda < 10, Hörmann's PTRS rejection above. Returns 0 for
 * lambda <= 0 or NaN. */
double sci_rng_poisson(sci_rng *rng, double lambda);

#endif
