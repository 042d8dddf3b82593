/* daemon/timestamp.c — time stamps for records on disk (see the header). */
#include "daemon/timestamp.h"

#include <time.h>

#include "base/clock.h"

json_t *scicapd_time_json(int64_t mono_ns)
{
    int64_t real = sci_clock_real_ns();
    time_t s = (time_t)(real / 1000000000);
    struct tm tm;
    char iso[64];
    gmtime_r(&s, &tm);
    strftime(iso, sizeof iso, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return json_pack("{s:I, s:I, s:s}", "mono_ns", (json_int_t)mono_ns, "realtime_ns", (json_int_t)real, "utc", iso);
}
