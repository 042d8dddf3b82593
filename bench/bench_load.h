/* bench/bench_load.h — the load average a benchmark records beside its figures (2 shared cores: a figure taken
 * at load 3 means another job had a core). Header-only: the benchmarks are single-file programs. */
#ifndef SCICAP_BENCH_LOAD_H
#define SCICAP_BENCH_LOAD_H

#include <stdio.h>
#include <stdlib.h>

/* "1-min 5-min 15-min" into buf, or "?" when the kernel does not say. */
static inline void bench_loadavg(char *buf, size_t n)
{
    double l[3];
    if (getloadavg(l, 3) == 3)
        snprintf(buf, n, "%.2f %.2f %.2f", l[0], l[1], l[2]);
    else
        snprintf(buf, n, "?");
}

#endif
