/* daemon/import_args.c — the "import" command's arguments and the descriptors passed with it (see the header). */
#include "daemon/import_args.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "io/matfile.h"

static void close_fds(int *fds, int n)
{
    for (int i = 0; i < n; i++)
        if (fds[i] >= 0) {
            close(fds[i]);
            fds[i] = -1;
        }
}

void scicapd_import_args_close(scicapd_import_args *a)
{
    close_fds(a->fds, a->nfiles);
}

void scicapd_import_args_free(scicapd_import_args *a)
{
    if (!a)
        return;
    close_fds(a->fds, a->nfiles);
    free(a);
}

/* A file name the staging folder can hold: 1..63 printable bytes, no '/', not "." or ".." or hidden. */
static int good_name(const char *s)
{
    size_t n = strlen(s);
    if (n == 0 || n >= SCICAPD_IMPORT_NAME_MAX || s[0] == '.')
        return 0;
    for (const char *p = s; *p; p++)
        if (!isprint((unsigned char)*p) || *p == '/')
            return 0;
    return 1;
}

static int find_name(const scicapd_import_args *a, const char *s)
{
    for (int i = 0; i < a->nfiles; i++)
        if (strcmp(a->names[i], s) == 0)
            return i;
    return -1;
}

static int get_var(const scicapd_request *r, const char *key, char *buf, size_t n, sci_error *err)
{
    const char *s = NULL;
    int rc = sci_json_get_string(r->doc, r->args, "args", key, 0, &s, err);
    if (rc != 0)
        return rc < 0 ? rc : 0;
    char p[64];
    if (!s[0] || strlen(s) >= n)
        return sci_json_fail(r->doc, err, sci_json_path_key(p, sizeof p, "args", key), "a variable name of 1..%zu "
                             "bytes", n - 1);
    snprintf(buf, n, "%s", s);
    return 0;
}

int scicapd_args_import(const scicapd_request *r, const scicapd_config *cfg, int *fds, int nfds,
                        scicapd_import_args **out, sci_error *err)
{
    static const char *const keys[] = {"files", "kind", "mask", "mask_var", "meas_var", "truth_var", "scale",
                                       "reconstruct", "method", "preset", "params", "allow_large", NULL};
    static const char *const kinds[] = {"mat", "folder", NULL};
    *out = NULL;
    scicapd_import_args *a = calloc(1, sizeof *a);
    if (!a) {
        close_fds(fds, nfds);
        return sci_error_set(err, -ENOMEM, "import: out of memory");
    }
    a->mask_index = -1;
    for (int i = 0; i < SCICAPD_IMPORT_MAX_FILES; i++)
        a->fds[i] = -1; /* until the descriptors are taken, at the very end: a refusal before closes only theirs */
    int rc, kind = 0;
    const json_t *files = r->args ? json_object_get(r->args, "files") : NULL, *v;
    size_t i;
    if (!r->args || !json_is_object(r->args)) {
        rc = sci_json_fail(r->doc, err, "args", "args.files is required: the names of the passed files");
        goto fail;
    }
    if ((rc = sci_json_check_keys(r->doc, r->args, "args", keys, err)) < 0 ||
        (rc = sci_json_get_enum(r->doc, r->args, "args", "kind", 0, kinds, &kind, err)) < 0)
        goto fail;
    a->folder = kind == 1;
    if (!json_is_array(files) || json_array_size(files) < 1 || json_array_size(files) > SCICAPD_IMPORT_MAX_FILES) {
        rc = sci_json_fail(r->doc, err, "args.files", "an array of 1..%d file names, one per passed descriptor",
                           SCICAPD_IMPORT_MAX_FILES);
        goto fail;
    }
    json_array_foreach(files, i, v) {
        const char *s = json_string_value(v);
        if (!s || !good_name(s) || find_name(a, s) >= 0) {
            rc = sci_json_fail(r->doc, err, "args.files", "entry %zu: a file name (no '/', not hidden, at most "
                               "%d bytes, each once)", i, SCICAPD_IMPORT_NAME_MAX - 1);
            goto fail;
        }
        snprintf(a->names[a->nfiles++], SCICAPD_IMPORT_NAME_MAX, "%s", s);
    }
    const char *mask = NULL;
    if ((rc = sci_json_get_string(r->doc, r->args, "args", "mask", 0, &mask, err)) < 0 ||
        (rc = get_var(r, "mask_var", a->mask_var, sizeof a->mask_var, err)) < 0 ||
        (rc = get_var(r, "meas_var", a->meas_var, sizeof a->meas_var, err)) < 0 ||
        (rc = get_var(r, "truth_var", a->truth_var, sizeof a->truth_var, err)) < 0)
        goto fail;
    const json_t *scale = json_object_get(r->args, "scale");
    if (scale && json_is_string(scale) && strcmp(json_string_value(scale), "auto") == 0)
        a->white = SCI_MAT_WHITE_AUTO;
    else if (scale && (!json_is_number(scale) || !(json_number_value(scale) > 0) ||
                       !isfinite(json_number_value(scale)))) {
        rc = sci_json_fail(r->doc, err, "args.scale", "\"auto\" or the white level, a number > 0");
        goto fail;
    } else if (scale) {
        a->white = json_number_value(scale);
    }
    if (a->folder) {
        if (mask || a->mask_var[0] || a->meas_var[0] || a->truth_var[0] || scale) {
            rc = sci_json_fail(r->doc, err, "args", "mask, mask_var, meas_var, truth_var and scale are for a .mat; "
                               "a problem folder names its parts and its scale itself");
            goto fail;
        }
        if (find_name(a, "problem.json") < 0) {
            rc = sci_json_fail(r->doc, err, "args.files", "a problem folder's files include problem.json");
            goto fail;
        }
    } else {
        if (mask && (a->mask_index = find_name(a, mask)) < 0) {
            rc = sci_json_fail(r->doc, err, "args.mask", "\"%.64s\" is not one of args.files", mask);
            goto fail;
        }
        if (a->nfiles != (a->mask_index >= 0 ? 2 : 1)) {
            rc = sci_json_fail(r->doc, err, "args.files", "a .mat import passes the data file%s",
                               a->mask_index >= 0 ? " and the mask file" : " (and, with args.mask, the mask file)");
            goto fail;
        }
        a->data_index = a->mask_index == 0 ? 1 : 0;
    }
    a->reconstruct = 0;
    if ((rc = sci_json_get_bool(r->doc, r->args, "args", "reconstruct", 0, &a->reconstruct, err)) < 0 ||
        (rc = sci_json_get_bool(r->doc, r->args, "args", "allow_large", 0, &a->allow_large, err)) < 0)
        goto fail;
    const char *method = cfg->recon_method, *preset = cfg->recon_preset;
    if ((rc = sci_json_get_string(r->doc, r->args, "args", "method", 0, &method, err)) < 0 ||
        (rc = sci_json_get_string(r->doc, r->args, "args", "preset", 0, &preset, err)) < 0)
        goto fail;
    if ((rc = scicapd_recon_spec_resolve(method, preset, r->doc, json_object_get(r->args, "params"), "args.params",
                                         &a->recon, err)) < 0)
        goto fail;
    /* last, so that every argument is checked (and fuzzed) with or without descriptors */
    if (nfds != a->nfiles) {
        rc = sci_json_fail(r->doc, err, "args.files", "%d files named but %d descriptors passed: send one open "
                           "descriptor per file (SCM_RIGHTS) with the request line, in the same order", a->nfiles,
                           nfds);
        goto fail;
    }
    memcpy(a->fds, fds, (size_t)nfds * sizeof *fds); /* ours now */
    *out = a;
    return 0;
fail:
    close_fds(fds, nfds);
    scicapd_import_args_free(a);
    return rc;
}
