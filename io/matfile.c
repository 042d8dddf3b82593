#include "io/matfile.h"

#include "base/file.h"
#include "io/mat_verify.h"
#include "io/matfile_sandbox.h"

#include <errno.h>
#include <hdf5.h>
#include <math.h>
#include <matio.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- v7.3 files: libmatio reads them through libhdf5 ----
 * HDF5 prints its whole error stack to stderr on every failure (22 KB for one damaged file) unless told not to,
 * and libmatio, when HDF5 cannot open a file, goes on with a handle that lists no variables: the user was told
 * "no variable 'meas'". So HDF5's automatic printing is off for the calling thread while this module reads (it is
 * per thread in a thread-safe libhdf5; restored after), and a v7.3 file is opened with HDF5 first: one that HDF5
 * refuses is refused here with HDF5's own innermost reason, before libmatio sees it. */
typedef struct h5_quiet {
    H5E_auto2_t fn;
    void *data;
} h5_quiet;

static void h5_quiet_begin(h5_quiet *q)
{
    if (H5Eget_auto2(H5E_DEFAULT, &q->fn, &q->data) < 0)
        q->fn = NULL, q->data = NULL;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
}

static void h5_quiet_end(const h5_quiet *q)
{
    H5Eclear2(H5E_DEFAULT);
    H5Eset_auto2(H5E_DEFAULT, q->fn, q->data);
}

/* The most specific message of the error stack (walked from the innermost). */
static herr_t h5_first_desc(unsigned n, const H5E_error2_t *e, void *user)
{
    char *buf = user;
    if (n == 0 && e && e->desc)
        snprintf(buf, 160, "%s", e->desc);
    return 0;
}

/* 0 when `path` is not an HDF5 file (libmatio's v5 path, verified elsewhere) or one HDF5 opens whole;
 * SCI_EFORMAT with one clear message when HDF5 cannot. */
static int h5_check(const char *path, sci_error *err)
{
    htri_t is = H5Fis_hdf5(path);
    H5Eclear2(H5E_DEFAULT);
    if (is <= 0)
        return 0;
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f >= 0) {
        hid_t g = H5Gopen2(f, "/", H5P_DEFAULT);
        H5G_info_t gi;
        herr_t ok = g >= 0 ? H5Gget_info(g, &gi) : -1;
        if (g >= 0)
            H5Gclose(g);
        H5Fclose(f);
        if (ok >= 0)
            return 0;
    }
    char why[160] = "";
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, h5_first_desc, why);
    H5Eclear2(H5E_DEFAULT);
    return sci_error_set(err, SCI_EFORMAT, "%s: a MATLAB v7.3 (HDF5) file that cannot be read: damaged or truncated%s%s%s",
                         path, why[0] ? " (HDF5: " : "", why, why[0] ? ")" : "");
}

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

static const char *class_name(enum matio_classes c)
{
    static const char *const names[] = {
        [MAT_C_EMPTY] = "empty",   [MAT_C_CELL] = "cell",     [MAT_C_STRUCT] = "struct", [MAT_C_OBJECT] = "object",
        [MAT_C_CHAR] = "char",     [MAT_C_SPARSE] = "sparse", [MAT_C_DOUBLE] = "double", [MAT_C_SINGLE] = "single",
        [MAT_C_INT8] = "int8",     [MAT_C_UINT8] = "uint8",   [MAT_C_INT16] = "int16",   [MAT_C_UINT16] = "uint16",
        [MAT_C_INT32] = "int32",   [MAT_C_UINT32] = "uint32", [MAT_C_INT64] = "int64",   [MAT_C_UINT64] = "uint64",
    };
    return (unsigned)c < sizeof names / sizeof names[0] && names[c] ? names[c] : "unknown";
}

/* "name HxWxN class, ..." for every variable in the directory of an open file (rewinds it). */
static void list_vars(mat_t *mat, char *buf, size_t n)
{
    size_t len = 0;
    buf[0] = 0;
    Mat_Rewind(mat);
    for (matvar_t *info; (info = Mat_VarReadNextInfo(mat)) != NULL; Mat_VarFree(info)) {
        char shape[96] = "";
        size_t sl = 0;
        for (int d = 0; d < info->rank && sl < sizeof shape - 24; d++)
            sl += (size_t)snprintf(shape + sl, sizeof shape - sl, "%s%zu", d ? "x" : "", info->dims[d]);
        if (len < n)
            len += (size_t)snprintf(buf + len, n - len, "%s%s %s %s%s", len ? ", " : "", info->name ? info->name : "?",
                                    shape, info->isComplex ? "complex " : "", class_name(info->class_type));
    }
    if (!buf[0])
        snprintf(buf, n, "no variables");
}

static int mat_list(const char *path, char *buf, size_t n);

int sci_mat_list(const char *path, char *buf, size_t n)
{
    h5_quiet q;
    h5_quiet_begin(&q);
    int rc = mat_list(path, buf, n);
    h5_quiet_end(&q);
    return rc;
}

static int mat_list(const char *path, char *buf, size_t n)
{
    /* libmatio allocates what a variable's header declares (a dims tag of 1.5 GB: fuzz_matfile): verify first */
    sci_error verr = {0};
    if (sci_mat_verify(path, &verr) < 0) {
        snprintf(buf, n, "%s", verr.msg);
        return SCI_EFORMAT;
    }
    if (h5_check(path, &verr) < 0) {
        snprintf(buf, n, "%s", verr.msg);
        return SCI_EFORMAT;
    }
    mat_t *mat = Mat_Open(path, MAT_ACC_RDONLY);
    if (!mat) {
        snprintf(buf, n, "not a .mat file");
        return SCI_EFORMAT;
    }
    list_vars(mat, buf, n);
    Mat_Close(mat);
    return 0;
}

static int has_var(mat_t *mat, const char *name)
{
    int found = 0;
    Mat_Rewind(mat);
    for (matvar_t *info; (info = Mat_VarReadNextInfo(mat)) != NULL; Mat_VarFree(info))
        found |= info->name && strcmp(info->name, name) == 0;
    return found;
}

/* The error for a variable that is not there: what the file holds and the option that names another. */
static int missing_var(mat_t *mat, const char *path, const char *name, const char *option, sci_error *err)
{
    char vars[360];
    list_vars(mat, vars, sizeof vars);
    return sci_error_set(err, SCI_EFORMAT, "%s: no variable '%s'; the file holds: %s. %s", path, name, vars, option);
}

#define MEAS_OPTION "Name the measurements with --meas-var NAME"
#define MASK_OPTION(separate) \
    ((separate) ? "Name the masks with --mask-var NAME" \
                : "Name the masks with --mask-var NAME, or give their file with --mask FILE")

/* Read variable `name` as H×W×F: rank 2 means F = 1, rank 4 (H×W×N×k) F = N·k with dims[3] = k (else 1).
 * `option` is the sentence naming the command-line option that picks another variable (for the message when it is missing).
 * Returns the matvar or NULL with err set (*rc = 0 when an optional variable is absent). */
static matvar_t *read_var(mat_t *mat, const char *path, const char *name, int required, const char *option,
                          size_t dims[4], sci_error *err, int *rc)
{
    *rc = 0;
    if (!has_var(mat, name)) {
        if (required)
            *rc = missing_var(mat, path, name, option, err);
        return NULL;
    }
    matvar_t *v = Mat_VarRead(mat, name);
    if (!v) {
        *rc = sci_error_set(err, SCI_EFORMAT, "%s: variable '%s' is unreadable (truncated file?)", path, name);
        return NULL;
    }
    if (!v->data && Mat_GetVersion(mat) == MAT_FT_MAT73) { /* HDF5 failed inside the variable */
        *rc = sci_error_set(err, SCI_EFORMAT, "%s: variable '%s' is unreadable: the MATLAB v7.3 (HDF5) file is "
                            "damaged or truncated", path, name);
        Mat_VarFree(v);
        return NULL;
    }
    if (!is_numeric(v->class_type) || v->isComplex || !v->data) {
        *rc = sci_error_set(err, SCI_EFORMAT, "%s: variable '%s' must be a real numeric array (it is %s%s)", path,
                            name, v->isComplex ? "complex " : "", class_name(v->class_type));
        Mat_VarFree(v);
        return NULL;
    }
    if (v->rank < 2 || v->rank > 4) {
        *rc = sci_error_set(err, SCI_ESHAPE, "%s: variable '%s' must be H×W, H×W×N or H×W×N×k, has rank %d", path,
                            name, v->rank);
        Mat_VarFree(v);
        return NULL;
    }
    dims[0] = v->dims[0];
    dims[1] = v->dims[1];
    dims[2] = v->rank >= 3 ? v->dims[2] : 1;
    dims[3] = v->rank == 4 ? v->dims[3] : 1;
    dims[2] *= dims[3];
    if (dims[0] < 1 || dims[1] < 1 || dims[2] < 1 || dims[0] > 65535 || dims[1] > 65535 || dims[2] > (1u << 24)) {
        *rc = sci_error_set(err, SCI_ESHAPE, "%s: variable '%s' has unusable size %zux%zux%zu", path, name, dims[0],
                            dims[1], dims[2]);
        Mat_VarFree(v);
        return NULL;
    }
    return v;
}

/* Copy frames [f0, f0+n) of column-major H×W×F `v` into a frame-major cube, dividing by scale. This is the one
 * place where MATLAB's layout is converted (docs/architecture.md, Contracts). */
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

/* The only numeric variable of a file, or NULL when there are none or several (name copied into buf). */
static const char *only_numeric_var(mat_t *mat, char *buf, size_t n)
{
    int count = 0;
    Mat_Rewind(mat);
    for (matvar_t *info; (info = Mat_VarReadNextInfo(mat)) != NULL; Mat_VarFree(info))
        if (info->name && is_numeric(info->class_type) && !info->isComplex && count++ == 0)
            snprintf(buf, n, "%s", info->name);
    return count == 1 ? buf : NULL;
}

static double var_max(const matvar_t *v, const size_t d[4])
{
    double m = -INFINITY;
    const size_t total = d[0] * d[1] * d[2];
    for (size_t i = 0; i < total; i++) {
        double x = mat_elem(v, i);
        if (x > m)
            m = x;
    }
    return m;
}

/* Where the masks of snapshot j, frame f are in the mask variable: each set holds `nset` frames, of which the
 * first n are used. */
typedef struct mask_layout {
    size_t px;  /* pixels per frame */
    int nset;   /* frames per set in the variable */
    int n;      /* frames used */
    int per;    /* one set per snapshot */
    double mw;  /* the masks' white level */
} mask_layout;

static double mask_at(const matvar_t *mask, const mask_layout *L, size_t j, int f, size_t i)
{
    return mat_elem(mask, i + L->px * ((L->per ? j * (size_t)L->nset : 0) + (size_t)f)) / L->mw;
}

/* Σ_f M̂_f over the n frames used, for snapshot j, into phi (px values); returns its maximum. */
static double mask_sum(const matvar_t *mask, const mask_layout *L, size_t j, double *phi)
{
    double pmax = 0;
    for (size_t i = 0; i < L->px; i++) {
        double acc = 0;
        for (int f = 0; f < L->n; f++)
            acc += mask_at(mask, L, j, f, i);
        phi[i] = acc;
        pmax = acc > pmax ? acc : pmax;
    }
    return pmax;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The 99.9th percentile of y / Σ_f M̂_f over the pixels where the masks let at least half their largest total
 * through (the few-open pixels are noisy), over the first 8 snapshots: how bright the frames are, in meas units
 * (a weighted mean of the frames at a pixel, so at most their maximum). NAN when nothing is lit. */
static double meas_range(const matvar_t *mask, const mask_layout *L, const matvar_t *meas, size_t nsnap)
{
    const size_t ns = nsnap < 8 ? nsnap : 8;
    double *phi = malloc(L->px * sizeof *phi), *r = malloc(L->px * ns * sizeof *r);
    size_t nr = 0;
    double pmax = 0;
    for (size_t j = 0; phi && r && j < ns; j++) {
        if (j == 0 || L->per)
            pmax = mask_sum(mask, L, j, phi);
        for (size_t i = 0; i < L->px; i++)
            if (pmax > 0 && phi[i] >= 0.5 * pmax)
                r[nr++] = mat_elem(meas, i + L->px * j) / phi[i];
    }
    double v = NAN;
    if (nr) {
        qsort(r, nr, sizeof *r, cmp_double);
        v = r[(size_t)(0.999 * (double)(nr - 1))];
    }
    free(phi);
    free(r);
    return v;
}

/* The least-squares gain ρ of meas against A(truth) (masks normalised, both in file units), over the first 8
 * snapshots that have a truth: 1 when the measurement is what the truth and masks make. NAN if undefined. */
static double meas_gain(const matvar_t *mask, const mask_layout *L, const matvar_t *meas, size_t nsnap,
                        const matvar_t *orig, size_t truth_frames)
{
    double num = 0, den = 0;
    for (size_t j = 0; j < nsnap && j < 8 && truth_frames >= (size_t)L->n * (j + 1); j++)
        for (size_t i = 0; i < L->px; i++) {
            double ax = 0;
            for (int f = 0; f < L->n; f++)
                ax += mask_at(mask, L, j, f, i) * mat_elem(orig, i + L->px * ((size_t)L->n * j + (size_t)f));
            num += ax * mat_elem(meas, i + L->px * j);
            den += ax * ax;
        }
    return den > 0 ? num / den : NAN;
}

/* The high-pass (4-neighbour Laplacian) of an h×w image at its interior pixels, into hp; returns the count. */
static size_t laplacian(const double *img, size_t h, size_t w, double *hp)
{
    size_t m = 0;
    for (size_t x = 1; x + 1 < w; x++)
        for (size_t y = 1; y + 1 < h; y++) {
            size_t i = y + h * x;
            hp[m++] = 4 * img[i] - img[i - 1] - img[i + 1] - img[i - h] - img[i + h];
        }
    return m;
}

static double correlation(const double *a, const double *b, size_t m)
{
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    for (size_t i = 0; i < m; i++)
        sa += a[i], sb += b[i], saa += a[i] * a[i], sbb += b[i] * b[i], sab += a[i] * b[i];
    double va = saa - sa * sa / (double)m, vb = sbb - sb * sb / (double)m;
    return va > 0 && vb > 0 ? (sab - sa * sb / (double)m) / sqrt(va * vb) : 0;
}

/* How many of the first mask frames the first snapshot's measurement was made with: a coded snapshot carries the
 * masks' pixel pattern, so its high-pass correlates best with the high-pass of the sum of the masks actually
 * shown (more frames add patterns it lacks, fewer miss some). Returns that count and its correlation in *best_c,
 * and the correlation of the count in use in *used_c; 0 when it cannot tell (one frame, or a tiny image). */
static int frames_guess(const matvar_t *mask, const mask_layout *L, const matvar_t *meas, size_t h, size_t w,
                        double *best_c, double *used_c)
{
    *best_c = *used_c = 0;
    if (L->nset < 2 || h < 8 || w < 8)
        return 0;
    double *phi = calloc(L->px, sizeof *phi), *img = malloc(L->px * sizeof *img);
    double *hy = malloc(L->px * sizeof *hy), *hp = malloc(L->px * sizeof *hp);
    int best = 0;
    if (phi && img && hy && hp) {
        for (size_t i = 0; i < L->px; i++)
            img[i] = mat_elem(meas, i);
        size_t m = laplacian(img, h, w, hy);
        mask_layout all = *L;
        all.n = L->nset;
        for (int f = 0; f < L->nset; f++) {
            for (size_t i = 0; i < L->px; i++)
                phi[i] += mask_at(mask, &all, 0, f, i);
            laplacian(phi, h, w, hp);
            double c = correlation(hy, hp, m);
            if (c > *best_c)
                *best_c = c, best = f + 1;
            if (f + 1 == L->n)
                *used_c = c;
        }
    }
    free(phi);
    free(img);
    free(hy);
    free(hp);
    return best;
}

/* The white level for a data maximum: the nearest usual full scale at or above it. Data up to 1.5 count as
 * [0, 1] (noise and a slight overshoot of calibrated data): a 0–255 image whose brightest value is 1.5 counts would
 * be black whatever is chosen. */
static double white_for(double range)
{
    if (range <= 1.5)
        return 1;
    static const double levels[] = {255, 1023, 4095, 65535};
    for (size_t i = 0; i < sizeof levels / sizeof levels[0]; i++)
        if (range <= levels[i] * 1.0001)
            return levels[i];
    return range;
}

/* How many frames per snapshot and whether masks are per snapshot, from the declared sizes (dims as read_var's:
 * H, W, frames, k). Shared masks H×W×N; per snapshot H×W×N×k, or H×W×(N·k) when the truth says N. */
static void split_masks(const size_t dm[4], const size_t dt[4], int have_truth, size_t nsnap, size_t *n, int *per)
{
    *n = dm[2];
    *per = 0;
    if (dm[3] > 1 || (nsnap > 1 && have_truth && dt[2] % nsnap == 0 && dt[2] / nsnap != dm[2] && dm[2] == dt[2])) {
        *per = 1;
        *n = dm[2] / nsnap;
    }
}

/* Declared H, W, frames (with rank-4 k folded in) and k of a variable from its header alone; -1 if absent. */
static int info_dims(mat_t *mat, const char *name, size_t d[4])
{
    matvar_t *info = Mat_VarReadInfo(mat, name);
    if (!info)
        return -1;
    d[0] = info->rank >= 1 ? info->dims[0] : 1;
    d[1] = info->rank >= 2 ? info->dims[1] : 1;
    d[2] = info->rank >= 3 ? info->dims[2] : 1;
    d[3] = info->rank >= 4 ? info->dims[3] : 1;
    d[2] *= d[3];
    Mat_VarFree(info);
    return 0;
}

static int probe_open(mat_t *mat, mat_t *msrc, const char *path, const char *mask_name, const char *meas_name,
                      const char *truth_name, long long *w, long long *h, long long *n, long long *k)
{
    size_t dm[4], dy[4], dt[4];
    if (!has_var(mat, meas_name) || !has_var(msrc, mask_name) || info_dims(mat, meas_name, dy) < 0 ||
        info_dims(msrc, mask_name, dm) < 0)
        return -1;
    const int have_truth = has_var(mat, truth_name) && info_dims(mat, truth_name, dt) == 0;
    size_t nn;
    int per;
    split_masks(dm, dt, have_truth, dy[2], &nn, &per);
    *w = (long long)dm[1], *h = (long long)dm[0], *n = (long long)nn, *k = (long long)dy[2];
    return 0;
}

static int mat_probe(const char *path, const sci_mat_options *opts, long long *w, long long *h, long long *n,
                     long long *k, sci_error *err);

int sci_mat_probe(const char *path, const sci_mat_options *opts, long long *w, long long *h, long long *n,
                  long long *k, sci_error *err)
{
    h5_quiet q;
    h5_quiet_begin(&q);
    /* v7.3 goes through libhdf5, which a malformed file can crash: in a child (io/matfile_sandbox.h) */
    int rc = sci_mat_is_v73(path, opts ? opts->mask_path : NULL)
                 ? sci_mat_probe_sandboxed(mat_probe, path, opts, w, h, n, k, err)
                 : mat_probe(path, opts, w, h, n, k, err);
    h5_quiet_end(&q);
    return rc;
}

static int mat_probe(const char *path, const sci_mat_options *opts, long long *w, long long *h, long long *n,
                     long long *k, sci_error *err)
{
    const sci_mat_options none = {0};
    const sci_mat_options *o = opts ? opts : &none;
    const char *paths[2] = {path, o->mask_path};
    for (int i = 0; i < (o->mask_path ? 2 : 1); i++) {
        if (access(paths[i], R_OK) != 0)
            return sci_error_set(err, -errno, "%s: %s", paths[i], strerror(errno));
        int rc0 = sci_mat_verify(paths[i], err);
        if (rc0 < 0 || (rc0 = h5_check(paths[i], err)) < 0)
            return rc0;
    }
    mat_t *mat = Mat_Open(path, MAT_ACC_RDONLY), *mmat = NULL;
    if (!mat)
        return sci_error_set(err, SCI_EFORMAT, "%s: not a MATLAB .mat file (v5 or v7.3), or truncated", path);
    if (o->mask_path && !(mmat = Mat_Open(o->mask_path, MAT_ACC_RDONLY))) {
        Mat_Close(mat);
        return sci_error_set(err, SCI_EFORMAT, "%s: not a MATLAB .mat file (v5 or v7.3), or truncated",
                             o->mask_path);
    }
    mat_t *msrc = mmat ? mmat : mat;
    char only[64];
    const char *mask_name = o->mask_var ? o->mask_var : "mask";
    if (mmat && !o->mask_var && !has_var(mmat, "mask") && only_numeric_var(mmat, only, sizeof only))
        mask_name = only;
    const char *meas_name = o->meas_var ? o->meas_var : "meas";
    int rc = 0;
    if (!has_var(mat, meas_name))
        rc = missing_var(mat, path, meas_name, MEAS_OPTION, err);
    else if (!has_var(msrc, mask_name))
        rc = missing_var(msrc, o->mask_path ? o->mask_path : path, mask_name, MASK_OPTION(o->mask_path), err);
    else if (probe_open(mat, msrc, path, mask_name, meas_name, o->truth_var ? o->truth_var : "orig", w, h, n, k) < 0)
        rc = sci_error_set(err, SCI_EFORMAT, "%s: variable '%s' or '%s' is unreadable", path, meas_name, mask_name);
    else if (o->frames > 0 && o->frames < *n)
        *n = o->frames;
    if (mmat)
        Mat_Close(mmat);
    Mat_Close(mat);
    return rc;
}

/* 1 when every value of v is a whole number. */
static int var_integral(const matvar_t *v, const size_t d[4])
{
    const size_t total = d[0] * d[1] * d[2];
    for (size_t i = 0; i < total; i++) {
        double x = mat_elem(v, i);
        if (x != floor(x))
            return 0;
    }
    return 1;
}

/* x rounded up to two significant digits (97.7 → 98, 122.2 → 130). */
static double round_up2(double x)
{
    if (!(x > 0))
        return x;
    double e = pow(10, floor(log10(x)) - 1);
    return ceil(x / e - 1e-9) * e;
}

/* Append a sentence to info->how ("; " between). */
static void how_add(sci_mat_info *info, const char *fmt, ...)
{
    size_t l = strlen(info->how);
    if (l && l + 2 < sizeof info->how)
        l += (size_t)snprintf(info->how + l, sizeof info->how - l, "; ");
    va_list ap;
    va_start(ap, fmt);
    if (l < sizeof info->how)
        vsnprintf(info->how + l, sizeof info->how - l, fmt, ap);
    va_end(ap);
}

/* The masks' white level, meas's and truth's (io/matfile.h, Scales), into L->mw and info; `legacy` > 0 fixes meas
 * and truth to it and the masks to 1. Also the warning when the measurement matches fewer mask frames. */
static int infer_scales(const sci_mat_options *o, double legacy, const matvar_t *mask, const size_t dm[4],
                        const matvar_t *meas, const size_t dy[4], const matvar_t *orig, const size_t dt[4],
                        mask_layout *L, const char *mask_name, const char *meas_name, const char *truth_name,
                        sci_mat_info *info, const char *path, sci_error *err)
{
    if (legacy > 0) {
        info->white = info->meas_white = legacy;
        info->mask_white = L->mw = 1;
        return 0;
    }
    if (o->mask_white > 0) {
        L->mw = o->mask_white;
    } else {
        double mmax = var_max(mask, dm);
        L->mw = mmax > 1.0001 ? mmax : 1;
        if (L->mw != 1)
            how_add(info, "masks '%s' peak at %g, divided by it", mask_name, mmax);
    }
    info->mask_white = L->mw;
    double guess_c, used_c;
    int guess = frames_guess(mask, L, meas, dm[0], dm[1], &guess_c, &used_c);
    if (guess && guess != L->n && guess_c > 0.2 && used_c < 0.8 * guess_c)
        snprintf(info->warning, sizeof info->warning,
                 "the measurement matches the first %d of the %d mask frames best (high-pass correlation %.2f, "
                 "against %.2f for the %d in use): if the capture's compression ratio is %d, give --frames %d",
                 guess, L->nset, guess_c, used_c, L->n, guess, guess);
    if (o->white > 0) {
        info->white = info->meas_white = o->white;
        return 0;
    }
    double range;
    if (orig) {
        range = var_max(orig, dt);
        info->white = info->meas_white = white_for(range);
        double g = meas_gain(mask, L, meas, dy[2], orig, dt[2]);
        if (isfinite(g) && g > 0 && fabs(g - 1) > 0.2) {
            info->meas_white = info->white * g;
            how_add(info, "truth '%s' peaks at %g, so white is %g; meas '%s' is %.3g times what the truth makes "
                          "through the masks, so it is divided by %g",
                    truth_name, range, info->white, meas_name, g, info->meas_white);
        } else {
            how_add(info, "truth '%s' peaks at %g, so white is %g", truth_name, range, info->white);
        }
        return 0;
    }
    range = meas_range(mask, L, meas, dy[2]);
    if (!(range > 0) || !isfinite(range))
        return sci_error_set(err, SCI_EFORMAT,
                             "%s: cannot infer the white level (meas '%s' over the sum of masks is %g where they "
                             "open); give --scale N (the value of white)",
                             path, meas_name, range);
    /* Integer counts come from an ADC of a usual depth: its full scale. Processed (fractional) values have no such
     * scale: a quarter of headroom over the estimate (a weighted mean, below the frames' peaks), 2 digits. */
    const int counts = var_integral(meas, dy);
    info->white = info->meas_white = counts || range <= 1.5 ? white_for(range) : round_up2(1.25 * range);
    how_add(info, "meas '%s' over the sum of the %d masks reaches %.4g (99.9th percentile), so white is %g%s",
            meas_name, L->n, range, info->white,
            info->white == 1 ? " (data already on [0, 1])"
            : counts         ? " (integer counts: the usual full scale at or above it)"
                             : " (fractional values: that with a quarter of headroom)");
    return 0;
}

/* The common reader. `legacy` > 0: meas and truth divided by it, masks as stored, peak 255 / legacy (sci_mat_read);
 * else the scales of `o`, inferred where not given, and peak 1. */
static int mat_read_quiet(const char *path, const sci_mat_options *o, double legacy, sci_problem ***out, int *k,
                          sci_mat_info *info, sci_error *err);

static int mat_read(const char *path, const sci_mat_options *o, double legacy, sci_problem ***out, int *k,
                    sci_mat_info *info, sci_error *err)
{
    h5_quiet q;
    h5_quiet_begin(&q);
    /* v7.3 goes through libhdf5, which a malformed file can crash: in a child (io/matfile_sandbox.h) */
    int rc = sci_mat_is_v73(path, o->mask_path) ? sci_mat_read_sandboxed(mat_read_quiet, path, o, legacy, out, k,
                                                                          info, err)
                                                : mat_read_quiet(path, o, legacy, out, k, info, err);
    h5_quiet_end(&q);
    return rc;
}

/* The files of a read exist, are readable and pass io/mat_verify.h's and the HDF5 checks. 0 or their error. */
static int mat_files_check(const char *path, const char *mask_file, int two, sci_error *err)
{
    const char *paths[2] = {path, mask_file};
    for (int i = 0; i < (two ? 2 : 1); i++) {
        if (access(paths[i], R_OK) != 0)
            return sci_error_set(err, -errno, "%s: %s", paths[i], strerror(errno));
        int rc0 = sci_mat_verify(paths[i], err);
        if (rc0 < 0 || (rc0 = h5_check(paths[i], err)) < 0)
            return rc0;
    }
    return 0;
}

/* The variables of one read (owned: Mat_VarFree), their dims as read_var's (H, W, frames, k) and names. */
typedef struct mat_vars {
    const char *path, *mask_file, *mask_name, *meas_name, *truth_name;
    char only[64]; /* the one variable of a separate mask file, when it names the masks */
    matvar_t *mask, *meas, *orig;
    size_t dm[4], dy[4], dt[4];
} mat_vars;

/* Read meas, the masks and the truth into V after checking the declared sizes against the limits; their H×W must
 * agree. 0 or the error (V's variables then freed by the caller). */
static int mat_vars_read(mat_t *mat, mat_t *msrc, const sci_mat_options *o, mat_vars *V, sci_error *err)
{
    const char *path = V->path;
    int rc = 0;
    /* What the variables declare, before libmatio allocates it: a 2 KB file can declare gigabytes. */
    {
        sci_io_limits deflim;
        const sci_io_limits *lim = o->limits;
        if (!lim)
            sci_io_limits_default(&deflim), lim = &deflim;
        long long pw, ph, pn, pk;
        if (probe_open(mat, msrc, path, V->mask_name, V->meas_name, V->truth_name, &pw, &ph, &pn, &pk) == 0 &&
            (rc = sci_io_limits_check_input(lim, path, pw, ph, pn, pk, err)) < 0)
            return rc;
    }
    if (!(V->meas = read_var(mat, path, V->meas_name, 1, MEAS_OPTION, V->dy, err, &rc)) ||
        !(V->mask = read_var(msrc, V->mask_file, V->mask_name, 1, MASK_OPTION(o->mask_path), V->dm, err, &rc)))
        return rc;
    /* The truth is optional, but a named one must be there, and one the directory lists must be readable (a
     * truncated file most often ends inside its largest variable). */
    V->orig = read_var(mat, path, V->truth_name, o->truth_var != NULL || has_var(mat, V->truth_name),
                       "Name the truth with --truth-var NAME (it is optional)", V->dt, err,
                       &rc);
    if (rc < 0)
        return rc;
    const size_t *dm = V->dm, *dy = V->dy, *dt = V->dt;
    if (dm[0] != dy[0] || dm[1] != dy[1])
        return sci_error_set(err, SCI_ESHAPE, "%s: mask '%s' is %zux%zu but meas '%s' is %zux%zu (H×W)", path,
                             V->mask_name, dm[0], dm[1], V->meas_name, dy[0], dy[1]);
    if (V->orig && (dt[0] != dm[0] || dt[1] != dm[1]))
        return sci_error_set(err, SCI_ESHAPE, "%s: truth '%s' is %zux%zu but mask '%s' is %zux%zu (H×W)", path,
                             V->truth_name, dt[0], dt[1], V->mask_name, dm[0], dm[1]);
    return rc;
}

/* The snapshots (*nsnap) and the masks' layout L (white level 1 until inferred), checked against --frames and
 * the truth's frame count; the layout's part of info. 0 or SCI_ESHAPE. */
static int mat_layout(const sci_mat_options *o, const mat_vars *V, mask_layout *L, int *nsnap, sci_mat_info *info,
                      sci_error *err)
{
    const char *path = V->path, *mask_name = V->mask_name;
    const size_t *dm = V->dm, *dy = V->dy, *dt = V->dt;
    *nsnap = (int)dy[2];
    /* Shared or per-snapshot masks: H×W×N×k says so; H×W×(N·k) does when the truth gives N = frames / k. */
    size_t nsplit;
    int per;
    split_masks(dm, dt, V->orig != NULL, (size_t)*nsnap, &nsplit, &per);
    if (per && (dm[2] % (size_t)*nsnap != 0 || (dm[3] > 1 && dm[3] != (size_t)*nsnap)))
        return sci_error_set(err, SCI_ESHAPE, "%s: per-snapshot masks '%s' (%zu frames) do not divide into %d "
                                              "snapshots", V->mask_file, mask_name, dm[2], *nsnap);
    *L = (mask_layout){.px = dm[0] * dm[1], .nset = (int)nsplit, .n = (int)nsplit, .per = per, .mw = 1};
    info->mask_per_snapshot = per;
    info->mask_frames = L->nset;
    if (o->frames > L->nset)
        return sci_error_set(err, SCI_ESHAPE, "%s: --frames %d, but the masks '%s' hold %d frames%s", path,
                             o->frames, mask_name, L->nset, per ? " per snapshot" : "");
    if (o->frames > 0)
        L->n = o->frames;
    const int n = L->n;
    info->frames = n;
    if (V->orig && (dt[2] < (size_t)n || (dt[2] % (size_t)n != 0 && dt[2] < (size_t)n * (size_t)*nsnap)))
        return sci_error_set(err, SCI_ESHAPE,
                             "%s: truth '%s' has %zu frames but the masks '%s' %d per snapshot (%d snapshot(s)); "
                             "if the capture used the first %zu masks, give --frames %zu",
                             path, V->truth_name, dt[2], mask_name, n, *nsnap, dt[2] / (size_t)*nsnap,
                             dt[2] / (size_t)*nsnap);
    return 0;
}

/* One problem per snapshot into *probs (*nprob of them made so far, freed by the caller also on an error), each
 * at the scales in info. 0 or the error. */
static int mat_problems_make(const mat_vars *V, const mask_layout *L, int nsnap, double legacy,
                             const sci_mat_info *info, sci_problem ***probs, int *nprob, sci_error *err)
{
    const char *path = V->path;
    const int n = L->n;
    int rc = 0;
    *probs = calloc((size_t)nsnap, sizeof **probs);
    if (!*probs)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
    for (int j = 0; j < nsnap; j++) {
        sci_problem *p = calloc(1, sizeof *p);
        if (!p)
            return sci_error_set(err, -ENOMEM, "%s: out of memory", path);
        (*probs)[(*nprob)++] = p;
        p->peak = legacy > 0 ? 255.0 / legacy : 1.0;
        snprintf(p->name, sizeof p->name, "%s#%d", base, j + 1);
        if ((rc = to_cube(V->mask, V->dm, L->per ? (size_t)L->nset * j : 0, n, L->mw, V->mask_file, V->mask_name,
                          &p->mask, err)) < 0 ||
            (rc = to_cube(V->meas, V->dy, (size_t)j, 1, info->meas_white, path, V->meas_name, &p->meas, err)) < 0)
            return rc;
        if (V->orig && V->dt[2] >= (size_t)n * (j + 1) &&
            (rc = to_cube(V->orig, V->dt, (size_t)n * j, n, info->white, path, V->truth_name, &p->truth, err)) < 0)
            return rc;
    }
    return rc;
}

static int mat_read_quiet(const char *path, const sci_mat_options *o, double legacy, sci_problem ***out, int *k,
                          sci_mat_info *info, sci_error *err)
{
    *out = NULL;
    *k = 0;
    sci_mat_info local;
    if (!info)
        info = &local;
    memset(info, 0, sizeof *info);
    mat_vars V = {.path = path,
                  .meas_name = o->meas_var ? o->meas_var : "meas",
                  .truth_name = o->truth_var ? o->truth_var : "orig",
                  .mask_file = o->mask_path ? o->mask_path : path};
    int rc = mat_files_check(path, V.mask_file, o->mask_path != NULL, err);
    if (rc < 0)
        return rc;
    mat_t *mat = Mat_Open(path, MAT_ACC_RDONLY), *mmat = NULL;
    if (!mat)
        return sci_error_set(err, SCI_EFORMAT, "%s: not a MATLAB .mat file (v5 or v7.3), or truncated", path);
    sci_problem **probs = NULL;
    int nprob = 0;
    if (o->mask_path) {
        mmat = Mat_Open(o->mask_path, MAT_ACC_RDONLY);
        if (!mmat) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s: not a MATLAB .mat file (v5 or v7.3), or truncated", o->mask_path);
            goto out;
        }
    }
    mat_t *msrc = mmat ? mmat : mat;
    V.mask_name = o->mask_var ? o->mask_var : "mask";
    /* A separate mask file with one variable needs no --mask-var (real-data sets ship e.g. mask.mat with one). */
    if (mmat && !o->mask_var && !has_var(mmat, "mask") && only_numeric_var(mmat, V.only, sizeof V.only))
        V.mask_name = V.only;
    snprintf(info->mask_var, sizeof info->mask_var, "%s", V.mask_name);
    mask_layout L = {0};
    int nsnap = 0;
    if ((rc = mat_vars_read(mat, msrc, o, &V, err)) < 0 || (rc = mat_layout(o, &V, &L, &nsnap, info, err)) < 0 ||
        (rc = infer_scales(o, legacy, V.mask, V.dm, V.meas, V.dy, V.orig, V.dt, &L, V.mask_name, V.meas_name,
                           V.truth_name, info, path, err)) < 0 ||
        (rc = mat_problems_make(&V, &L, nsnap, legacy, info, &probs, &nprob, err)) < 0)
        goto out;
    *out = probs;
    *k = nprob;
    probs = NULL;
    rc = 0;
out:
    if (probs)
        sci_problem_array_free(probs, nprob);
    Mat_VarFree(V.mask);
    Mat_VarFree(V.meas);
    Mat_VarFree(V.orig);
    if (mmat)
        Mat_Close(mmat);
    Mat_Close(mat);
    return rc;
}

int sci_mat_read(const char *path, double scale, sci_problem ***out, int *k, sci_error *err)
{
    const sci_mat_options o = {0};
    return mat_read(path, &o, scale == 0 ? 255 : scale, out, k, NULL, err);
}

int sci_mat_read_opts(const char *path, const sci_mat_options *opts, sci_problem ***out, int *k,
                      sci_mat_info *info, sci_error *err)
{
    const sci_mat_options none = {0};
    const sci_mat_options *o = opts ? opts : &none;
    if ((o->white != SCI_MAT_WHITE_AUTO && o->white < 0) || !(o->mask_white >= 0) || o->frames < 0)
        return sci_error_set(err, -EINVAL, "%s: the white levels must be > 0 and the frames ≥ 1 (got %g, %g, %d)", path,
                             o->white, o->mask_white, o->frames);
    return mat_read(path, o, 0, out, k, info, err);
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

typedef struct mat_job {
    sci_problem *const *problems;
    int k;
    double scale;
} mat_job;

/* The variables mask, meas and (when every problem has one) orig, into the file named tmp. */
static int mat_write_named(const char *tmp, void *user, sci_error *err)
{
    const mat_job *job = user;
    const int k = job->k;
    mat_t *mat = Mat_CreateVer(tmp, NULL, MAT_FT_MAT5);
    if (!mat)
        return sci_error_set(err, -EIO, "%s: cannot create", tmp);
    int rc = 0, have_truth = 1;
    sci_cube **cubes = calloc((size_t)k, sizeof *cubes);
    if (!cubes) {
        Mat_Close(mat);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", tmp);
    }
    for (int j = 0; j < k; j++)
        have_truth &= job->problems[j]->truth != NULL;
    const char *names[3] = {"mask", "meas", "orig"};
    for (int var = 0; var < (have_truth ? 3 : 2) && rc == 0; var++) {
        int nc = var == 0 ? 1 : k;
        for (int j = 0; j < nc; j++)
            cubes[j] = var == 0   ? job->problems[0]->mask
                       : var == 1 ? job->problems[j]->meas
                                  : job->problems[j]->truth;
        matvar_t *v = make_var(names[var], cubes, nc, var == 0 ? 1.0 : job->scale);
        if (!v || Mat_VarWrite(mat, v, MAT_COMPRESSION_ZLIB) != 0)
            rc = sci_error_set(err, -EIO, "%s: cannot write variable '%s'", tmp, names[var]);
        Mat_VarFree(v);
    }
    free(cubes);
    Mat_Close(mat);
    return rc;
}

int sci_mat_write(const char *path, sci_problem *const *problems, int k, double scale, sci_error *err)
{
    if (scale == 0)
        scale = 255;
    if (k < 1)
        return sci_error_set(err, -EINVAL, "%s: nothing to write", path);
    const mat_job job = {problems, k, scale};
    return sci_file_write_atomic_named(path, 0644, 0, mat_write_named, (void *)&job, err);
}
