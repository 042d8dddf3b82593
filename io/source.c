#include "io/source.h"

#include <errno.h>
#include <jansson.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "io/matfile.h"
#include "io/problem_dir.h"

/* What an input that is neither a .mat nor a problem folder gets told: an image alone holds no masks. */
static int unknown_format(const char *path, sci_error *err)
{
    static const char *const images[] = {".png", ".tif", ".tiff", ".exr", ".jpg", ".jpeg", ".pgm", ".gif"};
    const char *dot = strrchr(path, '.');
    for (size_t i = 0; dot && i < sizeof images / sizeof images[0]; i++)
        if (strcasecmp(dot, images[i]) == 0)
            return sci_error_set(err, SCI_EFORMAT,
                                 "%s: an image alone cannot be reconstructed (it holds no masks): give a .mat with "
                                 "the masks and measurements, or a problem folder (scicap sim, a capture)",
                                 path);
    return sci_error_set(err, SCI_EFORMAT,
                         "%s: unknown input format (expected a .mat file or a scicap problem folder)", path);
}

int sci_source_read(const char *path, sci_problem ***out, int *k, sci_error *err)
{
    struct stat st;
    if (stat(path, &st) != 0)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    size_t l = strlen(path);
    if (S_ISDIR(st.st_mode) || (l > 5 && strcmp(path + l - 5, ".json") == 0))
        return sci_problem_dir_read_opts(path, NULL, out, k, err);
    if (l > 4 && strcasecmp(path + l - 4, ".mat") == 0)
        return sci_mat_read_opts(path, NULL, out, k, NULL, err);
    return unknown_format(path, err);
}

int sci_source_is_mat(const char *path)
{
    size_t l = strlen(path);
    return l > 4 && strcasecmp(path + l - 4, ".mat") == 0;
}

/* Options that only a .mat takes (the limits apply to every input). */
static int mat_opts_set(const sci_mat_options *o)
{
    return o && (o->mask_path || o->mask_var || o->meas_var || o->truth_var || o->white || o->mask_white ||
                 o->frames);
}

static int refuse_mat_opts(const char *path, sci_error *err)
{
    return sci_error_set(err, -EINVAL,
                         "%s: --mask, --mask-var, --meas-var, --truth-var, --frames, --scale and --mask-scale are for "
                         ".mat input (a problem folder names its parts, frames and scale in problem.json)",
                         path);
}

int sci_source_read_opts(const char *path, const sci_mat_options *opts, sci_problem ***out, int *k,
                         sci_mat_info *info, sci_error *err)
{
    const int any = mat_opts_set(opts);
    if (!any && !sci_source_is_mat(path)) {
        struct stat st;
        if (stat(path, &st) != 0)
            return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
        size_t l = strlen(path);
        if (S_ISDIR(st.st_mode) || (l > 5 && strcmp(path + l - 5, ".json") == 0))
            return sci_problem_dir_read_opts(path, opts ? opts->limits : NULL, out, k, err);
        return sci_source_read(path, out, k, err);
    }
    if (!sci_source_is_mat(path))
        return refuse_mat_opts(path, err);
    return sci_mat_read_opts(path, opts, out, k, info, err);
}

int sci_source_probe(const char *path, const sci_mat_options *opts, long long *w, long long *h, long long *n,
                     long long *k, sci_error *err)
{
    if (sci_source_is_mat(path))
        return sci_mat_probe(path, opts, w, h, n, k, err);
    if (mat_opts_set(opts))
        return refuse_mat_opts(path, err);
    char man[4200];
    size_t l = strlen(path);
    struct stat st;
    if (stat(path, &st) != 0)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    if (l > 5 && strcmp(path + l - 5, ".json") == 0)
        snprintf(man, sizeof man, "%s", path);
    else if (S_ISDIR(st.st_mode))
        snprintf(man, sizeof man, "%s/problem.json", path);
    else
        return unknown_format(path, err);
    json_error_t je;
    json_t *j = json_load_file(man, 0, &je);
    if (!j) {
        if (access(man, R_OK) != 0)
            return sci_error_set(err, -errno, "%s: %s (not a scicap problem folder?)", man, strerror(errno));
        return sci_error_set(err, SCI_EFORMAT, "%s:%d:%d: %s", man, je.line, je.column, je.text);
    }
    /* Older folders lack w, h, n: 0 then (nothing to hold against a limit here; the reader checks the stacks). */
    *w = json_integer_value(json_object_get(j, "w"));
    *h = json_integer_value(json_object_get(j, "h"));
    *n = json_integer_value(json_object_get(j, "n"));
    *k = json_integer_value(json_object_get(j, "snapshots"));
    json_decref(j);
    return 0;
}
