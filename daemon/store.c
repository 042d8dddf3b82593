/* daemon/store.c — capture folders written atomically, calibrations, recovery after a crash, writer thread. */
#include "daemon/store.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "base/file.h"
#include "base/json.h"
#include "io/image.h"
#include "io/problem_dir.h"
#include "io/staging.h"

#define STORE_MAX_WRITERS 16
/* Ids the durable high-water mark runs ahead of use: one fsync'd write per this many captures. A crash skips at
 * most this many - 1 ids; a clean close writes the exact mark. */
#define STORE_ID_BLOCK 16
#define STORE_IDS_FILE "ids.json"
/* Mask stacks whose shared folder is known this run, per kind: a mask set's snapshots hit it. Stacks above
 * STORE_MASK_CACHE_BYTES (a large DMD's) are not kept: hashed each time, as before the cache. */
#define STORE_MASK_CACHE 2
#define STORE_MASK_CACHE_BYTES (64u << 20)
enum { STORE_SHOWN, STORE_STACK };

struct scicapd_store {
    char root[1024];
    int fsync_on;
    atomic_int previews;
    const sci_log *log;
    pthread_mutex_t mu;
    unsigned long next_capture, next_calib;
    unsigned long mark_capture, mark_calib; /* durable in ROOT/ids.json: no id above them was handed out */
    int ids_ok;                             /* the mark was read or written: close may write the exact one */
    int lock_fd;                            /* ROOT/scicapd.lock, flock'd for the store's life; -1 before */
    pthread_t threads[STORE_MAX_WRITERS];
    int running;            /* writer threads started */
    scicapd_queue *q;
    scicapd_stored_fn on_stored;
    void *user;
    scicapd_timing *timing;  /* borrowed; may be NULL */
    /* mask stacks whose shared folder is known this run (under mu; oldest replaced): kind STORE_SHOWN for
     * ROOT/dmd_masks/<hash>, STORE_STACK for ROOT/mask_stacks/<hash> (checked against the masks) */
    struct {
        int kind;
        uint64_t hash;
        sci_cube *mask;
    } mask_cache[2 * STORE_MASK_CACHE];
    int mask_cache_next;
};

static int mkdir_p(const char *path, sci_error *err)
{
    char buf[1100];
    snprintf(buf, sizeof buf, "%s", path);
    for (char *p = buf + 1; *p; p++)
        if (*p == '/') {
            *p = '\0';
            if (mkdir(buf, 0750) != 0 && errno != EEXIST)
                return sci_error_set(err, -errno, "%s: cannot create folder: %s", buf, strerror(errno));
            *p = '/';
        }
    if (mkdir(buf, 0750) != 0 && errno != EEXIST)
        return sci_error_set(err, -errno, "%s: cannot create folder: %s", buf, strerror(errno));
    return 0;
}

static int is_partial(const char *name)
{
    return name[0] == '.' || strstr(name, ".tmp-") || strstr(name, ".old-") || strstr(name, ".partial");
}

/* Remove partial entries of `dir`; count complete ones named <prefix>NNNNNN and track the largest number. */
static void sweep(const char *dir, const char *prefix, unsigned long *max, int *complete, int *removed,
                  int recurse_recon)
{
    DIR *d = opendir(dir);
    if (!d)
        return;
    struct dirent *e;
    size_t pl = prefix ? strlen(prefix) : 0;
    while ((e = readdir(d))) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
            continue;
        char p[1400];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        if (is_partial(e->d_name)) {
            if (sci_staging_remove(p) == 0)
                (*removed)++;
            continue;
        }
        if (prefix && strncmp(e->d_name, prefix, pl) == 0) {
            const char *num = e->d_name + pl;
            const char *dash = strrchr(num, '-');
            unsigned long v = strtoul(dash ? dash + 1 : num, NULL, 10);
            if (v > *max)
                *max = v;
            if (complete)
                (*complete)++;
        }
        if (recurse_recon) {
            char r[1500];
            snprintf(r, sizeof r, "%s/recon", p);
            unsigned long dummy = 0;
            sweep(r, NULL, &dummy, NULL, removed, 0);
        }
    }
    closedir(d);
}

/* ROOT's own files (ids.json, capture.running, the calibration pointer) are replaced through base/file's atomic
 * writers: a crash mid-write leaves a temporary ".<name>.tmp-XXXXXX" beside them. Only such regular files go;
 * anything else in ROOT is the administrator's. */
static void sweep_root_temporaries(const char *root, int *removed)
{
    DIR *d = opendir(root);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d))) {
        struct stat st;
        if (e->d_name[0] == '.' && strstr(e->d_name, ".tmp-") &&
            fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISREG(st.st_mode) &&
            unlinkat(dirfd(d), e->d_name, 0) == 0)
            (*removed)++;
    }
    closedir(d);
}

/* ---- the id high-water mark (ROOT/ids.json) ----
 * Folder names alone cannot say which ids were used: a crash removes the partial folder of a reserved id and a
 * user may delete the newest capture. So the largest id that may have been handed out is kept in a file, and
 * made durable (written beside, fsync'd, renamed, folder fsync'd) before any id above the old mark is used. */

/* Read the mark; a missing file is an empty mark (storage from before it existed). */
static int ids_read(scicapd_store *s, sci_error *err)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/" STORE_IDS_FILE, s->root);
    json_error_t je;
    json_t *j = json_load_file(path, 0, &je);
    if (!j) {
        if (access(path, F_OK) != 0 && errno == ENOENT)
            return 0;
        return sci_error_set(err, SCI_EFORMAT, "%s: %s (the capture id high-water mark; ids could be reused "
                             "without it: repair or remove it knowingly)", path, je.text);
    }
    json_t *c = json_object_get(j, "capture"), *k = json_object_get(j, "calibration");
    int ok = json_is_integer(c) && json_integer_value(c) >= 0 && json_is_integer(k) && json_integer_value(k) >= 0;
    if (ok) {
        s->mark_capture = (unsigned long)json_integer_value(c);
        s->mark_calib = (unsigned long)json_integer_value(k);
    }
    json_decref(j);
    if (!ok)
        return sci_error_set(err, SCI_EFORMAT, "%s: expected {\"capture\": N, \"calibration\": N} with N >= 0",
                             path);
    return 0;
}

/* Write the mark durably. Lock held (or single-threaded). */
static int ids_write(scicapd_store *s, unsigned long capture, unsigned long calib, sci_error *err)
{
    char path[1100], text[96];
    snprintf(path, sizeof path, "%s/" STORE_IDS_FILE, s->root);
    int n = snprintf(text, sizeof text, "{\"capture\": %lu, \"calibration\": %lu}\n", capture, calib);
    int rc = sci_file_write_atomic(path, text, (size_t)n, 0644, s->fsync_on ? 0 : SCI_FILE_NO_SYNC, err);
    if (rc < 0)
        return sci_error_set(err, rc, "%s: cannot write the capture id high-water mark: %s", path, sci_strerror(rc));
    s->mark_capture = capture;
    s->mark_calib = calib;
    s->ids_ok = 1;
    return 0;
}

/* Take the next id of *next with its durable mark *mark. Lock held. */
static int ids_take(scicapd_store *s, unsigned long *next, unsigned long *mark, unsigned long *id, sci_error *err)
{
    unsigned long n = *next;
    if (n > *mark) {
        unsigned long c = s->mark_capture, k = s->mark_calib;
        *(mark == &s->mark_capture ? &c : &k) = n + STORE_ID_BLOCK - 1;
        int rc = ids_write(s, c, k, err);
        if (rc < 0)
            return rc;
    }
    *next = n + 1;
    *id = n;
    return 0;
}

/* One daemon per storage root: the recovery below removes partial folders, which would be the live folders of
 * a second daemon writing there (a careless second start, even one that would fail later on its socket).
 * The lock holds the holder's pid for the message; flock is released by the kernel when the process dies. */
static int lock_root(scicapd_store *s, sci_error *err)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/scicapd.lock", s->root);
    int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0640);
    if (fd < 0)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
        int e = errno;
        char pid[32] = "";
        ssize_t n = pread(fd, pid, sizeof pid - 1, 0);
        pid[n > 0 ? n : 0] = '\0';
        pid[strcspn(pid, "\n")] = '\0';
        close(fd);
        if (e == EWOULDBLOCK)
            return sci_error_set(err, -EBUSY, "storage %s is in use by another scicapd (pid %s); one daemon per "
                                 "storage root", s->root, pid[0] ? pid : "?");
        return sci_error_set(err, -e, "%s: flock: %s", path, strerror(e));
    }
    char pid[32];
    int n = snprintf(pid, sizeof pid, "%d\n", (int)getpid());
    if (ftruncate(fd, 0) != 0 || pwrite(fd, pid, (size_t)n, 0) != n)
        sci_log_write(s->log, SCI_LOG_WARNING, "%s: cannot record the pid: %s", path, strerror(errno));
    s->lock_fd = fd;
    return 0;
}

int scicapd_store_open(scicapd_store **out, const char *root, int fsync_on, const sci_log *log,
                       scicapd_store_recovery *rec, sci_error *err)
{
    scicapd_store *s = calloc(1, sizeof *s);
    if (!s)
        return sci_error_set(err, -ENOMEM, "store: out of memory");
    snprintf(s->root, sizeof s->root, "%s", root);
    s->fsync_on = fsync_on;
    s->log = log;
    s->lock_fd = -1;
    pthread_mutex_init(&s->mu, NULL);
    atomic_init(&s->previews, 1);
    char caps[1100], cals[1100], shown[1100], stacks[1100];
    snprintf(caps, sizeof caps, "%s/captures", root);
    snprintf(cals, sizeof cals, "%s/calibrations", root);
    snprintf(shown, sizeof shown, "%s/dmd_masks", root);
    snprintf(stacks, sizeof stacks, "%s/mask_stacks", root);
    int rc;
    if ((rc = mkdir_p(caps, err)) < 0 || (rc = mkdir_p(cals, err)) < 0 || (rc = mkdir_p(shown, err)) < 0 ||
        (rc = mkdir_p(stacks, err)) < 0 || (rc = lock_root(s, err)) < 0) {
        scicapd_store_close(s);
        return rc;
    }
    scicapd_store_recovery r = {0};
    unsigned long maxc = 0, maxk = 0;
    sweep(caps, "c", &maxc, &r.captures, &r.removed, 1);
    sweep(cals, "dark-", &maxk, NULL, &r.removed, 0);
    sweep(cals, "masks-", &maxk, NULL, &r.removed, 0);
    unsigned long unused = 0;
    sweep(shown, NULL, &unused, NULL, &r.removed, 0);
    sweep(stacks, NULL, &unused, NULL, &r.removed, 0);
    sweep_root_temporaries(root, &r.removed);
    if ((rc = ids_read(s, err)) < 0) {
        scicapd_store_close(s);
        return rc;
    }
    /* the larger of what the folders and the mark say: neither alone covers deletions and crashes */
    s->next_capture = (maxc > s->mark_capture ? maxc : s->mark_capture) + 1;
    s->next_calib = (maxk > s->mark_calib ? maxk : s->mark_calib) + 1;
    s->mark_capture = s->next_capture - 1;
    s->mark_calib = s->next_calib - 1;
    s->ids_ok = 1;
    if (rec)
        *rec = r;
    *out = s;
    return 0;
}

void scicapd_store_close(scicapd_store *s)
{
    if (!s)
        return;
    /* exact mark: a clean stop leaves no gap in the numbering (ids reserved and stored are all below next) */
    if (s->ids_ok) {
        sci_error err = {0};
        if (ids_write(s, s->next_capture - 1, s->next_calib - 1, &err) < 0)
            sci_log_write(s->log, SCI_LOG_WARNING, "%s (the mark stays ahead: ids may skip, never repeat)", err.msg);
    }
    if (s->lock_fd >= 0)
        close(s->lock_fd); /* releases the flock */
    for (int i = 0; i < 2 * STORE_MASK_CACHE; i++)
        sci_cube_free(s->mask_cache[i].mask);
    pthread_mutex_destroy(&s->mu);
    free(s);
}

const char *scicapd_store_root(const scicapd_store *s) { return s->root; }
int scicapd_store_fsync_on(const scicapd_store *s) { return s->fsync_on; }

void scicapd_store_set_previews(scicapd_store *s, int on) { atomic_store(&s->previews, on != 0); }

int scicapd_store_take_id(scicapd_store *st, char *id, size_t n, unsigned long *num, sci_error *err)
{
    unsigned long v;
    pthread_mutex_lock(&st->mu);
    int rc = ids_take(st, &st->next_capture, &st->mark_capture, &v, err);
    pthread_mutex_unlock(&st->mu);
    if (rc < 0)
        return rc;
    snprintf(id, n, "c%06lu", v);
    if (num)
        *num = v;
    return 0;
}

int scicapd_store_reserve_id(scicapd_store *st, scicapd_snapshot *s, sci_error *err)
{
    return scicapd_store_take_id(st, s->capture_id, sizeof s->capture_id, NULL, err);
}

void scicapd_store_give_back_id(scicapd_store *st, unsigned long num)
{
    pthread_mutex_lock(&st->mu);
    if (st->next_capture == num + 1) /* the mark stays ahead: harmless, it only promises what was not used */
        st->next_capture = num;
    pthread_mutex_unlock(&st->mu);
}

void scicapd_snapshot_free(scicapd_jobs *jobs, scicapd_snapshot *s)
{
    if (!s)
        return;
    if (s->job)
        scicapd_job_unref(jobs, s->job);
    sci_problem_free(s->problem);
    sci_cube_free(s->raw);
    sci_cube_free(s->dmd_masks);
    sci_cube_free(s->dark);
    json_decref(s->meta);
    json_decref(s->calibration);
    free(s);
}

static int write_json(const char *path, const json_t *j, sci_error *err)
{
    errno = 0;
    if (json_dump_file(j, path, JSON_INDENT(2) | JSON_SORT_KEYS) != 0) {
        int e = errno ? errno : EIO; /* ENOSPC from the write or the close: say so */
        return sci_error_set(err, -e, "%s: cannot write: %s", path, strerror(e));
    }
    return 0;
}

/* Rename tmp to final after syncing it; then sync the parent. */
static int publish(scicapd_store *st, const char *tmp, const char *final, const char *parent, sci_error *err)
{
    int rc;
    if (st->fsync_on && (rc = sci_staging_sync(tmp, SCI_SYNC_TREE)) < 0)
        return sci_error_set(err, rc, "%s: fsync failed: %s", tmp, strerror(-rc));
    if (rename(tmp, final) != 0)
        return sci_error_set(err, -errno, "%s: cannot rename to %s: %s", tmp, final, strerror(errno));
    if (st->fsync_on)
        sci_staging_sync(parent, 0);
    return 0;
}

/* FNV-1a over the mask stack's shape and values: names its folder under ROOT/dmd_masks. */
static uint64_t masks_hash(const sci_cube *m)
{
    uint64_t h = 1469598103934665603ULL;
    int dims[3] = {m->w, m->h, m->n};
    const unsigned char *p = (const unsigned char *)dims;
    for (size_t i = 0; i < sizeof dims; i++)
        h = (h ^ p[i]) * 1099511628211ULL;
    p = (const unsigned char *)m->data;
    for (size_t i = 0, n = sci_cube_count(m) * sizeof(float); i < n; i++)
        h = (h ^ p[i]) * 1099511628211ULL;
    return h;
}

/* Hard-link every file of folder `from` into `to`. */
static int link_all(const char *from, const char *to)
{
    DIR *d = opendir(from);
    if (!d)
        return -errno;
    struct dirent *e;
    int rc = 0;
    while (rc == 0 && (e = readdir(d))) {
        if (e->d_name[0] == '.')
            continue;
        char a[1400], b[1400];
        snprintf(a, sizeof a, "%s/%s", from, e->d_name);
        snprintf(b, sizeof b, "%s/%s", to, e->d_name);
        if (link(a, b) != 0)
            rc = -errno;
    }
    closedir(d);
    return rc;
}

static int cube_same(const sci_cube *a, const sci_cube *b)
{
    return a->w == b->w && a->h == b->h && a->n == b->n &&
           memcmp(a->data, b->data, sci_cube_count(a) * sizeof(float)) == 0;
}

/* The hash of a mask stack of `kind` whose shared folder is known this run: 1 and *hash, else 0. The masks in
 * memory are compared (a memcmp), where hashing them byte by byte costs ten times that. */
static int mask_cache_find(scicapd_store *st, int kind, const sci_cube *m, uint64_t *hash)
{
    int found = 0;
    pthread_mutex_lock(&st->mu);
    for (int i = 0; i < 2 * STORE_MASK_CACHE && !found; i++)
        if (st->mask_cache[i].mask && st->mask_cache[i].kind == kind && cube_same(st->mask_cache[i].mask, m)) {
            *hash = st->mask_cache[i].hash;
            found = 1;
        }
    pthread_mutex_unlock(&st->mu);
    return found;
}

static void mask_cache_put(scicapd_store *st, int kind, const sci_cube *m, uint64_t hash)
{
    sci_cube *copy = NULL;
    if (sci_cube_count(m) * sizeof(float) > STORE_MASK_CACHE_BYTES || sci_cube_clone(&copy, m, NULL) < 0)
        return; /* only a cache */
    pthread_mutex_lock(&st->mu);
    const int i = st->mask_cache_next;
    st->mask_cache_next = (i + 1) % (2 * STORE_MASK_CACHE);
    sci_cube_free(st->mask_cache[i].mask);
    st->mask_cache[i].kind = kind;
    st->mask_cache[i].hash = hash;
    st->mask_cache[i].mask = copy;
    pthread_mutex_unlock(&st->mu);
}

/* The masks shown on the DMD (dmd_mask_*.png + dmd_mask.json) are the same for every snapshot of a mask set:
 * written once to ROOT/dmd_masks/<hash>/ (atomically) and hard-linked into each capture folder (~45 ms of PNG
 * encoding saved per 256×256×8 snapshot). Files are never modified in place, so sharing inodes is safe; a
 * filesystem without hard links falls back to writing them. */
static int write_shown_masks(scicapd_store *st, const sci_cube *m, const char *dir, sci_error *err)
{
    char shared[1200], tmp[1300];
    uint64_t h64;
    const int known = mask_cache_find(st, STORE_SHOWN, m, &h64);
    if (!known)
        h64 = masks_hash(m);
    const unsigned long long hash = (unsigned long long)h64;
    snprintf(shared, sizeof shared, "%s/dmd_masks/%016llx", st->root, hash);
    struct stat sb;
    if (!known && stat(shared, &sb) != 0) {
        snprintf(tmp, sizeof tmp, "%s/dmd_masks/.%016llx.tmp-%d-%lx", st->root, hash, (int)getpid(),
                 (unsigned long)pthread_self());
        int rc;
        if ((rc = mkdir_p(tmp, err)) < 0 ||
            (rc = sci_stack_write(tmp, "dmd_mask", "png", m, SCI_PIXEL_U8, 255.0, NULL, err)) < 0) {
            sci_staging_remove(tmp);
            return rc;
        }
        if (st->fsync_on)
            sci_staging_sync(tmp, SCI_SYNC_TREE);
        if (rename(tmp, shared) != 0) /* another writer got there first: theirs is the same */
            sci_staging_remove(tmp);
        else if (st->fsync_on)
            sci_staging_sync(shared, SCI_SYNC_PARENT);
    }
    if (link_all(shared, dir) == 0) {
        if (!known)
            mask_cache_put(st, STORE_SHOWN, m, h64);
        return 0;
    }
    return sci_stack_write(dir, "dmd_mask", "png", m, SCI_PIXEL_U8, 255.0, NULL, err);
}

/* The reconstruction's masks (mask.json, mask_*.exr, preview_mask_*.png) are the same for every snapshot of a
 * mask set: written once to ROOT/mask_stacks/<hash>/ (atomically) and hard-linked into each capture folder
 * (io/problem_dir.h, masks_from), which saves 8 EXR and 8 PNG encodings per 256×256×8 snapshot. A folder found
 * on disk (an earlier run's, or another writer's) is read back and compared once per run before it is used, so a
 * hash collision or a damaged folder is never linked; after that the masks in memory are compared (a memcmp).
 * Into `path` the folder to link from; -1 when the masks must be written in the capture folder instead. */
static int shared_mask_stack(scicapd_store *st, const sci_cube *m, char *path, size_t n)
{
    uint64_t hash;
    if (mask_cache_find(st, STORE_STACK, m, &hash)) {
        snprintf(path, n, "%s/mask_stacks/%016llx", st->root, (unsigned long long)hash);
        return 0;
    }
    hash = masks_hash(m);
    snprintf(path, n, "%s/mask_stacks/%016llx", st->root, (unsigned long long)hash);
    sci_error err = {0};
    struct stat sb;
    if (stat(path, &sb) != 0) {
        char tmp[1300];
        snprintf(tmp, sizeof tmp, "%s/mask_stacks/.%016llx.tmp-%d-%lx", st->root, (unsigned long long)hash,
                 (int)getpid(), (unsigned long)pthread_self());
        if (sci_problem_dir_write_masks(tmp, m, &err) < 0) {
            sci_staging_remove(tmp);
            sci_log_write(st->log, SCI_LOG_WARNING, "%s (the masks are written in each capture folder)", err.msg);
            return -1;
        }
        if (st->fsync_on)
            sci_staging_sync(tmp, SCI_SYNC_TREE);
        if (rename(tmp, path) != 0) /* another writer got there first: checked below like any folder found */
            sci_staging_remove(tmp);
        else if (st->fsync_on)
            sci_staging_sync(path, SCI_SYNC_PARENT);
    }
    char side[1400];
    snprintf(side, sizeof side, "%s/mask.json", path);
    sci_cube *back = NULL;
    int same = sci_stack_read(side, &back, NULL, &err) == 0 && cube_same(back, m);
    sci_cube_free(back);
    if (!same) {
        sci_log_write(st->log, SCI_LOG_WARNING, "%s does not hold this capture's masks%s%s: they are written in each "
                      "capture folder", path, err.msg[0] ? ": " : "", err.msg);
        return -1;
    }
    mask_cache_put(st, STORE_STACK, m, hash);
    return 0;
}

int scicapd_store_write_capture(scicapd_store *st, scicapd_snapshot *s, sci_error *err)
{
    int rc;
    if (!s->capture_id[0] && (rc = scicapd_store_reserve_id(st, s, err)) < 0)
        return rc;
    char parent[1100], tmp[1200], path[1400];
    snprintf(parent, sizeof parent, "%s/captures", st->root);
    snprintf(tmp, sizeof tmp, "%s/.%s.partial", parent, s->capture_id);
    snprintf(s->dir, sizeof s->dir, "%s/%s", parent, s->capture_id);
    snprintf(s->problem->name, sizeof s->problem->name, "%s", s->capture_id);
    json_object_set_new(s->meta, "capture_id", json_string(s->capture_id));
    json_t *source = json_pack("{s:s, s:s}", "kind", "scicapd-capture", "capture_id", s->capture_id);
    sci_problem *p = s->problem;
    char masks[1200];
    sci_problem_dir_opts o = {.previews = atomic_load(&st->previews)};
    if (shared_mask_stack(st, p->mask, masks, sizeof masks) == 0)
        o.masks_from = masks;
    rc = sci_problem_dir_save(tmp, &p, 1, source, &o, err);
    json_decref(source);
    if (rc < 0)
        goto fail;
    snprintf(path, sizeof path, "%s/raw.tif", tmp);
    if (s->raw && (rc = sci_image_write(path, s->raw, 0, SCI_PIXEL_U16, 1.0, "scicap raw snapshot (counts)", err)) < 0)
        goto fail;
    if (s->dmd_masks && (rc = write_shown_masks(st, s->dmd_masks, tmp, err)) < 0)
        goto fail;
    if (s->dark) {
        snprintf(path, sizeof path, "%s/dark.tif", tmp);
        if ((rc = sci_image_write(path, s->dark, 0, SCI_PIXEL_U16, 1.0, "scicap dark frame (counts)", err)) < 0)
            goto fail;
    }
    json_t *cal = s->calibration ? json_incref(s->calibration) : json_pack("{s:s}", "kind", "none");
    snprintf(path, sizeof path, "%s/calibration.json", tmp);
    rc = write_json(path, cal, err);
    json_decref(cal);
    if (rc < 0)
        goto fail;
    snprintf(path, sizeof path, "%s/meta.json", tmp);
    if ((rc = write_json(path, s->meta, err)) < 0 || (rc = publish(st, tmp, s->dir, parent, err)) < 0)
        goto fail;
    return 0;
fail:
    sci_staging_remove(tmp);
    sci_error_prefix(err, "capture %s: ", s->capture_id);
    return rc;
}

int scicapd_store_capture_dir(const scicapd_store *st, const char *id, char *buf, size_t n, sci_error *err)
{
    struct stat sb;
    if (!id[0] || strchr(id, '/') || id[0] == '.')
        return sci_error_set(err, -ENOENT, "no capture \"%s\"", id);
    snprintf(buf, n, "%s/captures/%s", st->root, id);
    char pj[1400];
    snprintf(pj, sizeof pj, "%s/problem.json", buf);
    if (stat(pj, &sb) != 0)
        return sci_error_set(err, -ENOENT, "no capture \"%s\" in %s/captures", id, st->root);
    return 0;
}

int scicapd_store_write_calibration(scicapd_store *st, const char *key, const sci_cube *data, const json_t *record,
                                    json_t **record_out, sci_error *err)
{
    unsigned long n;
    pthread_mutex_lock(&st->mu);
    int rc = ids_take(st, &st->next_calib, &st->mark_calib, &n, err);
    pthread_mutex_unlock(&st->mu);
    if (rc < 0)
        return rc;
    char parent[1100], id[128], tmp[1300], final[1300], path[1400];
    snprintf(parent, sizeof parent, "%s/calibrations", st->root);
    snprintf(id, sizeof id, "%s-%06lu", key, n);
    snprintf(tmp, sizeof tmp, "%s/.%s.partial", parent, id);
    snprintf(final, sizeof final, "%s/%s", parent, id);
    json_t *rec = json_deep_copy(record);
    json_object_set_new(rec, "id", json_string(id));
    json_object_set_new(rec, "folder", json_string(final));
    if ((rc = mkdir_p(tmp, err)) < 0)
        goto fail;
    if (strcmp(key, "dark") == 0) {
        snprintf(path, sizeof path, "%s/dark.tif", tmp);
        rc = sci_image_write(path, data, 0, SCI_PIXEL_U16, 1.0, "scicap dark frame (counts)", err);
    } else {
        rc = sci_stack_write(tmp, "mask", "exr", data, SCI_PIXEL_F32, 1.0, NULL, err);
    }
    if (rc < 0)
        goto fail;
    snprintf(path, sizeof path, "%s/calibration.json", tmp);
    if ((rc = write_json(path, rec, err)) < 0 || (rc = publish(st, tmp, final, parent, err)) < 0)
        goto fail;
    /* the pointer: written beside and renamed over the old one */
    char ptr[1300];
    snprintf(ptr, sizeof ptr, "%s/%s.json", parent, key);
    if ((rc = sci_json_write_atomic(ptr, rec, JSON_INDENT(2) | JSON_SORT_KEYS, 0644,
                                    st->fsync_on ? 0 : SCI_FILE_NO_SYNC, err)) < 0)
        goto fail;
    if (record_out)
        *record_out = rec;
    else
        json_decref(rec);
    return 0;
fail:
    json_decref(rec);
    sci_staging_remove(tmp);
    return rc;
}

int scicapd_store_load_calibration(scicapd_store *st, const char *key, sci_cube **data, json_t **record,
                                   sci_error *err)
{
    char ptr[1300], path[1400];
    snprintf(ptr, sizeof ptr, "%s/calibrations/%s.json", st->root, key);
    json_error_t je;
    json_t *rec = json_load_file(ptr, 0, &je);
    if (!rec)
        return access(ptr, F_OK) == 0 ? sci_error_set(err, SCI_EFORMAT, "%s: %s", ptr, je.text)
                                      : sci_error_set(err, -ENOENT, "no %s calibration", key);
    const char *folder = json_string_value(json_object_get(rec, "folder"));
    int rc;
    if (!folder) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: no \"folder\"", ptr);
        goto fail;
    }
    int bits;
    if (strcmp(key, "dark") == 0) {
        snprintf(path, sizeof path, "%s/dark.tif", folder);
        rc = sci_image_read(path, data, &bits, err);
    } else {
        snprintf(path, sizeof path, "%s/mask.json", folder);
        rc = sci_stack_read(path, data, NULL, err);
    }
    if (rc < 0)
        goto fail;
    *record = rec;
    return 0;
fail:
    json_decref(rec);
    return rc;
}

/* A failed write whose library did not keep errno (OpenEXR says only "File output failed"): when the store's
 * file system has no room left, the cause is that; say it, with -ENOSPC, so the user knows what to free. */
static int name_full_disk(const scicapd_store *st, const scicapd_snapshot *s, int rc, sci_error *err)
{
    struct statvfs v;
    if (rc == -ENOSPC || strstr(err->msg, strerror(ENOSPC)) || statvfs(st->root, &v) != 0)
        return rc;
    /* what the snapshot's folder needs, roughly: its cubes as float32 (the partial folder is gone by now, so the
     * room it took is free again) */
    double need = 0;
    const sci_cube *c[] = {s->problem ? s->problem->meas : NULL, s->problem ? s->problem->mask : NULL,
                           s->problem ? s->problem->truth : NULL, s->raw, s->dark};
    for (int i = 0; i < 5; i++)
        need += c[i] ? (double)sci_cube_count(c[i]) * 4.0 : 0;
    double free_b = (double)v.f_bavail * (double)v.f_frsize;
    if (free_b >= 2 * need + 1048576.0 && v.f_favail > 0)
        return rc;
    char msg[sizeof err->msg];
    snprintf(msg, sizeof msg, "%s: %s (%.0f bytes free on %s)", strerror(ENOSPC), err->msg, free_b, st->root);
    return sci_error_set(err, -ENOSPC, "%s", msg);
}

static void *writer_main(void *arg)
{
    scicapd_store *st = arg;
    scicapd_snapshot *s;
    while ((s = scicapd_queue_pop(st->q, -1))) {
        sci_error err = {0};
        scicapd_span sp;
        scicapd_span_begin(&sp);
        int rc = scicapd_store_write_capture(st, s, &err);
        if (rc < 0)
            rc = name_full_disk(st, s, rc, &err);
        scicapd_timing_add(st->timing, SCICAPD_STAGE_STORE, &sp);
        st->on_stored(st->user, s, rc, &err);
    }
    return NULL;
}

int scicapd_store_start(scicapd_store *st, scicapd_queue *q, int writers, scicapd_stored_fn on_stored, void *user,
                        scicapd_timing *timing, sci_error *err)
{
    /* the writers (and reconstruction workers) are the parallelism: OpenEXR's pool on top only adds hand-offs on
     * few cores (256×256 float frame: 4-7 ms of CPU with it, 2.5 without; io/image.h) */
    sci_image_exr_threads(-1);
    st->q = q;
    st->timing = timing;
    st->on_stored = on_stored;
    st->user = user;
    writers = writers < 1 ? 1 : writers > STORE_MAX_WRITERS ? STORE_MAX_WRITERS : writers;
    for (int i = 0; i < writers; i++) {
        int rc = pthread_create(&st->threads[i], NULL, writer_main, st);
        if (rc != 0)
            return sci_error_set(err, -rc, "store: cannot start writer thread %d: %s", i, strerror(rc));
        st->running++;
    }
    return 0;
}

void scicapd_store_stop(scicapd_store *st)
{
    if (!st)
        return;
    for (int i = 0; i < st->running; i++)
        pthread_join(st->threads[i], NULL);
    st->running = 0;
}
