#include "base/rng.h"

#include <math.h>

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void sci_rng_seed(sci_rng *rng, uint64_t seed, uint64_t stream)
{
    /* Mix the stream id through splitmix first so that streams 0, 1, 2 ... are far apart in seed space. */
    uint64_t st = stream;
    uint64_t x = seed ^ splitmix64(&st);
    for (int i = 0; i < 4; i++)
        rng->s[i] = splitmix64(&x);
}

uint64_t sci_rng_u64(sci_rng *rng)
{
    uint64_t *s = rng->s;
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

void sci_rng_jump(sci_rng *rng)
{
    static const uint64_t jump[] = {0x180ec6d33cfd0abaULL, 0xd5a61266f0c9392cULL, 0xa9582618e03fc9aaULL,
                                    0x39abdc4529b1661cULL};
    uint64_t s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    for (int i = 0; i < 4; i++)
        for (int b = 0; b < 64; b++) {
            if (jump[i] & (1ULL << b)) {
                s0 ^= rng->s[0];
                s1 ^= rng->s[1];
                s2 ^= rng->s[2];
                s3 ^= rng->s[3];
            }
            sci_rng_u64(rng);
        }
    rng->s[0] = s0;
    rng->s[1] = s1;
    rng->s[2] = s2;
    rng->s[3] = s3;
}

double sci_rng_uniform(sci_rng *rng) { return (double)(sci_rng_u64(rng) >> 11) * 0x1.0p-53; }
float sci_rng_uniformf(sci_rng *rng) { return (float)(sci_rng_u64(rng) >> 40) * 0x1.0p-24f; }

uint64_t sci_rng_below(sci_rng *rng, uint64_t n)
{
    /* Lemire's nearly-divisionless method. */
    unsigned __int128 m = (unsigned __int128)sci_rng_u64(rng) * n;
    uint64_t lo = (uint64_t)m;
    if (lo < n) {
        uint64_t t = -n % n;
        while (lo < t) {
            m = (unsigned __int128)sci_rng_u64(rng) * n;
            lo = (uint64_t)m;
        }
    }
    return (uint64_t)(m >> 64);
}

double sci_rng_normal(sci_rng *rng)
{
    double u, v, s;
    do {
        u = 2.0 * sci_rng_uniform(rng) - 1.0;
        v = 2.0 * sci_rng_uniform(rng) - 1.0;
        s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    return u * sqrt(-2.0 * log(s) / s);
}

double sci_rng_poisson(sci_rng *rng, double lambda)
{
    if (!(lambda > 0))
        return 0;
    if (lambda < 10) {
        /* Inversion by sequential search: exact, O(lambda) expected. */
        double p = exp(-lambda), f = p, u = sci_rng_uniform(rng);
        double k = 0;
        while (u > f && k < 1000) {
            k += 1;
            p *= lambda / k;
            f += p;
        }
        return k;
    }
    /* PTRS: W. Hörmann, "The transformed rejection method for generating Poisson random variables" (1993). */
    double slam = sqrt(lambda), loglam = log(lambda);
    double b = 0.931 + 2.53 * slam, a = -0.059 + 0.02483 * b;
    double invalpha = 1.1239 + 1.1328 / (b - 3.4), vr = 0.9277 - 3.6224 / (b - 2);
    for (;;) {
        double u = sci_rng_uniform(rng) - 0.5, v = sci_rng_uniform(rng);
        double us = 0.5 - fabs(u);
        double k = floor((2 * a / us + b) * u + lambda + 0.43);
        if (us >= 0.07 && v <= vr)
            return k;
        if (k < 0 || (us < 0.013 && v > us))
            continue;
        if (log(v) + log(invalpha) - log(a / (us * us) + b) <= -lambda + k * loglam - lgamma(k + 1))
            return k;
    }
}
