/* python/pyops.c — the SCI operators and the image metrics on numpy arrays (recon/sci_ops.h, recon/metrics.h).
 * The GIL is released while the library computes. */
#include "python/pyscicap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "recon/metrics.h"
#include "recon/sci_ops.h"

/* mask (n, h, w) and a partner of the same frame size; *a_out has `dims` dimensions. 0 or -1. */
static int load_pair(PyObject *mask_obj, PyObject *x_obj, int dims, const char *xname, sci_cube **mask, sci_cube **x)
{
    *x = NULL;
    if (py_cube_from_array(mask_obj, 3, "mask", mask) < 0)
        return -1;
    if (py_cube_from_array(x_obj, dims, xname, x) < 0) {
        sci_cube_free(*mask);
        return -1;
    }
    if ((*x)->w != (*mask)->w || (*x)->h != (*mask)->h || (dims == 3 && (*x)->n != (*mask)->n)) {
        if (dims == 3)
            py_error_input("%s has shape (%d, %d, %d) but mask has (%d, %d, %d)", xname, (*x)->n, (*x)->h, (*x)->w,
                           (*mask)->n, (*mask)->h, (*mask)->w);
        else
            py_error_input("%s has shape (%d, %d) but the mask frames are (%d, %d)", xname, (*x)->h, (*x)->w,
                           (*mask)->h, (*mask)->w);
        sci_cube_free(*mask);
        sci_cube_free(*x);
        return -1;
    }
    return 0;
}

/* out = op(mask, in) with the GIL released, out having n_out frames; a new array, (h, w) when as_frame. Takes
 * (frees) mask and in. */
static PyObject *apply_op(sci_cube *m, sci_cube *in, int n_out, int as_frame,
                          void (*op)(const sci_cube *, const sci_cube *, sci_cube *))
{
    sci_cube *out = NULL;
    sci_error err = {0};
    int rc = sci_cube_new(&out, m->w, m->h, n_out, &err);
    if (rc == 0) {
        Py_BEGIN_ALLOW_THREADS
        op(m, in, out);
        Py_END_ALLOW_THREADS
    }
    PyObject *res = rc < 0 ? py_error_raise(rc, &err) : py_array_from_cube(out, as_frame);
    sci_cube_free(m), sci_cube_free(in), sci_cube_free(out);
    return res;
}

static PyObject *py_forward(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"mask", "x", NULL};
    PyObject *mo, *xo;
    sci_cube *m, *x;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO:forward", kws, &mo, &xo) || load_pair(mo, xo, 3, "x", &m, &x) < 0)
        return NULL;
    return apply_op(m, x, 1, 1, sci_op_forward);
}

static PyObject *py_adjoint(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"mask", "y", NULL};
    PyObject *mo, *yo;
    sci_cube *m, *y;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO:adjoint", kws, &mo, &yo) || load_pair(mo, yo, 2, "y", &m, &y) < 0)
        return NULL;
    return apply_op(m, y, m->n, 0, sci_op_adjoint);
}

static PyObject *py_phi_sum(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"mask", NULL};
    PyObject *mo;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O:phi_sum", kws, &mo))
        return NULL;
    sci_cube *m, *phi = NULL;
    if (py_cube_from_array(mo, 3, "mask", &m) < 0)
        return NULL;
    sci_error err = {0};
    int rc = sci_cube_new(&phi, m->w, m->h, 1, &err);
    if (rc == 0) {
        Py_BEGIN_ALLOW_THREADS
        sci_op_phi_sum(m, phi);
        Py_END_ALLOW_THREADS
    }
    PyObject *res = rc < 0 ? py_error_raise(rc, &err) : py_array_from_cube(phi, 1);
    sci_cube_free(m), sci_cube_free(phi);
    return res;
}

static PyObject *py_residual(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"mask", "x", "y", NULL};
    PyObject *mo, *xo, *yo;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOO:residual", kws, &mo, &xo, &yo))
        return NULL;
    sci_cube *m, *x, *y;
    if (load_pair(mo, xo, 3, "x", &m, &x) < 0)
        return NULL;
    if (py_cube_from_array(yo, 2, "y", &y) < 0) {
        sci_cube_free(m), sci_cube_free(x);
        return NULL;
    }
    if (y->w != m->w || y->h != m->h) {
        py_error_input("y has shape (%d, %d) but the mask frames are (%d, %d)", y->h, y->w, m->h, m->w);
        sci_cube_free(m), sci_cube_free(x), sci_cube_free(y);
        return NULL;
    }
    double r;
    Py_BEGIN_ALLOW_THREADS
    r = sci_op_residual(m, x, y);
    Py_END_ALLOW_THREADS
    sci_cube_free(m), sci_cube_free(x), sci_cube_free(y);
    return PyFloat_FromDouble(r);
}

/* x and truth of the same shape, 2-D or 3-D. 0 or -1. */
static int load_same(PyObject *xo, PyObject *to, sci_cube **x, sci_cube **t)
{
    if (py_cube_from_array(xo, 0, "x", x) < 0)
        return -1;
    if (py_cube_from_array(to, 0, "truth", t) < 0) {
        sci_cube_free(*x);
        return -1;
    }
    if (!sci_cube_same_shape(*x, *t)) {
        py_error_input("x has shape (%d, %d, %d) but truth has (%d, %d, %d)", (*x)->n, (*x)->h, (*x)->w, (*t)->n,
                       (*t)->h, (*t)->w);
        sci_cube_free(*x), sci_cube_free(*t);
        return -1;
    }
    return 0;
}

static PyObject *per_frame_result(double mean, const double *v, int n)
{
    npy_intp d = n;
    PyObject *a = PyArray_SimpleNew(1, &d, NPY_FLOAT64);
    if (!a)
        return NULL;
    memcpy(PyArray_DATA((PyArrayObject *)a), v, (size_t)n * sizeof *v);
    return Py_BuildValue("(dN)", mean, a);
}

/* Which metric to take: SSIM with data range `value`, or PSNR by `conv` with peak `value`. */
typedef struct metric {
    int ssim;
    sci_peak conv;
    double value;
} metric;

/* (mean, per-frame array) of metric m over x against truth, computed without the GIL. NULL with an exception set. */
static PyObject *metric_per_frame(PyObject *xo, PyObject *to, const metric *m)
{
    sci_cube *x, *t;
    if (load_same(xo, to, &x, &t) < 0)
        return NULL;
    double *v = malloc((size_t)x->n * sizeof *v), mean = NAN;
    if (!v) {
        sci_cube_free(x), sci_cube_free(t);
        return PyErr_NoMemory();
    }
    Py_BEGIN_ALLOW_THREADS
    mean = m->ssim ? sci_ssim(x, t, m->value, v) : sci_psnr(x, t, m->conv, m->value, v);
    Py_END_ALLOW_THREADS
    PyObject *res = per_frame_result(mean, v, x->n);
    free(v);
    sci_cube_free(x), sci_cube_free(t);
    return res;
}

static PyObject *py_psnr(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"x", "truth", "peak", NULL};
    PyObject *xo, *to, *peak_o = Py_None;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO|O:psnr", kws, &xo, &to, &peak_o))
        return NULL;
    double peak = 0;
    if (peak_o != Py_None && ((peak = PyFloat_AsDouble(peak_o)) == -1.0 && PyErr_Occurred()))
        return NULL;
    if (peak_o != Py_None && !(peak > 0))
        return py_error_input("peak must be > 0 (or None: each truth frame's maximum), got %g", peak);
    metric m = {.ssim = 0, .conv = peak_o == Py_None ? SCI_PEAK_FRAME_MAX : SCI_PEAK_FIXED, .value = peak};
    return metric_per_frame(xo, to, &m);
}

static PyObject *py_ssim(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"x", "truth", "data_range", NULL};
    PyObject *xo, *to;
    double range = 1.0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO|d:ssim", kws, &xo, &to, &range))
        return NULL;
    if (!(range > 0))
        return py_error_input("data_range must be > 0, got %g", range);
    metric m = {.ssim = 1, .value = range};
    return metric_per_frame(xo, to, &m);
}

PyMethodDef py_ops_methods[] = {
    {"forward", (PyCFunction)(void (*)(void))py_forward, METH_VARARGS | METH_KEYWORDS,
     "forward(mask, x) -> y\n\nThe SCI forward operator y = sum_f mask[f] * x[f]: mask and x (n, h, w), y (h, w) "
     "float32.\nSums in double, rounded once (recon/sci_ops.h)."},
    {"adjoint", (PyCFunction)(void (*)(void))py_adjoint, METH_VARARGS | METH_KEYWORDS,
     "adjoint(mask, y) -> x\n\nThe adjoint x[f] = mask[f] * y: mask (n, h, w), y (h, w), x (n, h, w) float32."},
    {"phi_sum", (PyCFunction)(void (*)(void))py_phi_sum, METH_VARARGS | METH_KEYWORDS,
     "phi_sum(mask) -> (h, w)\n\nsum_f mask[f]**2, zeros replaced by 1 (the diagonal of A A^T, guarded)."},
    {"residual", (PyCFunction)(void (*)(void))py_residual, METH_VARARGS | METH_KEYWORDS,
     "residual(mask, x, y) -> float\n\n||y - A x|| / ||y|| in double."},
    {"psnr", (PyCFunction)(void (*)(void))py_psnr, METH_VARARGS | METH_KEYWORDS,
     "psnr(x, truth, peak=None) -> (mean_db, per_frame_db)\n\nPSNR per frame and its mean; peak None: each truth "
     "frame's maximum (the MATLAB reference's convention), else a fixed peak (1 on /255 data)."},
    {"ssim", (PyCFunction)(void (*)(void))py_ssim, METH_VARARGS | METH_KEYWORDS,
     "ssim(x, truth, data_range=1.0) -> (mean, per_frame)\n\nSSIM as MATLAB's ssim (Gaussian window 1.5)."},
    {NULL, NULL, 0, NULL},
};
