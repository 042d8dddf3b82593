/* daemon/calibs.c — the calibrations in use (see the header). */
#include "daemon/calibs.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_CALIB 64

typedef struct calib_entry {
    char key[96];            /* "dark" or "masks-<set>" */
    scicapd_calib c;
    int missing;             /* looked up in the store and not found */
} calib_entry;

struct scicapd_calibs {
    scicapd_store *store;
    const sci_log *log;
    calib_entry e[MAX_CALIB];
    int n;
};

int scicapd_calibs_new(scicapd_calibs **out, scicapd_store *store, const sci_log *log, sci_error *err)
{
    scicapd_calibs *c = calloc(1, sizeof *c);
    if (!c)
        return sci_error_set(err, -ENOMEM, "calibrations: out of memory");
    c->store = store;
    c->log = log;
    *out = c;
    return 0;
}

void scicapd_calibs_free(scicapd_calibs *c)
{
    if (!c)
        return;
    for (int i = 0; i < c->n; i++) {
        sci_cube_free(c->e[i].c.data);
        json_decref(c->e[i].c.record);
    }
    free(c);
}

const scicapd_calib *scicapd_calibs_get(scicapd_calibs *cs, const char *key)
{
    for (int i = 0; i < cs->n; i++)
        if (strcmp(cs->e[i].key, key) == 0)
            return cs->e[i].missing ? NULL : &cs->e[i].c;
    if (cs->n == MAX_CALIB)
        return NULL;
    calib_entry *c = &cs->e[cs->n++];
    memset(c, 0, sizeof *c);
    snprintf(c->key, sizeof c->key, "%s", key);
    sci_error err = {0};
    if (scicapd_store_load_calibration(cs->store, key, &c->c.data, &c->c.record, &err) < 0) {
        if (err.code != -ENOENT)
            sci_log_write(cs->log, SCI_LOG_WARNING, "calibration %s: %s", key, err.msg);
        c->missing = 1;
        return NULL;
    }
    c->c.counts_per_unit = json_number_value(json_object_get(c->c.record, "counts_per_unit"));
    return &c->c;
}

void scicapd_calibs_set(scicapd_calibs *cs, const char *key, sci_cube *data, json_t *record, double cpu)
{
    calib_entry *c = NULL;
    for (int i = 0; i < cs->n; i++)
        if (strcmp(cs->e[i].key, key) == 0)
            c = &cs->e[i];
    if (!c && cs->n < MAX_CALIB)
        c = &cs->e[cs->n++];
    if (!c) {
        sci_cube_free(data);
        json_decref(record);
        return;
    }
    sci_cube_free(c->c.data);
    json_decref(c->c.record);
    snprintf(c->key, sizeof c->key, "%s", key);
    c->c = (scicapd_calib){.data = data, .record = record, .counts_per_unit = cpu};
    c->missing = 0;
}
