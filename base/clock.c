#include "base/clock.h"

#include <sys/resource.h>
#include <time.h>

static int64_t read_clock(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

int64_t sci_clock_mono_ns(void) { return read_clock(CLOCK_MONOTONIC); }
int64_t sci_clock_real_ns(void) { return read_clock(CLOCK_REALTIME); }
int64_t sci_clock_cpu_ns(void) { return read_clock(CLOCK_PROCESS_CPUTIME_ID); }

int64_t sci_clock_peak_rss_bytes(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0)
        return -1;
    return (int64_t)ru.ru_maxrss * 1024; /* Linux reports KiB */
}
