#include "tests/helpers/testfiles.h"

#include <glob.h>
#include <matio.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>

#include "io/problem_dir.h"

void testfiles_write_problem(const char *path, int w, int h, int n, int k)
{
    sci_problem **p = calloc((size_t)k, sizeof *p);
    assert_non_null(p);
    sci_cube *mask;
    assert_int_equal(sci_cube_new(&mask, w, h, n, NULL), 0);
    for (size_t i = 0; i < sci_cube_count(mask); i++)
        mask->data[i] = (float)((i * 2654435761u >> 7) & 1);
    for (int j = 0; j < k; j++) {
        p[j] = calloc(1, sizeof *p[j]);
        assert_non_null(p[j]);
        p[j]->peak = 1;
        snprintf(p[j]->name, sizeof p[j]->name, "limits#%d", j + 1);
        assert_int_equal(sci_cube_clone(&p[j]->mask, mask, NULL), 0);
        assert_int_equal(sci_cube_new(&p[j]->meas, w, h, 1, NULL), 0);
        for (size_t i = 0; i < sci_cube_frame_size(p[j]->meas); i++)
            p[j]->meas->data[i] = (float)(i % 7) * 0.5f;
    }
    sci_error err = {0};
    if (sci_problem_dir_write_opt(path, p, k, NULL, 1, 0, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube_free(mask);
    sci_problem_array_free(p, k);
}

void testfiles_write_declared_mat(const char *path, size_t snapshots)
{
    mat_t *m = Mat_CreateVer(path, NULL, MAT_FT_MAT5);
    assert_non_null(m);
    size_t dm[3] = {8, 8, 8}, dy[3] = {8, 8, snapshots};
    double *mask = calloc(8 * 8 * 8, sizeof *mask), *meas = calloc((size_t)8 * 8 * snapshots, sizeof *meas);
    assert_non_null(mask);
    assert_non_null(meas);
    for (int i = 0; i < 8 * 8 * 8; i++)
        mask[i] = i % 2;
    for (size_t i = 0; i < (size_t)8 * 8 * snapshots; i++)
        meas[i] = 4;
    testfiles_mat_put(m, "mask", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dm, mask, MAT_COMPRESSION_ZLIB);
    testfiles_mat_put(m, "meas", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dy, meas, MAT_COMPRESSION_ZLIB);
    Mat_Close(m);
    free(mask);
    free(meas);
    assert_int_equal(chmod(path, 0644), 0);
}

void testfiles_assert_nothing_at(const char *out)
{
    struct stat st;
    if (stat(out, &st) == 0)
        fail_msg("%s exists", out);
    char pat[600];
    glob_t g;
    for (int i = 0; i < 2; i++) {
        snprintf(pat, sizeof pat, "%s.%s-*", out, i ? "old" : "tmp");
        if (glob(pat, 0, NULL, &g) == 0) {
            const char *first = g.gl_pathv[0];
            fail_msg("%s left behind", first);
        }
        globfree(&g);
    }
}

void testfiles_mat_put(mat_t *m, const char *name, enum matio_classes cls, enum matio_types type, int rank,
                       size_t *dims, void *data, enum matio_compression compression)
{
    matvar_t *v = Mat_VarCreate(name, cls, type, rank, dims, data, 0);
    assert_non_null(v);
    assert_int_equal(Mat_VarWrite(m, v, compression), 0);
    Mat_VarFree(v);
}

void testfiles_expect_all(const char *text, const char *const *want)
{
    for (; *want; want++)
        if (!strstr(text, *want))
            fail_msg("missing \"%s\" in:\n%s", *want, text);
}
