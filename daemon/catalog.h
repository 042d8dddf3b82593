/* daemon/catalog.h — the stored captures as the "captures" request lists them (docs/protocol.md): each complete
 * folder of ROOT/captures with its time, size and origin, and its reconstructions (recon/<method>[.N]/).
 *
 *     json_t *r = scicapd_catalog_list(root, 20, &err);
 *     // {"captures": [the newest 20, oldest first], "total": every capture stored}
 *
 * A capture: {"capture": "c000042", "time": "2025-01-31T10:00:00Z" (when it was taken or imported; null when its
 * meta.json does not say), "w", "h", "frames" (masks per snapshot), "source": "bench" | "import", "scene" (the
 * simulated bench's), "broken" (sync), "truth" (has the frames it saw), "recons": [...]}; a reconstruction:
 * {"folder": "gap-tv.2", "method", "psnr" (dB, only with truth), "residual" (‖y − Ax‖/‖y‖), "iterations",
 * "solve_s", "time" (when it was written), "budget" (what a budget chose, when one did)}, sorted by method, then
 * in the order they were written. A folder or file that cannot be read leaves its fields out; it never fails
 * the list.
 *
 * Cost: the names of ROOT/captures are read and sorted; only the listed captures' meta.json, problem.json and
 * result.json files are opened (a few KB each), on the caller's thread. Reentrant.
 */
#ifndef SCICAP_DAEMON_CATALOG_H
#define SCICAP_DAEMON_CATALOG_H

#include <jansson.h>

#include "base/error.h"

/* The newest `limit` captures under root/captures (0: all), oldest first, and the total. New reference, or NULL
 * with err set (-errno naming the folder, -ENOMEM). A missing captures/ folder is an empty list. */
json_t *scicapd_catalog_list(const char *root, long limit, sci_error *err);

#endif
