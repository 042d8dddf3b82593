#include "io/matfile.h"

#include <errno.h>
#include <math.h>
#include <matio.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Element i of a matio array as double, whatever its numeric class. */
static double mat_elem(const matvar_t *v, size_t i)
{
    switch (v->class_type) {
    case MAT_C_DOUBLE: return ((const double *)v->data)[i];
    case MAT_C_SINGLE: return ((const float *)v->data)[i];
    case MAT_C_INT8: return ((const int8_t *)v->data)[i];
    case MAT_C_UINT8: return ((const uint8_t *)v->data)[i];
    case MAT_C_INT16: return ((const int16_t *)v->data)[i];
    case MAT_C_UINT16: return ((const uint16_t *)v->data)[i];
    case MAT_C_INT32: return ((const int32_t *)v->data)[i];
    case MAT_C_UINT32: return ((const uint32_t *)v->data)[i];
    case MAT_C_INT64: return (double)((const int64_t *)v->data)[i];
    case MAT_C_UINT64: return (double)((const uint64_t *)v->data)[i];
    default: return NAN;
    }
}

static int is_numeric(enum matio_classes c)
{
    return c == MAT_C_DOUBLE || c == MAT_C_SINGLE || (c >= MAT_C_INT8 && c <= MAT_C_UINT64);
}

/* Read variable `name` as H×W×F (rank 2 means F = 1). Returns the matvar or NULL with err set. */
static matvar_t *read_var(mat_t *mat, const char *path, const char *name, int required, size_t dims[3],
                          sci_error *err, int *rc)
{
    *rc = 0;
    matvar_t *v = Mat_VarRead(mat, name);
    if (!v) {
        if (required)
            *rc = sci_error_set(err, SCI_EFORMAT, "%s: variable '%s' is missing or unreadable (truncated file?)",
                                path, name);
        return NULL;
    }
    if (!is_numeric(v->class_type) || v->isComplex || !v->data) {
        *rc = sci_error_set(err, SCI_EFORMAT, "%s: variable '%s' must be a real numeric array", path, name);
        Mat_VarFree(v);
        return NULL;
    }
    if (v->rank < 2 || v->rank > 3) {
        *rc = sci_error_set(err, SCI_ESHAPE, "%s: variable '%s' must be H×W or H×W×N, has rank %d", path, name,
                            v->rank);
        Mat_VarFree(v);
        return NULL;
    }
    dims[0] = v->dims[0];
    dims[1] = v->dims[1];
    dims[2] = v->rank == 3 ? v->dims[2] : 1;
    if (dims[0] < 1 || dims[1] < 1 || dims[2] < 1 || dims[0] > 65535 || dims[1] > 65535) {
        *rc = sci_error_set(err, SCI_ESHAPE, "%s: variable '%s' has unusable size %zux%zux%zu", path, name, dims[0],
                            dims[1], dims[2]);
        Mat_VarFree(v);
        return NULL;
    }
    return v;
}

/* Copy frames [f0, f0+n) of column-major H×W×F `v` into a frame-major cube, dividing by scale. This is the one
 * place where MATLAB's layout is converted (DESIGN.md, Contracts). */
static int to_cube(const matvar_t *v, const size_t dims[3], size_t f0, int n, double scale, const char *path,
                   const char *name, sci_cube **out, sci_error *err)
{
    const int h = (int)dims[0], w = (int)dims[1];
    int rc = sci_cube_new(out, w, h, n, err);
    if (rc < 0)
        return rc;
    sci_cube *c = *out;
    for (int k = 0; k < n; k++)
        for (int x = 0; x < w; x++)
            for (int y = 0; y < h; y++) {
                double val = mat_elem(v, (size_t)y + (size_t)h * x + (size_t)h * w * (f0 + k));
                if (!isfinite(val)) {
                    sci_cube_free(c);
                    *out = NULL;
                    return sci_error_set(err, SCI_ENONFINITE, "%s: variable '%s' has a non-finite value at (%d, %d, %zu)",
                                         path, name, y + 1, x + 1, f0 + k + 1);
                }
                c->data[((size_t)k * h + y) * w + x] = (float)(val / scale);
            }
    return 0;
}

/* A MAT v5 file is a 128-byte header and a chain of tagged elements; a truncated file ends inside an element.
 * matio stops quietly at such an element (it looks like the end of the file), so walk the chain ourselves.
 * v7.3 files (HDF5) carry their own integrity checks and are left to the HDF5 library. */
static int check_v5_complete(const char *path, sci_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    unsigned char hdr[128];
    int rc = 0;
    if (fread(hdr, 1, sizeof hdr, f) != sizeof hdr) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: shorter than a MAT-file header (truncated?)", path);
        goto out;
    }
    int swap = hdr[126] == 'M' && hdr[127] == 'I';
    int version = swap ? (hdr[124] << 8 | hdr[125]) : (hdr[125] << 8 | hdr[124]);
    if (version != 0x0100)
        goto out; /* v7.3 (0x0200) or something matio will judge */
    if (fseeko(f, 0, SEEK_END) != 0) {
        rc = sci_error_set(err, -EIO, "%s: cannot seek", path);
        goto out;
    }
    off_t size = ftello(f), pos = 128;
    while (pos + 8 <= size) {
        unsigned char tag[8];
        if (fseeko(f, pos, SEEK_SET) != 0 || fread(tag, 1, 8, f) != 8)
            break;
        uint32_t type, nbytes;
        if (swap) {
            type = (uint32_t)tag[0] << 24 | (uint32_t)tag[1] << 16 | (uint32_t)tag[2] << 8 | tag[3];
            nbytes = (uint32_t)tag[4] << 24 | (uint32_t)tag[5] << 16 | (uint32_t)tag[6] << 8 | tag[7];
        } else {
            type = (uint32_t)tag[3] << 24 | (uint32_t)tag[2] << 16 | (uint32_t)tag[1] << 8 | tag[0];
            nbytes = (uint32_t)tag[7] << 24 | (uint32_t)tag[6] << 16 | (uint32_t)tag[5] << 8 | tag[4];
        }
        if (type >> 16) { /* small data element: 4 bytes of data inside the tag */
            pos += 8;
            continue;
        }
        off_t len = 8 + (off_t)nbytes;
        if (type != 15) /* miMATRIX elements are padded to 8 bytes; miCOMPRESSED (15) is not */
            len = (len + 7) & ~(off_t)7;
        if (pos + 8 + (off_t)nbytes > size) {
            rc = sci_error_set(err, SCI_EFORMAT,
                               "%s: truncated: an element at byte %lld needs %u bytes, the file ends %lld bytes later",
                               path, (long long)pos, (unsigned)nbytes, (long long)(size - pos - 8));
            goto out;
        }
        pos += len;
    }
out:
    fclose(f);
    return rc;
}

int sci_mat_read(const char *path, double scale, sci_problem ***out, int *k, sci_error *err)
{
    *out = NULL;
    *k = 0;
    if (scale == 0)
        scale = 255;
    if (access(path, R_OK) != 0)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    int rc0 = check_v5_complete(path, err);
    if (rc0 < 0)
        return rc0;
    mat_t *mat = Mat_Open(path, MAT_ACC_RDONLY);
    if (!mat)
        return sci_error_set(err, SCI_EFORMAT, "%s: not a MATLAB .mat file (v5 or v7.3), or truncated", path);
    size_t dm[3], dy[3], dt[3];
    int rc;
    matvar_t *mask = NULL, *meas = NULL, *orig = NULL;
    sci_problem **probs = NULL;
    int nprob = 0;
    if (!(mask = read_var(mat, path, "mask", 1, dm, err, &rc)) || !(meas = read_var(mat, path, "meas", 1, dy, err, &rc)))
        goto out;
    /* orig is optional, but if the file's directory lists it, a failure to read it is a fault (a truncated
     * file most often ends inside its largest variable). */
    int has_orig = 0;
    Mat_Rewind(mat);
    for (matvar_t *info; (info = Mat_VarReadNextInfo(mat)) != NULL; Mat_VarFree(info))
        has_orig |= info->name && strcmp(info->name, "orig") == 0;
    orig = read_var(mat, path, "orig", has_orig, dt, err, &rc);
    if (rc < 0)
        goto out;
    if (dm[0] != dy[0] || dm[1] != dy[1]) {
        rc = sci_error_set(err, SCI_ESHAPE, "%s: mask is %zux%zu but meas is %zux%zu (H×W)", path, dm[0], dm[1],
                           dy[0], dy[1]);
        goto out;
    }
    if (orig && (dt[0] != dm[0] || dt[1] != dm[1])) {
        rc = sci_error_set(err, SCI_ESHAPE, "%s: orig is %zux%zu but mask is %zux%zu (H×W)", path, dt[0], dt[1],
                           dm[0], dm[1]);
        goto out;
    }
    const int n = (int)dm[2], nsnap = (int)dy[2];
    probs = calloc((size_t)nsnap, sizeof *probs);
    if (!probs) {
        rc = sci_error_set(err, -ENOMEM, "%s: out of memory", path);
        goto out;
    }
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
    for (int j = 0; j < nsnap; j++) {
        sci_problem *p = calloc(1, sizeof *p);
        if (!p) {
            rc = sci_error_set(err, -ENOMEM, "%s: out of memory", path);
            goto out;
        }
        probs[nprob++] = p;
        p->peak = 255.0 / scale;
        snprintf(p->name, sizeof p->name, "%s#%d", base, j + 1);
        if ((rc = to_cube(mask, dm, 0, n, 1.0, path, "mask", &p->mask, err)) < 0 ||
            (rc = to_cube(meas, dy, (size_t)j, 1, scale, path, "meas", &p->meas, err)) < 0)
            goto out;
        if (orig && dt[2] >= (size_t)n * (j + 1) &&
            (rc = to_cube(orig, dt, (size_t)n * j, n, scale, path, "orig", &p->truth, err)) < 0)
            goto out;
    }
    *out = probs;
    *k = nprob;
    probs = NULL;
    rc = 0;
out:
    if (probs)
        sci_problem_array_free(probs, nprob);
    Mat_VarFree(mask);
    Mat_VarFree(meas);
    Mat_VarFree(orig);
    Mat_Close(mat);
    return rc;
}

/* Column-major double copy of `nframes` cubes' frames (each w×h×n), multiplied by scale. */
static matvar_t *make_var(const char *name, sci_cube *const *cubes, int ncubes, double scale)
{
    const int w = cubes[0]->w, h = cubes[0]->h;
    size_t total = 0;
    for (int i = 0; i < ncubes; i++)
        total += (size_t)cubes[i]->n;
    double *d = malloc((size_t)w * h * total * sizeof *d);
    if (!d)
        return NULL;
    size_t f0 = 0;
    for (int i = 0; i < ncubes; i++) {
        const sci_cube *c = cubes[i];
        for (int k = 0; k < c->n; k++, f0++)
            for (int x = 0; x < w; x++)
                for (int y = 0; y < h; y++)
                    d[(size_t)y + (size_t)h * x + (size_t)h * w * f0] = c->data[((size_t)k * h + y) * w + x] * scale;
    }
    size_t dims[3] = {(size_t)h, (size_t)w, total};
    matvar_t *v = Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, d, 0);
    free(d); /* Mat_VarCreate without MAT_F_DONT_COPY_DATA has copied it */
    return v;
}

int sci_mat_write(const char *path, sci_problem *const *problems, int k, double scale, sci_error *err)
{
    if (scale == 0)
        scale = 255;
    if (k < 1)
        return sci_error_set(err, -EINVAL, "%s: nothing to write", path);
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp-%d", path, (int)getpid());
    mat_t *mat = Mat_CreateVer(tmp, NULL, MAT_FT_MAT5);
    if (!mat)
        return sci_error_set(err, -EIO, "%s: cannot create", tmp);
    int rc = 0, have_truth = 1;
    sci_cube **cubes = calloc((size_t)k, sizeof *cubes);
    if (!cubes) {
        rc = sci_error_set(err, -ENOMEM, "%s: out of memory", path);
        goto out;
    }
    for (int j = 0; j < k; j++)
        have_truth &= problems[j]->truth != NULL;
    const char *names[3] = {"mask", "meas", "orig"};
    for (int var = 0; var < (have_truth ? 3 : 2) && rc == 0; var++) {
        int nc = var == 0 ? 1 : k;
        for (int j = 0; j < nc; j++)
            cubes[j] = var == 0 ? problems[0]->mask : var == 1 ? problems[j]->meas : problems[j]->truth;
        matvar_t *v = make_var(names[var], cubes, nc, var == 0 ? 1.0 : scale);
        if (!v || Mat_VarWrite(mat, v, MAT_COMPRESSION_ZLIB) != 0)
            rc = sci_error_set(err, -EIO, "%s: cannot write variable '%s'", tmp, names[var]);
        Mat_VarFree(v);
    }
out:
    free(cubes);
    Mat_Close(mat);
    if (rc == 0 && rename(tmp, path) != 0)
        rc = sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    if (rc < 0)
        unlink(tmp);
    return rc;
}
