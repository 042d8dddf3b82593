/* libFuzzer target: scicapd's control protocol parser (daemon/protocol.h), read-only use.
 *
 * The input is one request line (no newline), as a client would send it: checks 2–4 (JSON, version, command) in
 * scicapd_request_parse, then check 5, each command's typed arguments, against the built-in configuration. Every
 * path must return a code and free what it made (LeakSanitizer runs under libFuzzer). */
#include <stdint.h>
#include <stdlib.h>

#include "daemon/config.h"
#include "daemon/import.h"
#include "daemon/protocol.h"

static scicapd_config *cfg;

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sci_error err = {0};
    if (!cfg && scicapd_config_default(&cfg, &err) < 0)
        abort();
    scicapd_request req = {0};
    if (scicapd_request_parse((const char *)data, size, &req, &err) == SCICAPD_OK) {
        switch (req.cmd) {
        case SCICAPD_CMD_CAPTURE: {
            scicapd_capture_args a;
            scicapd_args_capture(&req, cfg, &a, &err);
            break;
        }
        case SCICAPD_CMD_CALIBRATE: {
            scicapd_calib_args a;
            scicapd_args_calibrate(&req, cfg, &a, &err);
            break;
        }
        case SCICAPD_CMD_RECONSTRUCT: {
            scicapd_recon_args a;
            scicapd_args_reconstruct(&req, cfg, &a, &err);
            break;
        }
        case SCICAPD_CMD_CANCEL: {
            uint64_t job;
            scicapd_args_cancel(&req, &job, &err);
            break;
        }
        case SCICAPD_CMD_SIMULATE: {
            scicapd_simulate_args a;
            scicapd_args_simulate(&req, &a, &err);
            break;
        }
        case SCICAPD_CMD_IMPORT: { /* no descriptors: every option is checked before any is needed */
            scicapd_import_args *a = NULL;
            scicapd_args_import(&req, cfg, NULL, 0, &a, &err);
            scicapd_import_args_free(a);
            break;
        }
        default: scicapd_args_none(&req, &err); break;
        }
    }
    char *reply = scicapd_reply_error(req.id, SCICAPD_E_BAD_ARGUMENTS, err.msg);
    free(reply);
    scicapd_request_clear(&req);
    return 0;
}
