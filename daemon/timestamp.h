/* daemon/timestamp.h — when something happened, as the records on disk say it (a capture's meta.json, a
 * calibration's record, an import's meta): the monotonic time the daemon measured it at, with the wall clock
 * read now beside it, so records compare with each other (mono) and with the outside world (realtime, utc).
 */
#ifndef SCICAP_DAEMON_TIMESTAMP_H
#define SCICAP_DAEMON_TIMESTAMP_H

#include <jansson.h>
#include <stdint.h>

/* {"mono_ns": mono_ns, "realtime_ns": now, "utc": now in ISO 8601, seconds} (new reference; NULL only when out
 * of memory). mono_ns: CLOCK_MONOTONIC, ns. Thread-safe. */
json_t *scicapd_time_json(int64_t mono_ns);

#endif
