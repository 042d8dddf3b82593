/* base/clock.h — time sources. All values in nanoseconds (int64) or seconds (double), as named. */
#ifndef SCICAP_BASE_CLOCK_H
#define SCICAP_BASE_CLOCK_H

#include <stdint.h>

/* CLOCK_MONOTONIC, nanoseconds. The project's timestamp everywhere (docs/architecture.md, Contracts: Units). */
int64_t sci_clock_mono_ns(void);
/* CLOCK_REALTIME, nanoseconds since the epoch: only for human-facing metadata (meta.json). */
int64_t sci_clock_real_ns(void);
/* CPU time of the whole process (all threads), nanoseconds. */
int64_t sci_clock_cpu_ns(void);
/* Seconds between two monotonic readings. */
static inline double sci_clock_s(int64_t t0_ns, int64_t t1_ns) { return (double)(t1_ns - t0_ns) * 1e-9; }
/* Peak resident set size of this process, bytes (from getrusage). */
int64_t sci_clock_peak_rss_bytes(void);

#endif
