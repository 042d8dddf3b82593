/* libFuzzer target: scicapd's configuration parser (daemon/config.h), read-only use.
 *
 * The input is the text of a configuration file. Whatever loads is copied, compared, turned back into JSON and
 * freed, the paths a reload takes. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "daemon/config.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = 0; /* the loader takes a C string, as read from a file */
    sci_error err = {0};
    scicapd_config *c = NULL, *d = NULL, *copy = NULL;
    if (scicapd_config_load_string(&c, "fuzz.json", text, &err) == 0) {
        if (scicapd_config_default(&d, &err) == 0) {
            scicapd_config_devices_differ(c, d);
            json_decref(scicapd_config_restart_keys(c, d));
        }
        if (scicapd_config_copy(&copy, c, &err) == 0)
            scicapd_config_free(copy);
        json_decref(scicapd_config_to_json(c));
        scicapd_config_mask_set(c, "default");
    }
    scicapd_config_free(c);
    scicapd_config_free(d);
    free(text);
    return 0;
}
