/* daemon/reconout.c — reconstruction folder names (see the header). */
#include "daemon/reconout.h"

#include <dirent.h>
#include <errno.h>
#include <jansson.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct scicapd_reconout {
    pthread_mutex_t mu;
    char **held; /* "CAPDIR/recon/NAME" of each reservation (at most one per running worker) */
    int n, cap;
};

int scicapd_reconout_new(scicapd_reconout **out)
{
    scicapd_reconout *r = calloc(1, sizeof *r);
    if (!r)
        return -ENOMEM;
    pthread_mutex_init(&r->mu, NULL);
    *out = r;
    return 0;
}

void scicapd_reconout_free(scicapd_reconout *r)
{
    if (!r)
        return;
    for (int i = 0; i < r->n; i++)
        free(r->held[i]);
    free(r->held);
    pthread_mutex_destroy(&r->mu);
    free(r);
}

int scicapd_reconout_ordinal(const char *name, const char *method)
{
    size_t m = strlen(method);
    if (strncmp(name, method, m) != 0)
        return 0;
    if (name[m] == '\0')
        return 1;
    const char *d = name + m + 1;
    size_t len = strlen(d);
    if (name[m] != '.' || len == 0 || len > 6 || d[0] == '0' || strspn(d, "0123456789") != len)
        return 0;
    int k = atoi(d);
    return k >= 2 ? k : 0;
}

static void name_of(const char *method, int k, char *name, size_t n)
{
    if (k <= 1)
        snprintf(name, n, "%s", method);
    else
        snprintf(name, n, "%s.%d", method, k);
}

/* Largest ordinal of `method` among the folders in `rdir` (0: none; a missing folder has none). */
static int largest_on_disk(const char *rdir, const char *method, sci_error *err)
{
    DIR *d = opendir(rdir);
    if (!d)
        return errno == ENOENT ? 0 : sci_error_set(err, -errno, "%s: %s", rdir, strerror(errno));
    int top = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        int k = scicapd_reconout_ordinal(e->d_name, method);
        top = k > top ? k : top;
    }
    closedir(d);
    return top;
}

/* Largest ordinal reserved under rdir. Lock held. */
static int largest_held(const scicapd_reconout *r, const char *rdir, const char *method)
{
    size_t l = strlen(rdir);
    int top = 0;
    for (int i = 0; i < r->n; i++)
        if (strncmp(r->held[i], rdir, l) == 0 && r->held[i][l] == '/') {
            int k = scicapd_reconout_ordinal(r->held[i] + l + 1, method);
            top = k > top ? k : top;
        }
    return top;
}

static int hold(scicapd_reconout *r, const char *path)
{
    if (r->n == r->cap) {
        int nc = r->cap ? 2 * r->cap : 8;
        char **v = realloc(r->held, (size_t)nc * sizeof *v);
        if (!v)
            return -ENOMEM;
        r->held = v;
        r->cap = nc;
    }
    if (!(r->held[r->n] = strdup(path)))
        return -ENOMEM;
    r->n++;
    return 0;
}

int scicapd_reconout_reserve(scicapd_reconout *r, const char *capdir, const char *method, char *name, size_t n,
                             sci_error *err)
{
    char rdir[1200], path[1400];
    snprintf(rdir, sizeof rdir, "%s/recon", capdir);
    pthread_mutex_lock(&r->mu);
    int top = largest_on_disk(rdir, method, err), rc = top;
    if (rc >= 0) {
        int held = largest_held(r, rdir, method);
        name_of(method, (held > top ? held : top) + 1, name, n);
        if ((size_t)snprintf(path, sizeof path, "%s/%s", rdir, name) >= sizeof path)
            rc = sci_error_set(err, -ENAMETOOLONG, "%s/%s: name too long", rdir, name);
        else if ((rc = hold(r, path)) < 0)
            sci_error_set(err, rc, "reconstruction folder names: out of memory");
    }
    pthread_mutex_unlock(&r->mu);
    return rc < 0 ? rc : 0;
}

void scicapd_reconout_release(scicapd_reconout *r, const char *capdir, const char *name)
{
    char path[1400];
    snprintf(path, sizeof path, "%s/recon/%s", capdir, name);
    pthread_mutex_lock(&r->mu);
    for (int i = 0; i < r->n; i++)
        if (strcmp(r->held[i], path) == 0) {
            free(r->held[i]);
            r->held[i] = r->held[--r->n];
            break;
        }
    pthread_mutex_unlock(&r->mu);
}

int scicapd_reconout_published_by(const char *capdir, const char *method, const char *entry)
{
    char rdir[1200], path[1500];
    snprintf(rdir, sizeof rdir, "%s/recon", capdir);
    DIR *d = opendir(rdir);
    if (!d)
        return 0;
    int found = 0;
    struct dirent *e;
    while (!found && (e = readdir(d))) {
        if (!scicapd_reconout_ordinal(e->d_name, method))
            continue;
        snprintf(path, sizeof path, "%s/%s/result.json", rdir, e->d_name);
        json_t *res = json_load_file(path, 0, NULL);
        const char *by = json_string_value(json_object_get(json_object_get(res, "job"), "queue_entry"));
        found = by && strcmp(by, entry) == 0;
        json_decref(res);
    }
    closedir(d);
    return found;
}
