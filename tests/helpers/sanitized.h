/* tests/helpers/sanitized.h — SANITIZED: 1 in a build under AddressSanitizer (make SANITIZE=1), else 0.
 *
 * Tests that run a solver or a daemon for long use it to shorten the run (fewer iterations, a smaller crop) where
 * ASan's cost would make the full one too slow, and keep the full check, golden figures included, for the
 * optimised build. A plain C constant, so both branches always compile. */
#ifndef SCICAP_TESTS_SANITIZED_H
#define SCICAP_TESTS_SANITIZED_H

#if defined(__SANITIZE_ADDRESS__)
#define SANITIZED 1
#else
#define SANITIZED 0
#endif

#endif
