/* python/pyarray.c — numpy arrays to and from cubes, problems and traces (pyscicap.h). */
#include "python/pyscicap.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

int py_cube_from_array(PyObject *obj, int dims, const char *what, sci_cube **out)
{
    *out = NULL;
    if (obj == NULL || obj == Py_None) {
        py_error_input("%s is required (a numpy array)", what);
        return -1;
    }
    PyArrayObject *any = (PyArrayObject *)PyArray_FROM_O(obj);
    if (!any)
        return -1;
    const char kind = PyArray_DESCR(any)->kind;
    if (kind != 'b' && kind != 'i' && kind != 'u' && kind != 'f') {
        py_error_input("%s must be a real numeric array, got dtype kind '%c'", what, kind);
        Py_DECREF(any);
        return -1;
    }
    /* float64 and integer inputs are cast on purpose: the library works in float32
     * (docs/architecture.md, Contracts: Numerics). */
    PyArrayObject *a = (PyArrayObject *)PyArray_FROM_OTF((PyObject *)any, NPY_FLOAT32,
                                                        NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED |
                                                            NPY_ARRAY_FORCECAST);
    Py_DECREF(any);
    if (!a)
        return -1;
    const int nd = PyArray_NDIM(a);
    const npy_intp *d = PyArray_DIMS(a);
    if ((dims && nd != dims) || (nd != 2 && nd != 3)) {
        if (dims == 2)
            py_error_input("%s must be one frame of shape (h, w), got %d dimension(s)", what, nd);
        else if (dims == 3)
            py_error_input("%s must be a stack of shape (n, h, w), got %d dimension(s)", what, nd);
        else
            py_error_input("%s must have shape (h, w) or (n, h, w), got %d dimension(s)", what, nd);
        Py_DECREF(a);
        return -1;
    }
    const npy_intp n = nd == 3 ? d[0] : 1, h = d[nd - 2], w = d[nd - 1];
    if (n < 1 || h < 1 || w < 1 || n > INT_MAX || h > INT_MAX || w > INT_MAX) {
        py_error_input("%s has an empty or oversized shape (%ld, %ld, %ld)", what, (long)n, (long)h, (long)w);
        Py_DECREF(a);
        return -1;
    }
    sci_error err = {0};
    int rc = sci_cube_new(out, (int)w, (int)h, (int)n, &err);
    if (rc < 0) {
        Py_DECREF(a);
        sci_error_prefix(&err, "%s: ", what);
        py_error_raise(rc, &err);
        return -1;
    }
    memcpy((*out)->data, PyArray_DATA(a), sci_cube_count(*out) * sizeof(float));
    Py_DECREF(a);
    return 0;
}

PyObject *py_array_from_cube(const sci_cube *c, int as_frame)
{
    npy_intp d[3] = {c->n, c->h, c->w};
    PyObject *a = as_frame ? PyArray_SimpleNew(2, d + 1, NPY_FLOAT32) : PyArray_SimpleNew(3, d, NPY_FLOAT32);
    if (a)
        memcpy(PyArray_DATA((PyArrayObject *)a), c->data, sci_cube_count(c) * sizeof(float));
    return a;
}

/* A field of a dict or an attribute of an object: a new reference, Py_None when absent (no exception). */
static PyObject *field_get(PyObject *obj, const char *key)
{
    PyObject *v = NULL;
    if (PyDict_Check(obj)) {
        v = PyDict_GetItemString(obj, key);
        Py_XINCREF(v);
    } else if (PyObject_HasAttrString(obj, key)) {
        v = PyObject_GetAttrString(obj, key);
    }
    if (!v && !PyErr_Occurred())
        v = Py_NewRef(Py_None);
    return v;
}

/* A number field; `dflt` when absent (NAN: required). 0 or -1. */
static int field_double(PyObject *obj, const char *owner, const char *key, double dflt, double *out)
{
    PyObject *v = field_get(obj, key);
    if (!v)
        return -1;
    if (v == Py_None) {
        Py_DECREF(v);
        if (isnan(dflt)) {
            py_error_input("%s.%s is required", owner, key);
            return -1;
        }
        *out = dflt;
        return 0;
    }
    *out = PyFloat_AsDouble(v);
    Py_DECREF(v);
    if (*out == -1.0 && PyErr_Occurred()) {
        PyErr_Clear();
        py_error_input("%s.%s must be a number", owner, key);
        return -1;
    }
    return 0;
}

static int camera_from_object(PyObject *obj, int n, sci_camera **out)
{
    *out = NULL;
    double fx, fy, cx, cy, near_m, far_m;
    if (field_double(obj, "camera", "fx", NAN, &fx) < 0 || field_double(obj, "camera", "fy", fx, &fy) < 0 ||
        field_double(obj, "camera", "cx", NAN, &cx) < 0 || field_double(obj, "camera", "cy", NAN, &cy) < 0 ||
        field_double(obj, "camera", "near", NAN, &near_m) < 0 || field_double(obj, "camera", "far", NAN, &far_m) < 0)
        return -1;
    PyObject *poses = field_get(obj, "poses");
    if (!poses)
        return -1;
    PyArrayObject *a = poses == Py_None ? NULL
                                        : (PyArrayObject *)PyArray_FROM_OTF(poses, NPY_FLOAT64,
                                                                            NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED);
    Py_DECREF(poses);
    if (!a) {
        if (!PyErr_Occurred())
            py_error_input("camera.poses is required: an array of shape (n, 3, 4), camera-to-world");
        return -1;
    }
    const npy_intp *d = PyArray_DIMS(a);
    const int ok = (PyArray_NDIM(a) == 3 && d[1] == 3 && d[2] == 4) || (PyArray_NDIM(a) == 2 && d[1] == 12);
    if (!ok || d[0] != n) {
        py_error_input("camera.poses must have shape (%d, 3, 4) (one pose per frame), got %d dimension(s) with %ld "
                       "pose(s)", n, PyArray_NDIM(a), (long)d[0]);
        Py_DECREF(a);
        return -1;
    }
    sci_camera *c = sci_camera_new(n);
    if (!c) {
        Py_DECREF(a);
        PyErr_NoMemory();
        return -1;
    }
    c->fx = fx, c->fy = fy, c->cx = cx, c->cy = cy, c->near_m = near_m, c->far_m = far_m;
    memcpy(c->pose, PyArray_DATA(a), (size_t)n * sizeof *c->pose);
    Py_DECREF(a);
    *out = c;
    return 0;
}

/* A cube field of a problem: 0 (maybe *out = NULL when optional and absent) or -1. */
static int field_cube(PyObject *obj, const char *key, int dims, int required, sci_cube **out)
{
    *out = NULL;
    PyObject *v = field_get(obj, key);
    if (!v)
        return -1;
    char what[64];
    snprintf(what, sizeof what, "problem.%s", key);
    int rc = (v == Py_None && !required) ? 0 : py_cube_from_array(v, dims, what, out);
    Py_DECREF(v);
    return rc;
}

int py_problem_from_object(PyObject *obj, sci_problem **out)
{
    *out = NULL;
    sci_problem *p = calloc(1, sizeof *p);
    if (!p) {
        PyErr_NoMemory();
        return -1;
    }
    PyObject *name = NULL, *cam = NULL;
    if (field_cube(obj, "meas", 2, 1, &p->meas) < 0 || field_cube(obj, "mask", 3, 1, &p->mask) < 0 ||
        field_cube(obj, "truth", 3, 0, &p->truth) < 0 || field_double(obj, "problem", "peak", 1.0, &p->peak) < 0)
        goto fail;
    if (!(name = field_get(obj, "name")))
        goto fail;
    if (name != Py_None) {
        const char *s = PyUnicode_Check(name) ? PyUnicode_AsUTF8(name) : NULL;
        if (!s) {
            PyErr_Clear();
            py_error_input("problem.name must be a string");
            goto fail;
        }
        snprintf(p->name, sizeof p->name, "%s", s);
    }
    if (!(cam = field_get(obj, "camera")))
        goto fail;
    if (cam != Py_None && camera_from_object(cam, p->mask->n, &p->camera) < 0)
        goto fail;
    sci_error err = {0};
    int rc = sci_problem_validate(p, &err);
    if (rc < 0) {
        py_error_raise(rc, &err);
        goto fail;
    }
    Py_XDECREF(name);
    Py_XDECREF(cam);
    *out = p;
    return 0;
fail:
    Py_XDECREF(name);
    Py_XDECREF(cam);
    sci_problem_free(p);
    return -1;
}

static PyObject *camera_to_dict(const sci_camera *c)
{
    npy_intp d[3] = {c->n, 3, 4};
    PyObject *poses = PyArray_SimpleNew(3, d, NPY_FLOAT64);
    if (!poses)
        return NULL;
    memcpy(PyArray_DATA((PyArrayObject *)poses), c->pose, (size_t)c->n * sizeof *c->pose);
    return Py_BuildValue("{s:d,s:d,s:d,s:d,s:d,s:d,s:N}", "fx", c->fx, "fy", c->fy, "cx", c->cx, "cy", c->cy, "near",
                         c->near_m, "far", c->far_m, "poses", poses);
}

PyObject *py_problem_to_dict(const sci_problem *p)
{
    PyObject *meas = py_array_from_cube(p->meas, 1);
    PyObject *mask = meas ? py_array_from_cube(p->mask, 0) : NULL;
    PyObject *truth = !mask ? NULL : p->truth ? py_array_from_cube(p->truth, 0) : Py_NewRef(Py_None);
    PyObject *cam = !truth ? NULL : p->camera ? camera_to_dict(p->camera) : Py_NewRef(Py_None);
    if (!cam) {
        Py_XDECREF(meas);
        Py_XDECREF(mask);
        Py_XDECREF(truth);
        return NULL;
    }
    return Py_BuildValue("{s:N,s:N,s:N,s:N,s:d,s:s}", "meas", meas, "mask", mask, "truth", truth, "camera", cam,
                         "peak", p->peak, "name", p->name);
}

PyObject *py_problem_list(sci_problem *const *problems, int k)
{
    PyObject *list = PyList_New(k);
    for (int j = 0; list && j < k; j++) {
        PyObject *d = py_problem_to_dict(problems[j]);
        if (!d) {
            Py_CLEAR(list);
            break;
        }
        PyList_SET_ITEM(list, j, d);
    }
    return list;
}

int py_problem_array_from_sequence(PyObject *seq, sci_problem ***out, int *k)
{
    *out = NULL, *k = 0;
    PyObject *fast = PySequence_Fast(seq, "problems must be a sequence of problems");
    if (!fast)
        return -1;
    const Py_ssize_t n = PySequence_Fast_GET_SIZE(fast);
    if (n < 1 || n > INT_MAX) {
        Py_DECREF(fast);
        py_error_input("problems must hold at least one problem");
        return -1;
    }
    sci_problem **ps = calloc((size_t)n, sizeof *ps);
    if (!ps) {
        Py_DECREF(fast);
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t j = 0; j < n; j++)
        if (py_problem_from_object(PySequence_Fast_GET_ITEM(fast, j), &ps[j]) < 0) {
            sci_problem_array_free(ps, (int)j);
            Py_DECREF(fast);
            return -1;
        }
    Py_DECREF(fast);
    *out = ps, *k = (int)n;
    return 0;
}

/* The trace's fields in sci_trace_entry order: name, numpy type, offset in the C struct. */
static const struct {
    const char *name, *type;
    size_t off;
} trace_fields[] = {
    {"iter", "i4", offsetof(sci_trace_entry, iter)},
    {"wall_s", "f8", offsetof(sci_trace_entry, wall_s)},
    {"cpu_s", "f8", offsetof(sci_trace_entry, cpu_s)},
    {"residual", "f8", offsetof(sci_trace_entry, residual)},
    {"loss", "f8", offsetof(sci_trace_entry, loss)},
    {"psnr", "f8", offsetof(sci_trace_entry, psnr)},
    {"psnr_peak1", "f8", offsetof(sci_trace_entry, psnr_peak1)},
    {"ssim", "f8", offsetof(sci_trace_entry, ssim)},
    {"meas_residual", "f8", offsetof(sci_trace_entry, meas_residual)},
    {"max_weight", "f8", offsetof(sci_trace_entry, max_weight)},
};
#define TRACE_NFIELDS (sizeof trace_fields / sizeof trace_fields[0])

/* The trace dtype with the C struct's own layout (names, formats, offsets, itemsize), so rows copy as they are. */
static PyArray_Descr *trace_dtype(void)
{
    PyObject *names = PyList_New(TRACE_NFIELDS), *formats = PyList_New(TRACE_NFIELDS),
             *offsets = PyList_New(TRACE_NFIELDS);
    if (!names || !formats || !offsets)
        goto fail;
    for (size_t i = 0; i < TRACE_NFIELDS; i++) {
        PyList_SET_ITEM(names, i, PyUnicode_FromString(trace_fields[i].name));
        PyList_SET_ITEM(formats, i, PyUnicode_FromString(trace_fields[i].type));
        PyList_SET_ITEM(offsets, i, PyLong_FromSize_t(trace_fields[i].off));
    }
    PyObject *spec = Py_BuildValue("{s:N,s:N,s:N,s:n}", "names", names, "formats", formats, "offsets", offsets,
                                   "itemsize", (Py_ssize_t)sizeof(sci_trace_entry));
    if (!spec)
        return NULL;
    PyArray_Descr *d = NULL;
    PyArray_DescrConverter(spec, &d);
    Py_DECREF(spec);
    return d;
fail:
    Py_XDECREF(names);
    Py_XDECREF(formats);
    Py_XDECREF(offsets);
    return NULL;
}

PyObject *py_trace_dtype(void)
{
    return (PyObject *)trace_dtype();
}

PyObject *py_trace_to_array(const sci_trace *t)
{
    PyArray_Descr *d = trace_dtype();
    if (!d)
        return NULL;
    npy_intp len = (npy_intp)t->len;
    PyObject *a = PyArray_NewFromDescr(&PyArray_Type, d, 1, &len, NULL, NULL, 0, NULL); /* steals d */
    if (a && t->len)
        memcpy(PyArray_DATA((PyArrayObject *)a), t->e, t->len * sizeof *t->e);
    return a;
}

int py_trace_from_array(PyObject *obj, sci_trace *t)
{
    PyArray_Descr *d = trace_dtype();
    if (!d)
        return -1;
    /* Any array with the same field names converts (a view with another layout, a copy of it, a record array). */
    PyArrayObject *a = (PyArrayObject *)PyArray_FromAny(obj, d, 1, 1, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED |
                                                                          NPY_ARRAY_FORCECAST, NULL); /* steals d */
    if (!a) {
        PyErr_Clear();
        py_error_input("trace must be a one-dimensional array of scicap.TRACE_DTYPE records");
        return -1;
    }
    const npy_intp n = PyArray_DIM(a, 0);
    const sci_trace_entry *rows = PyArray_DATA(a);
    for (npy_intp i = 0; i < n; i++)
        if (sci_trace_push(t, &rows[i]) < 0) {
            Py_DECREF(a);
            PyErr_NoMemory();
            return -1;
        }
    Py_DECREF(a);
    return 0;
}
