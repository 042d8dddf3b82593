/* daemon/import_args.h — the "import" command's arguments (docs/protocol.md) and the descriptors that came with
 * the request line (daemon/import.h reads them). Kept apart from the import itself so that the job table
 * (daemon/jobs.h), which owns them, depends on nothing that depends on it.
 */
#ifndef SCICAP_DAEMON_IMPORT_ARGS_H
#define SCICAP_DAEMON_IMPORT_ARGS_H

#include "base/error.h"
#include "daemon/protocol.h"

#define SCICAPD_IMPORT_MAX_FILES 250  /* one sendmsg carries at most 253 descriptors */
#define SCICAPD_IMPORT_NAME_MAX 64

typedef struct scicapd_import_args {
    int folder;                       /* 1: a problem folder's files; 0: one .mat (+ the mask .mat) */
    int nfiles;                       /* names and descriptors, in the order they were passed */
    char names[SCICAPD_IMPORT_MAX_FILES][SCICAPD_IMPORT_NAME_MAX];
    int fds[SCICAPD_IMPORT_MAX_FILES]; /* owned: closed by scicapd_import_args_free; -1 once closed */
    int data_index, mask_index;       /* .mat: the data file, the mask file (-1: masks in the data file) */
    char mask_var[SCICAPD_IMPORT_NAME_MAX], meas_var[SCICAPD_IMPORT_NAME_MAX], truth_var[SCICAPD_IMPORT_NAME_MAX];
    double white;                     /* 0: 255; SCI_MAT_WHITE_AUTO: from the data; else the white level */
    int reconstruct;                  /* reconstruct every imported snapshot */
    int allow_large;                  /* lift io/limits.h (`--allow-large`): admins only (checked by the caller) */
    scicapd_recon_spec recon;
} scicapd_import_args;

/* Check 5 for "import": the arguments (docs/protocol.md) and the descriptors that came with the line (fds[0..
 * nfds-1], taken over: kept in *out, or closed on error). *out is malloc'd; free with scicapd_import_args_free.
 * SCI_ECONFIG-style errors positioned in the request (bad_arguments). */
int scicapd_args_import(const scicapd_request *r, const scicapd_config *cfg, int *fds, int nfds,
                        scicapd_import_args **out, sci_error *err);
void scicapd_import_args_free(scicapd_import_args *a); /* NULL is harmless */
/* Close the descriptors (once their bytes are copied); the arguments stay. */
void scicapd_import_args_close(scicapd_import_args *a);

#endif
