/* tests/helpers/layering.c — the include-direction check (see layering.h). */
#include "tests/helpers/layering.h"

#include <errno.h>
#include <dirent.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

const layering_layer layering_tree[] = {
    {"base", 0},   {"recon", 1}, {"io", 2},     {"drivers", 2}, {"sim", 3},
    {"daemon", 4}, {"cli", 4},   {"python", 5}, {"bench", 5},   {"tests", 6},
};
const int layering_tree_count = sizeof layering_tree / sizeof layering_tree[0];

/* One walk: the table, and the report being written. */
typedef struct walk {
    const layering_layer *layers;
    int n_layers;
    char *report;
    size_t size, used;
    int bad, files;
} walk;

static void note(walk *w, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void note(walk *w, const char *fmt, ...)
{
    w->bad++;
    if (w->used + 1 >= w->size)
        return;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(w->report + w->used, w->size - w->used, fmt, ap);
    va_end(ap);
    if (n > 0)
        w->used = w->used + (size_t)n < w->size ? w->used + (size_t)n : w->size - 1;
}

/* The layer of a path's first component (len bytes), or NULL. */
static const layering_layer *layer_of(const walk *w, const char *dir, size_t len)
{
    for (int i = 0; i < w->n_layers; i++)
        if (strlen(w->layers[i].dir) == len && strncmp(w->layers[i].dir, dir, len) == 0)
            return &w->layers[i];
    return NULL;
}

static int is_source(const char *path)
{
    const char *dot = strrchr(path, '.');
    return dot && (strcmp(dot, ".c") == 0 || strcmp(dot, ".h") == 0 || strcmp(dot, ".cpp") == 0);
}

static void check_file(walk *w, const char *fpath, const char *rel, const layering_layer *own)
{
    FILE *f = fopen(fpath, "r");
    if (!f) {
        note(w, "%s: cannot read: %s\n", rel, strerror(errno));
        return;
    }
    w->files++;
    char line[4096];
    for (int ln = 1; fgets(line, sizeof line, f); ln++) {
        const char *p = line;
        while (*p == ' ' || *p == '\t')
            p++;
        if (*p++ != '#')
            continue;
        while (*p == ' ' || *p == '\t')
            p++;
        if (strncmp(p, "include", 7) != 0)
            continue;
        p += 7;
        while (*p == ' ' || *p == '\t')
            p++;
        if (*p != '"')
            continue; /* <system> headers */
        const char *name = p + 1, *end = strchr(name, '"'), *slash = strchr(name, '/');
        if (!end || !slash || slash > end)
            continue; /* "local.h" */
        const layering_layer *to = layer_of(w, name, (size_t)(slash - name));
        if (!to)
            note(w, "%s:%d: includes \"%.*s\": %.*s/ is not a layer\n", rel, ln, (int)(end - name), name,
                 (int)(slash - name), name);
        else if (to != own && to->rank >= own->rank)
            note(w, "%s:%d: includes \"%.*s\": %s/ (layer %d) is %s %s/ (layer %d)\n", rel, ln, (int)(end - name), name,
                 to->dir, to->rank, to->rank == own->rank ? "beside" : "above", own->dir, own->rank);
    }
    fclose(f);
}

/* Walk dir (path root/rel); depth 0 is the root. */
static int walk_dir(walk *w, const char *root, const char *rel, int depth)
{
    char path[4096];
    snprintf(path, sizeof path, "%s%s%s", root, rel[0] ? "/" : "", rel);
    DIR *d = opendir(path);
    if (!d)
        return -errno;
    struct dirent *e;
    int rc = 0;
    while (rc == 0 && (e = readdir(d))) {
        const char *name = e->d_name;
        if (name[0] == '.' || (depth == 0 && strncmp(name, "build", 5) == 0))
            continue; /* hidden folders, build output */
        char sub[4096], full[8200];
        snprintf(sub, sizeof sub, "%s%s%s", rel, rel[0] ? "/" : "", name);
        snprintf(full, sizeof full, "%s/%s", root, sub);
        struct stat st;
        if (lstat(full, &st) != 0)
            continue;
        if (S_ISDIR(st.st_mode)) {
            rc = walk_dir(w, root, sub, depth + 1);
            continue;
        }
        if (!S_ISREG(st.st_mode) || !is_source(name) || depth == 0)
            continue; /* top-level files hold no code */
        const char *slash = strchr(sub, '/');
        const layering_layer *own = layer_of(w, sub, (size_t)(slash - sub));
        if (!own)
            note(w, "%s:1: %.*s/ is not a layer (add it to the table of docs/architecture.md and "
                    "tests/helpers/layering.c)\n", sub, (int)(slash - sub), sub);
        else
            check_file(w, full, sub, own);
    }
    closedir(d);
    return rc;
}

int layering_check(const char *root, const layering_layer *layers, int n_layers, char *report, size_t report_size,
                   int *files)
{
    walk w = {.layers = layers, .n_layers = n_layers, .report = report, .size = report_size};
    if (report_size)
        report[0] = 0;
    int rc = walk_dir(&w, root, "", 0);
    if (files)
        *files = w.files;
    return rc < 0 ? rc : w.bad;
}
