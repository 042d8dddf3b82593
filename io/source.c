#include "io/source.h"

#include <errno.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "io/matfile.h"
#include "io/problem_dir.h"

int sci_source_read(const char *path, sci_problem ***out, int *k, sci_error *err)
{
    struct stat st;
    if (stat(path, &st) != 0)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    size_t l = strlen(path);
    if (S_ISDIR(st.st_mode) || (l > 5 && strcmp(path + l - 5, ".json") == 0))
        return sci_problem_dir_read(path, out, k, err);
    if (l > 4 && strcasecmp(path + l - 4, ".mat") == 0)
        return sci_mat_read(path, 255, out, k, err);
    return sci_error_set(err, SCI_EFORMAT,
                         "%s: unknown input format (expected a .mat benchmark file or a scicap problem folder)", path);
}

int sci_source_is_mat(const char *path)
{
    size_t l = strlen(path);
    return l > 4 && strcasecmp(path + l - 4, ".mat") == 0;
}

int sci_source_read_opts(const char *path, const sci_mat_options *opts, sci_problem ***out, int *k,
                         sci_mat_info *info, sci_error *err)
{
    const int any = opts && (opts->mask_path || opts->mask_var || opts->meas_var || opts->truth_var || opts->white);
    if (!any)
        return sci_source_read(path, out, k, err);
    if (!sci_source_is_mat(path))
        return sci_error_set(err, -EINVAL,
                             "%s: --mask, --mask-var, --meas-var, --truth-var and --scale are for .mat input (a "
                             "problem folder names its parts and scale in problem.json)",
                             path);
    return sci_mat_read_opts(path, opts, out, k, info, err);
}
