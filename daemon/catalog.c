/* daemon/catalog.c — the stored captures listed (see the header). */
#include "daemon/catalog.h"

#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

/* A capture folder's number: "c000042" -> 42; 0 for any other name (temporaries, strays). */
static unsigned long capture_number(const char *name)
{
    size_t len = strlen(name);
    if (name[0] != 'c' || len < 2 || len > 16 || strspn(name + 1, "0123456789") != len - 1)
        return 0;
    return strtoul(name + 1, NULL, 10);
}

static int by_number(const void *a, const void *b)
{
    unsigned long x = *(const unsigned long *)a, y = *(const unsigned long *)b;
    return x < y ? -1 : x > y;
}

/* Numbers of every capture folder under dir, ascending: *out (caller frees), count returned; -errno. */
static long capture_numbers(const char *dir, unsigned long **out, sci_error *err)
{
    *out = NULL;
    DIR *d = opendir(dir);
    if (!d)
        return errno == ENOENT ? 0 : sci_error_set(err, -errno, "%s: %s", dir, strerror(errno));
    unsigned long *v = NULL;
    long n = 0, cap = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        unsigned long k = capture_number(e->d_name);
        if (!k)
            continue;
        if (n == cap) {
            unsigned long *nv = realloc(v, (size_t)(cap = cap ? 2 * cap : 64) * sizeof *nv);
            if (!nv) {
                free(v);
                closedir(d);
                return sci_error_set(err, -ENOMEM, "%s: out of memory", dir);
            }
            v = nv;
        }
        v[n++] = k;
    }
    closedir(d);
    if (n)
        qsort(v, (size_t)n, sizeof *v, by_number);
    *out = v;
    return n;
}

static json_t *utc_of(time_t t)
{
    struct tm tm;
    char iso[64];
    gmtime_r(&t, &tm);
    strftime(iso, sizeof iso, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return json_string(iso);
}

/* Copy a member of `from` to `to` under `as` when it is present. */
static void copy(json_t *to, const char *as, const json_t *from, const char *key)
{
    json_t *v = json_object_get(from, key);
    if (v && !json_is_null(v))
        json_object_set(to, as, v);
}

/* "gap-tv.2" -> base length 6 and ordinal 2; "gap-tv" -> 6 and 1. */
static size_t split_folder(const char *name, int *ordinal)
{
    const char *dot = strrchr(name, '.');
    size_t len = strlen(name);
    if (dot && dot[1] && strspn(dot + 1, "0123456789") == strlen(dot + 1)) {
        *ordinal = atoi(dot + 1);
        return (size_t)(dot - name);
    }
    *ordinal = 1;
    return len;
}

static int by_folder(const void *a, const void *b)
{
    const char *x = *(char *const *)a, *y = *(char *const *)b;
    int ox, oy;
    size_t lx = split_folder(x, &ox), ly = split_folder(y, &oy);
    int c = strncmp(x, y, lx < ly ? lx : ly);
    if (c || lx != ly)
        return c ? c : lx < ly ? -1 : 1;
    return ox < oy ? -1 : ox > oy;
}

/* One reconstruction folder as listed; NULL when it holds no readable result.json. */
static json_t *recon_entry(const char *rdir, const char *name)
{
    char path[1600];
    snprintf(path, sizeof path, "%s/%s/result.json", rdir, name);
    struct stat sb;
    json_t *r = stat(path, &sb) == 0 ? json_load_file(path, 0, NULL) : NULL;
    if (!json_is_object(r)) {
        json_decref(r);
        return NULL;
    }
    json_t *e = json_pack("{s:s, s:o}", "folder", name, "time", utc_of(sb.st_mtime));
    copy(e, "method", r, "method");
    copy(e, "psnr", json_object_get(r, "psnr_frame_max_db"), "mean");
    copy(e, "residual", r, "residual");
    copy(e, "iterations", r, "iterations");
    copy(e, "solve_s", r, "wall_s");
    copy(e, "budget", json_object_get(r, "params"), "budget");
    json_decref(r);
    return e;
}

/* The reconstructions of the capture in `dir`, sorted by method then order written. */
static json_t *recons_of(const char *dir)
{
    char rdir[1200];
    snprintf(rdir, sizeof rdir, "%s/recon", dir);
    json_t *a = json_array();
    DIR *d = opendir(rdir);
    if (!d)
        return a;
    char *names[256];
    int n = 0;
    struct dirent *e;
    while (n < 256 && (e = readdir(d))) {
        char *name = e->d_name[0] != '.' && !strstr(e->d_name, ".tmp-") && !strstr(e->d_name, ".old-")
                         ? strdup(e->d_name) : NULL;
        if (name)
            names[n++] = name;
    }
    closedir(d);
    qsort(names, (size_t)n, sizeof *names, by_folder);
    for (int i = 0; i < n; i++) {
        json_t *r = recon_entry(rdir, names[i]);
        if (r)
            json_array_append_new(a, r);
        free(names[i]);
    }
    return a;
}

/* One capture as listed. */
static json_t *capture_entry(const char *root, unsigned long num)
{
    char id[32], dir[1100], path[1300];
    snprintf(id, sizeof id, "c%06lu", num);
    snprintf(dir, sizeof dir, "%s/captures/%s", root, id);
    json_t *e = json_pack("{s:s}", "capture", id);
    snprintf(path, sizeof path, "%s/problem.json", dir);
    json_t *p = json_load_file(path, 0, NULL);
    copy(e, "w", p, "w");
    copy(e, "h", p, "h");
    copy(e, "frames", p, "n");
    json_object_set_new(e, "truth", json_boolean(json_object_get(p, "truth") != NULL));
    json_decref(p);
    snprintf(path, sizeof path, "%s/meta.json", dir);
    json_t *m = json_load_file(path, 0, NULL);
    const json_t *when = json_object_get(json_object_get(m, "captured"), "utc");
    json_object_set_new(e, "time", when ? json_incref((json_t *)when) : json_null());
    json_object_set_new(e, "source", json_string(json_object_get(m, "imported") ? "import" : "bench"));
    copy(e, "scene", json_object_get(m, "simulated"), "scene");
    json_object_set_new(e, "broken", json_boolean(json_is_true(json_object_get(json_object_get(m, "sync"),
                                                                               "broken"))));
    json_decref(m);
    json_object_set_new(e, "recons", recons_of(dir));
    return e;
}

json_t *scicapd_catalog_list(const char *root, long limit, sci_error *err)
{
    char dir[1100];
    snprintf(dir, sizeof dir, "%s/captures", root);
    unsigned long *nums;
    long n = capture_numbers(dir, &nums, err);
    if (n < 0)
        return NULL;
    json_t *list = json_array();
    long first = limit > 0 && n > limit ? n - limit : 0;
    for (long i = first; i < n; i++)
        json_array_append_new(list, capture_entry(root, nums[i]));
    free(nums);
    return json_pack("{s:o, s:I}", "captures", list, "total", (json_int_t)n);
}
