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
#include "daemon/timestamp.h"
#include "io/limits.h"
#include "io/problem_dir.h"
#include "io/recon_store.h"
#include "io/source.h"
#include "io/staging.h"


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
    scicapd_import_args_close(a); /* copied: the client's files are not touched again */
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
