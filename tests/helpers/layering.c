/* tests/helpers/layering.c — the include-direction check (see layering.h). */
#include "tests/helpers/layering.h"

#include <errno.h>
#include <dirent.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
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

/* What follows `#include` on a source line (blanks skipped), or NULL when the line is no include. */
static const char *include_operand(const char *line)
{
    const char *p = line + strspn(line, " \t");
    if (*p++ != '#')
        return NULL;
    p += strspn(p, " \t");
    if (strncmp(p, "include", 7) != 0)
        return NULL;
    p += 7;
    return p + strspn(p, " \t");
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
        const char *p = include_operand(line);
        if (!p)
            continue;
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

/* ---- cycles between the modules of one folder ---- */

#define CYCLE_MAX_MODULES 512

/* One folder's modules and the first include seen from each to each (file and line; line 0: none). */
typedef struct graph {
    int n;
    char name[CYCLE_MAX_MODULES][256];          /* "acquire" for dir/acquire.c and dir/acquire.h */
    struct edge {
        unsigned short line;
        char from_ext;                          /* 'c' or 'h': the including file */
    } *edge;                                    /* n_max × n_max, row = includer */
    unsigned char color[CYCLE_MAX_MODULES];     /* 0 unseen, 1 on the walk's path, 2 done */
    int path[CYCLE_MAX_MODULES], depth;
} graph;

static int module_of(graph *g, const char *name, size_t len, int add)
{
    for (int i = 0; i < g->n; i++)
        if (strlen(g->name[i]) == len && strncmp(g->name[i], name, len) == 0)
            return i;
    if (!add || len >= sizeof g->name[0])
        return -1;
    if (g->n == CYCLE_MAX_MODULES)
        return -E2BIG;
    snprintf(g->name[g->n], sizeof g->name[0], "%.*s", (int)len, name);
    return g->n++;
}

/* The modules of dir (every .c and .h directly in it). */
static int graph_modules(graph *g, const char *path)
{
    DIR *d = opendir(path);
    if (!d)
        return -errno;
    struct dirent *e;
    int rc = 0;
    while (rc >= 0 && (e = readdir(d))) {
        const char *dot = strrchr(e->d_name, '.');
        if (e->d_name[0] != '.' && dot && (strcmp(dot, ".c") == 0 || strcmp(dot, ".h") == 0))
            rc = module_of(g, e->d_name, (size_t)(dot - e->d_name), 1);
    }
    closedir(d);
    return rc < 0 ? rc : 0;
}

/* The includes of "dir/x.h" in file `name` of module `from`. */
static void graph_edges(graph *g, const char *path, const char *dir, int from, char ext)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return;
    char line[4096], prefix[300];
    int plen = snprintf(prefix, sizeof prefix, "\"%s/", dir);
    for (int ln = 1; fgets(line, sizeof line, f); ln++) {
        const char *p = include_operand(line);
        if (!p)
            continue;
        if (strncmp(p, prefix, (size_t)plen) != 0)
            continue;
        const char *name = p + plen, *end = strstr(name, ".h\"");
        int to = end ? module_of(g, name, (size_t)(end - name), 0) : -1;
        struct edge *e = to >= 0 ? &g->edge[from * CYCLE_MAX_MODULES + to] : NULL;
        if (e && to != from && e->line == 0)
            *e = (struct edge){.line = (unsigned short)(ln < 65535 ? ln : 65535), .from_ext = ext};
    }
    fclose(f);
}

/* The cycle closed by the edge path[depth-1] -> to, written as the includes along it. */
static void cycle_note(walk *w, const graph *g, const char *dir, int to)
{
    int start = g->depth - 1;
    while (start > 0 && g->path[start] != to)
        start--;
    char buf[2048];
    size_t used = (size_t)snprintf(buf, sizeof buf, "cycle:");
    for (int i = start; i < g->depth && used < sizeof buf; i++) {
        int a = g->path[i], b = i + 1 < g->depth ? g->path[i + 1] : to;
        const struct edge *e = &g->edge[a * CYCLE_MAX_MODULES + b];
        used += (size_t)snprintf(buf + used, sizeof buf - used, "%s %s/%s.%c includes %s/%s.h (line %d)",
                                 i > start ? ";" : "", dir, g->name[a], e->from_ext, dir, g->name[b], e->line);
    }
    note(w, "%s\n", buf);
}

static void graph_walk(walk *w, graph *g, const char *dir, int u)
{
    g->color[u] = 1;
    g->path[g->depth++] = u;
    for (int v = 0; v < g->n; v++) {
        if (g->edge[u * CYCLE_MAX_MODULES + v].line == 0)
            continue;
        if (g->color[v] == 1)
            cycle_note(w, g, dir, v);
        else if (g->color[v] == 0)
            graph_walk(w, g, dir, v);
    }
    g->depth--;
    g->color[u] = 2;
}

int layering_cycles(const char *root, const char *dir, char *report, size_t report_size, int *modules)
{
    walk w = {.report = report, .size = report_size};
    if (report_size)
        report[0] = 0;
    graph *g = calloc(1, sizeof *g);
    if (!g || !(g->edge = calloc((size_t)CYCLE_MAX_MODULES * CYCLE_MAX_MODULES, sizeof *g->edge))) {
        free(g);
        return -ENOMEM;
    }
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", root, dir);
    int rc = graph_modules(g, path);
    for (int i = 0; rc == 0 && i < g->n; i++) {
        char file[4400];
        snprintf(file, sizeof file, "%s/%s.c", path, g->name[i]);
        graph_edges(g, file, dir, i, 'c');
        snprintf(file, sizeof file, "%s/%s.h", path, g->name[i]);
        graph_edges(g, file, dir, i, 'h');
    }
    for (int i = 0; rc == 0 && i < g->n; i++)
        if (g->color[i] == 0)
            graph_walk(&w, g, dir, i);
    if (modules)
        *modules = g->n;
    free(g->edge);
    free(g);
    return rc < 0 ? rc : w.bad;
}
