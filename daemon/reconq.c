/* daemon/reconq.c — the persisted reconstruction queue (see the header). */
#include "daemon/reconq.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "base/file.h"
#include "base/json.h"
#include "daemon/reconout.h"

#define RECONQ_DIR "recon-queue"

static void dir_of(scicapd_store *st, char *buf, size_t n)
{
    snprintf(buf, n, "%s/" RECONQ_DIR, scicapd_store_root(st));
}

static int ensure_dir(scicapd_store *st, char *dir, size_t n, sci_error *err)
{
    dir_of(st, dir, n);
    if (mkdir(dir, 0750) != 0 && errno != EEXIST)
        return sci_error_set(err, -errno, "%s: cannot create: %s", dir, strerror(errno));
    return 0;
}

static json_t *item_json(const scicapd_job *j)
{
    const scicapd_recon_spec *s = &j->recon.spec;
    json_t *params = scicapd_recon_spec_json_plain(s); /* method, preset and every parameter */
    if (!params)
        return NULL;
    json_t *method = json_incref(json_object_get(params, "method"));
    json_t *preset = json_incref(json_object_get(params, "preset"));
    json_object_del(params, "method");
    json_object_del(params, "preset");
    json_t *o = json_pack("{s:s, s:I, s:o, s:o, s:o}", "capture", j->recon.capture_id, "owner", (json_int_t)j->owner,
                          "method", method, "preset", preset, "params", params);
    json_t *b = o ? scicapd_recon_budget_json(s) : NULL;
    if (b)
        json_object_set_new(o, "budget", b);
    return o;
}

/* The atomic writers' flags for this store: fsync'd only with storage.fsync. */
static unsigned fsync_flags(const scicapd_store *st)
{
    return scicapd_store_fsync_on(st) ? 0 : SCI_FILE_NO_SYNC;
}

int scicapd_reconq_save(scicapd_store *st, scicapd_job *j, sci_error *err)
{
    char dir[1100], path[1300];
    int rc;
    if ((rc = ensure_dir(st, dir, sizeof dir, err)) < 0)
        return rc;
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    char name[sizeof j->persisted];
    snprintf(name, sizeof name, "r-%020lld-%llu.json", (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec,
             (unsigned long long)j->id);
    snprintf(path, sizeof path, "%s/%s", dir, name);
    json_t *o = item_json(j);
    char *text = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    size_t len = text ? strlen(text) : 0;
    char *line = text ? realloc(text, len + 2) : NULL;
    if (!line) {
        free(text);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
    }
    memcpy(line + len, "\n", 2);
    /* beside, then renamed (a dot and .tmp: an interrupted save is removed at the next load) */
    rc = sci_file_write_atomic(path, line, len + 1, 0640, fsync_flags(st), err);
    free(line);
    if (rc < 0)
        return sci_error_set(err, rc, "%s: cannot save the queued reconstruction: %s", path, sci_strerror(rc));
    snprintf(j->persisted, sizeof j->persisted, "%s", name);
    return 0;
}

/* ROOT/recon-queue/r-<...>.ckpt for j's r-<...>.json (and the name alone in *name); -ENOENT when not persisted. */
static int ckpt_path(scicapd_store *st, const scicapd_job *j, char *path, size_t n, char *name, size_t nn)
{
    size_t l = strlen(j->persisted);
    if (l < 6)
        return -ENOENT;
    char dir[1100];
    dir_of(st, dir, sizeof dir);
    snprintf(name, nn, "%.*s.ckpt", (int)(l - 5), j->persisted);
    snprintf(path, n, "%s/%s", dir, name);
    return 0;
}

void scicapd_reconq_drop(scicapd_store *st, const scicapd_job *j)
{
    if (!j->persisted[0])
        return;
    char dir[1100], path[1300], name[128];
    dir_of(st, dir, sizeof dir);
    snprintf(path, sizeof path, "%s/%s", dir, j->persisted);
    unlink(path);
    if (ckpt_path(st, j, path, sizeof path, name, sizeof name) == 0)
        unlink(path);
}

int scicapd_reconq_checkpoint_save(scicapd_store *st, const scicapd_job *j, const void *blob, size_t bytes,
                                   sci_error *err)
{
    char path[1300], name[128];
    if (ckpt_path(st, j, path, sizeof path, name, sizeof name) < 0)
        return sci_error_set(err, -ENOENT, "job %llu has no saved entry", (unsigned long long)j->id);
    int rc = sci_file_write_atomic(path, blob, bytes, 0640, fsync_flags(st), err);
    if (rc < 0)
        return sci_error_set(err, rc, "%s: cannot save the checkpoint: %s", path, sci_strerror(rc));
    return 0;
}

int scicapd_reconq_checkpoint_load(scicapd_store *st, const scicapd_job *j, void **blob, size_t *bytes,
                                   sci_error *err)
{
    char path[1300], name[128];
    *blob = NULL;
    *bytes = 0;
    if (ckpt_path(st, j, path, sizeof path, name, sizeof name) < 0)
        return 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return errno == ENOENT ? 0 : sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    struct stat sb;
    unsigned char *buf = NULL;
    int rc = 0;
    if (fstat(fd, &sb) != 0 || sb.st_size <= 0 || !(buf = malloc((size_t)sb.st_size))) {
        rc = sci_error_set(err, sb.st_size <= 0 ? SCI_EFORMAT : -ENOMEM, "%s: empty or unreadable", path);
    } else {
        size_t got = 0;
        while (got < (size_t)sb.st_size) {
            ssize_t r = read(fd, buf + got, (size_t)sb.st_size - got);
            if (r < 0 && errno == EINTR)
                continue;
            if (r <= 0)
                break;
            got += (size_t)r;
        }
        if (got != (size_t)sb.st_size)
            rc = sci_error_set(err, -EIO, "%s: short read", path);
    }
    close(fd);
    if (rc < 0) {
        free(buf);
        return rc;
    }
    *blob = buf;
    *bytes = (size_t)sb.st_size;
    return 1;
}

/* Parse one file into *it. SCI_EFORMAT (or the resolver's code) with err positioned in the file. */
static int item_read(const char *path, scicapd_reconq_item *it, sci_error *err)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    char buf[16384]; /* an entry is a few hundred bytes (a NeRF method's, ~2 KB): anything larger is not ours */
    size_t len = fread(buf, 1, sizeof buf, f);
    int big = !feof(f);
    fclose(f);
    if (big)
        return sci_error_set(err, SCI_EFORMAT, "%s: larger than %zu bytes", path, sizeof buf);
    sci_json_doc *doc;
    int rc = sci_json_doc_load_string(&doc, path, buf, len, err);
    if (rc < 0)
        return rc;
    const json_t *root = sci_json_doc_root(doc);
    static const char *const keys[] = {"capture", "owner", "method", "preset", "params", "budget", NULL};
    const char *cap = NULL, *method = NULL, *preset = NULL;
    long long owner = 0;
    double budget = 0, predicted = 0, expected = 0;
    const json_t *b = json_object_get(root, "budget");
    if (!json_is_object(root)) {
        rc = sci_json_fail(doc, err, "", "must be an object");
        goto out;
    }
    if ((rc = sci_json_check_keys(doc, root, "", keys, err)) < 0 ||
        (rc = sci_json_get_string(doc, root, "", "capture", 1, &cap, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "owner", 1, 0, 0xFFFFFFFELL, &owner, err)) < 0 ||
        (rc = sci_json_get_string(doc, root, "", "method", 1, &method, err)) < 0 ||
        (rc = sci_json_get_string(doc, root, "", "preset", 1, &preset, err)) < 0)
        goto out;
    if (b && (!json_is_object(b) ||
              (rc = sci_json_get_double(doc, b, "budget", "budget_s", 1, 1e-6, 1e6, &budget, err)) < 0 ||
              (rc = sci_json_get_double(doc, b, "budget", "predicted_s", 1, 0, 1e9, &predicted, err)) < 0 ||
              (rc = sci_json_get_double(doc, b, "budget", "expected_psnr_db", 1, -1e3, 1e3, &expected, err)) < 0)) {
        rc = rc < 0 ? rc : sci_json_fail(doc, err, "budget", "must be an object");
        goto out;
    }
    if (!cap[0] || strlen(cap) >= sizeof it->capture_id || strchr(cap, '/') || cap[0] == '.') {
        rc = sci_json_fail(doc, err, "capture", "not a capture id: \"%.64s\"", cap);
        goto out;
    }
    /* a budget's setting is stored as its parameters: resolve them on the default preset, then restore */
    if ((rc = scicapd_recon_spec_resolve(method, strcmp(preset, "budget") == 0 ? "default" : preset, doc,
                                         json_object_get(root, "params"), "params", &it->spec, err)) < 0)
        goto out;
    if (b) {
        const char *setting = json_string_value(json_object_get(b, "setting"));
        snprintf(it->spec.budget_setting, sizeof it->spec.budget_setting, "%s", setting ? setting : "");
        snprintf(it->spec.preset, sizeof it->spec.preset, "budget");
        it->spec.budget_s = budget;
        it->spec.predicted_s = predicted;
        it->spec.expected_db = expected;
    }
    snprintf(it->capture_id, sizeof it->capture_id, "%s", cap);
    it->owner = (uid_t)owner;
out:
    sci_json_doc_free(doc);
    return rc;
}

/* 1 when the job saved as `file` already published its output: a recon/<method>[.N]/result.json of its capture
 * names this entry as the job that wrote it (daemon/workers.c). The daemon died between the publish and the
 * removal of the entry; running it again would only add the same result a second time. */
static int item_published(scicapd_store *st, const scicapd_reconq_item *it, const char *file)
{
    char dir[1100];
    sci_error e = {0};
    if (scicapd_store_capture_dir(st, it->capture_id, dir, sizeof dir, &e) < 0)
        return 0;
    return scicapd_reconout_published_by(dir, it->spec.method->name, file);
}

static int by_name(const void *a, const void *b)
{
    return strcmp(((const scicapd_reconq_item *)a)->file, ((const scicapd_reconq_item *)b)->file);
}

int scicapd_reconq_load(scicapd_store *st, const sci_log *log, scicapd_reconq_item **items, int *n, sci_error *err)
{
    char dir[1100];
    int rc;
    *items = NULL;
    *n = 0;
    if ((rc = ensure_dir(st, dir, sizeof dir, err)) < 0)
        return rc;
    DIR *d = opendir(dir);
    if (!d)
        return sci_error_set(err, -errno, "%s: %s", dir, strerror(errno));
    scicapd_reconq_item *v = NULL;
    int len = 0, cap = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        char path[1400];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (e->d_name[0] == '.') {
            if (strstr(e->d_name, ".tmp")) /* a save interrupted before its rename: never queued */
                unlink(path);
            continue;
        }
        size_t nl = strlen(e->d_name);
        if (strncmp(e->d_name, "r-", 2) == 0 && nl > 5 && nl < 200 && strcmp(e->d_name + nl - 5, ".ckpt") == 0) {
            /* a checkpoint outlives its entry only if a stop fell between their removals: it is of no use */
            char entry[1400];
            struct stat sb;
            snprintf(entry, sizeof entry, "%s/%.*s.json", dir, (int)(nl - 5), e->d_name);
            if (stat(entry, &sb) != 0 && errno == ENOENT)
                unlink(path);
            continue;
        }
        if (strncmp(e->d_name, "r-", 2) != 0 || nl < 6 || strcmp(e->d_name + nl - 5, ".json") != 0 ||
            nl >= sizeof v->file)
            continue;
        if (len == cap) {
            int nc = cap ? cap * 2 : 16;
            scicapd_reconq_item *nv = realloc(v, (size_t)nc * sizeof *nv);
            if (!nv) {
                closedir(d);
                free(v);
                return sci_error_set(err, -ENOMEM, "%s: out of memory", dir);
            }
            v = nv;
            cap = nc;
        }
        scicapd_reconq_item *it = &v[len];
        memset(it, 0, sizeof *it);
        sci_error e2 = {0};
        if (item_read(path, it, &e2) < 0) {
            char bad[1400];
            snprintf(bad, sizeof bad, "%s/bad-%s", dir, e->d_name);
            rename(path, bad);
            sci_log_write(log, SCI_LOG_ERR, "queued reconstruction not resumed: %s (kept as %s)", e2.msg, bad);
            continue;
        }
        if (item_published(st, it, e->d_name)) {
            char ckpt[1400];
            unlink(path);
            snprintf(ckpt, sizeof ckpt, "%s/%.*s.ckpt", dir, (int)(nl - 5), e->d_name);
            unlink(ckpt);
            sci_log_write(log, SCI_LOG_NOTICE, "queued reconstruction %s of %s was already published by the job "
                          "saved as %s: not run again", it->spec.method->name, it->capture_id, e->d_name);
            continue;
        }
        snprintf(it->file, sizeof it->file, "%s", e->d_name);
        len++;
    }
    closedir(d);
    if (len > 0) /* qsort(NULL, 0, ...) is undefined (UBSan) */
        qsort(v, (size_t)len, sizeof *v, by_name);
    *items = v;
    *n = len;
    return 0;
}
