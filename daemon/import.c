/* daemon/import.c — captures from a client's files, read through its descriptors (see the header). */
#include "daemon/import.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/clock.h"
#include "daemon/package.h"
#include "io/limits.h"
#include "io/problem_dir.h"
#include "io/recon_store.h"
#include "io/source.h"
#include "io/staging.h"

static void close_fds(int *fds, int n)
{
    for (int i = 0; i < n; i++)
        if (fds[i] >= 0) {
            close(fds[i]);
            fds[i] = -1;
        }
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

/* Copy the bytes behind fd (a regular file: pipes and devices could block a worker forever) to path, from
 * offset 0 without moving the descriptor's offset (the client shares it). *total counts against the limit. */
static int copy_fd(int fd, const char *name, const char *path, size_t *total, sci_error *err)
{
    struct stat sb;
    if (fstat(fd, &sb) != 0)
        return sci_error_set(err, -errno, "%s: %s", name, strerror(errno));
    if (!S_ISREG(sb.st_mode))
        return sci_error_set(err, -EINVAL, "%s: not a regular file (pass an open file)", name);
    *total += (size_t)sb.st_size;
    if (*total > SCI_IO_LIMIT_INPUT_BYTES)
        return sci_error_set(err, -EFBIG, "%s: the files passed hold more than the input limit of %.1f GB",
                             name, (double)SCI_IO_LIMIT_INPUT_BYTES / 1e9);
    int out = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (out < 0)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    enum { CHUNK = 1 << 16 };
    char *buf = malloc(CHUNK);
    if (!buf) {
        close(out);
        return sci_error_set(err, -ENOMEM, "import: out of memory");
    }
    off_t off = 0;
    int rc = 0;
    for (;;) {
        ssize_t n = pread(fd, buf, CHUNK, off);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0) {
            rc = sci_error_set(err, -errno, "%s: read: %s", name, strerror(errno));
            break;
        }
        if (n == 0)
            break;
        for (ssize_t w = 0; w < n;) {
            ssize_t m = write(out, buf + w, (size_t)(n - w));
            if (m < 0 && errno == EINTR)
                continue;
            if (m <= 0) {
                rc = sci_error_set(err, -EIO, "%s: %s", path, strerror(errno));
                break;
            }
            w += m;
        }
        if (rc < 0)
            break;
        off += n;
        if ((size_t)off > (size_t)sb.st_size + (1 << 20)) { /* a file that keeps growing while we read */
            rc = sci_error_set(err, -EFBIG, "%s: grew past %lld bytes while being read", name,
                               (long long)sb.st_size);
            break;
        }
    }
    free(buf);
    if (close(out) != 0 && rc == 0)
        rc = sci_error_set(err, -EIO, "%s: %s", path, strerror(errno));
    return rc;
}

static void imports_dir(scicapd_store *st, char *buf, size_t n)
{
    snprintf(buf, n, "%s/imports", scicapd_store_root(st));
}

void scicapd_import_sweep(scicapd_store *st)
{
    char d[1100];
    imports_dir(st, d, sizeof d);
    sci_staging_remove(d);
}

/* What storing and reconstructing every snapshot `path` declares would write, held against lim as `scicap recon`
 * holds the same file (its message names the client's file, the figure and the override). */
static int check_output(const scicapd_import_args *a, const char *path, const sci_mat_options *o,
                        const sci_io_limits *lim, sci_error *err)
{
    long long w, h, n, k;
    int rc = sci_source_probe(path, a->folder ? NULL : o, &w, &h, &n, &k, err);
    if (rc < 0 || w <= 0 || h <= 0 || n <= 0 || k <= 0)
        return rc; /* a folder that does not state its sizes: the reader checks each part against lim */
    double bytes, files;
    sci_recon_store_estimate(w, h, n, k, &bytes, &files);
    char what[1500];
    snprintf(what, sizeof what, "%s (%lld snapshot(s) of %lldx%lld pixels, %lld frames each; admins may pass "
             "allow_large)", path, k, w, h, n);
    return sci_io_limits_check_output(lim, what, bytes, files + 1, err);
}

int scicapd_import_read(scicapd_store *st, uint64_t job, scicapd_import_args *a, sci_problem ***out, int *k,
                        sci_mat_info *info, sci_error *err)
{
    char base[1100], stage[1200], path[1300], mask[1300];
    imports_dir(st, base, sizeof base);
    if (mkdir(base, 0700) != 0 && errno != EEXIST)
        return sci_error_set(err, -errno, "%s: %s", base, strerror(errno));
    snprintf(stage, sizeof stage, "%s/.import-%llu", base, (unsigned long long)job);
    sci_staging_remove(stage);
    if (mkdir(stage, 0700) != 0)
        return sci_error_set(err, -errno, "%s: %s", stage, strerror(errno));
    size_t total = 0;
    int rc = 0;
    for (int i = 0; i < a->nfiles && rc == 0; i++) {
        snprintf(path, sizeof path, "%s/%s", stage, a->names[i]);
        rc = copy_fd(a->fds[i], a->names[i], path, &total, err);
    }
    close_fds(a->fds, a->nfiles); /* copied: the client's files are not touched again */
    memset(info, 0, sizeof *info);
    sci_io_limits lim;
    if (a->allow_large)
        sci_io_limits_none(&lim);
    else
        sci_io_limits_default(&lim);
    if (a->folder) {
        snprintf(path, sizeof path, "%s", stage);
    } else {
        snprintf(path, sizeof path, "%s/%s", stage, a->names[a->data_index]);
        if (a->mask_index >= 0)
            snprintf(mask, sizeof mask, "%s/%s", stage, a->names[a->mask_index]);
    }
    sci_mat_options o = {.mask_path = !a->folder && a->mask_index >= 0 ? mask : NULL,
                         .mask_var = a->mask_var[0] ? a->mask_var : NULL,
                         .meas_var = a->meas_var[0] ? a->meas_var : NULL,
                         .truth_var = a->truth_var[0] ? a->truth_var : NULL, .white = a->white, .limits = &lim};
    if (rc == 0)
        rc = check_output(a, path, &o, &lim, err);
    if (rc == 0 && a->folder)
        rc = sci_problem_dir_read_opts(stage, &lim, out, k, err);
    else if (rc == 0)
        rc = sci_mat_read_opts(path, &o, out, k, info, err);
    if (rc < 0) { /* messages name the staged copy: say the client's name instead */
        char *at = strstr(err->msg, stage);
        if (at) {
            char msg[sizeof err->msg];
            size_t skip = strlen(stage) + 1;
            snprintf(msg, sizeof msg, "%.*s%s", (int)(at - err->msg), err->msg,
                     strlen(at) >= skip ? at + skip : at);
            snprintf(err->msg, sizeof err->msg, "%s", msg);
        }
    }
    sci_staging_remove(stage);
    return rc;
}

int scicapd_import_store(scicapd_store *st, const scicapd_import_args *a, const sci_mat_info *info, uid_t owner,
                         uint64_t job, int index, sci_problem *p, char *id, char *dir, sci_error *err)
{
    scicapd_snapshot *s = calloc(1, sizeof *s);
    if (!s) {
        sci_problem_free(p);
        return sci_error_set(err, -ENOMEM, "import: out of memory");
    }
    s->problem = p;
    s->index = index;
    json_t *names = json_array();
    for (int i = 0; i < a->nfiles; i++)
        json_array_append_new(names, json_string(a->names[i]));
    json_t *imp = json_pack("{s:s, s:o, s:I, s:i}", "kind", a->folder ? "folder" : "mat", "files", names, "owner",
                            (json_int_t)owner, "snapshot_index", index);
    if (!a->folder) {
        json_object_set_new(imp, "white", json_real(info->white));
        json_object_set_new(imp, "mask_variable", json_string(info->mask_var));
        json_object_set_new(imp, "mask_per_snapshot", json_boolean(info->mask_per_snapshot));
        if (info->how[0])
            json_object_set_new(imp, "scale_auto", json_string(info->how));
    }
    s->meta = json_pack("{s:s, s:i, s:{s:s, s:s}, s:I, s:i, s:o, s:o}", "format", "scicap-capture", "version", 1,
                        "software", "name", "scicapd", "version", SCICAP_VERSION, "job", (json_int_t)job,
                        "snapshot_index", index, "imported", imp, "captured",
                        scicapd_time_json(sci_clock_mono_ns()));
    int rc = s->meta ? scicapd_store_write_capture(st, s, err) : sci_error_set(err, -ENOMEM, "out of memory");
    if (rc == 0) {
        snprintf(id, 32, "%s", s->capture_id);
        snprintf(dir, 1100, "%s", s->dir);
    }
    scicapd_snapshot_free(NULL, s);
    return rc;
}
