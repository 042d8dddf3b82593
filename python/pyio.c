/* python/pyio.c — files: any problem source (a .mat or a problem folder, io/source.h), writing .mat files and
 * problem folders, and writing a reconstruction folder as `scicap recon` does (io/recon_store.h). The GIL is
 * released during file I/O. */
#include "python/pyscicap.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "io/limits.h"
#include "io/matfile.h"
#include "io/problem_dir.h"
#include "io/recon_store.h"
#include "io/source.h"

static PyObject *py_read(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"path", "mask", "mask_var", "meas_var", "truth_var", "scale", "allow_large", "frames",
                          "mask_scale", NULL};
    PyObject *path_o, *scale_o = Py_None;
    const char *mask = NULL, *mask_var = NULL, *meas_var = NULL, *truth_var = NULL;
    int allow_large = 0, frames = 0;
    double mask_scale = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&|$zzzzOpid:read", kws, PyUnicode_FSConverter, &path_o, &mask,
                                     &mask_var, &meas_var, &truth_var, &scale_o, &allow_large, &frames, &mask_scale))
        return NULL;
    if (frames < 0 || mask_scale < 0 || isnan(mask_scale)) {
        Py_DECREF(path_o);
        if (frames < 0)
            return py_error_input("frames must be >= 0 (0: every mask frame), got %d", frames);
        return py_error_input("mask_scale must be > 0 (the value of a fully open mask pixel), got %g", mask_scale);
    }
    sci_mat_options mo = {.mask_path = mask, .mask_var = mask_var, .meas_var = meas_var, .truth_var = truth_var,
                          .frames = frames, .mask_white = mask_scale};
    sci_io_limits lim;
    sci_io_limits_default(&lim);
    if (allow_large)
        sci_io_limits_none(&lim);
    mo.limits = &lim;
    if (PyUnicode_Check(scale_o) && strcmp(PyUnicode_AsUTF8(scale_o), "auto") == 0) {
        mo.white = SCI_MAT_WHITE_AUTO;
    } else if (scale_o != Py_None) {
        mo.white = PyFloat_AsDouble(scale_o);
        if ((mo.white == -1.0 && PyErr_Occurred()) || !(mo.white > 0)) {
            PyErr_Clear();
            Py_DECREF(path_o);
            return py_error_input("scale must be 'auto' or a number > 0 (the value of white in the file)");
        }
    }
    const char *path = PyBytes_AS_STRING(path_o);
    sci_problem **ps = NULL;
    int k = 0, rc;
    sci_error err = {0};
    Py_BEGIN_ALLOW_THREADS
    rc = sci_source_read_opts(path, &mo, &ps, &k, NULL, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(path_o);
    if (rc < 0)
        return py_error_raise(rc, &err);
    PyObject *list = py_problem_list(ps, k);
    sci_problem_array_free(ps, k);
    return list;
}

static PyObject *py_probe(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"path", NULL};
    PyObject *path_o;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&:probe", kws, PyUnicode_FSConverter, &path_o))
        return NULL;
    long long w, h, n, k;
    sci_error err = {0};
    int rc;
    Py_BEGIN_ALLOW_THREADS
    rc = sci_source_probe(PyBytes_AS_STRING(path_o), NULL, &w, &h, &n, &k, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(path_o);
    if (rc < 0)
        return py_error_raise(rc, &err);
    return Py_BuildValue("{s:L,s:L,s:L,s:L}", "w", w, "h", h, "n", n, "snapshots", k);
}

static PyObject *py_write_mat(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"path", "problems", "scale", NULL};
    PyObject *path_o, *seq;
    double scale = 255;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&O|d:write_mat", kws, PyUnicode_FSConverter, &path_o, &seq, &scale))
        return NULL;
    sci_problem **ps;
    int k, rc;
    if (!(scale > 0)) {
        Py_DECREF(path_o);
        return py_error_input("scale must be > 0 (values are multiplied by it), got %g", scale);
    }
    if (py_problem_array_from_sequence(seq, &ps, &k) < 0) {
        Py_DECREF(path_o);
        return NULL;
    }
    sci_error err = {0};
    Py_BEGIN_ALLOW_THREADS
    rc = sci_mat_write(PyBytes_AS_STRING(path_o), ps, k, scale, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(path_o);
    sci_problem_array_free(ps, k);
    return rc < 0 ? py_error_raise(rc, &err) : Py_NewRef(Py_None);
}

/* Optional JSON text to a jansson value; NULL text gives NULL without error. 0 or -1. */
static int json_from_text(const char *text, const char *what, json_t **out)
{
    *out = NULL;
    if (!text)
        return 0;
    json_error_t je;
    if (!(*out = json_loads(text, 0, &je))) {
        py_error_input("%s is not valid JSON: line %d: %s", what, je.line, je.text);
        return -1;
    }
    return 0;
}

static PyObject *py_write_problem_dir(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"dir", "problems", "overwrite", "previews", "source", NULL};
    PyObject *path_o, *seq;
    int overwrite = 0, previews = 1;
    const char *source_text = NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&O|$ppz:write_problem_dir", kws, PyUnicode_FSConverter, &path_o,
                                     &seq, &overwrite, &previews, &source_text))
        return NULL;
    json_t *source;
    sci_problem **ps = NULL;
    int k = 0, rc;
    if (json_from_text(source_text, "source", &source) < 0 || py_problem_array_from_sequence(seq, &ps, &k) < 0) {
        json_decref(source);
        Py_DECREF(path_o);
        return NULL;
    }
    sci_error err = {0};
    Py_BEGIN_ALLOW_THREADS
    rc = sci_problem_dir_write_opt(PyBytes_AS_STRING(path_o), ps, k, source, overwrite, previews, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(path_o);
    json_decref(source);
    sci_problem_array_free(ps, k);
    return rc < 0 ? py_error_raise(rc, &err) : Py_NewRef(Py_None);
}

static PyObject *py_write_recon(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"dir", "problem", "frames", "trace", "method", "params", "overwrite", NULL};
    PyObject *path_o, *prob_o, *frames_o, *trace_o;
    const char *method = "", *params_text = NULL;
    int overwrite = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&OOO|$szp:write_recon", kws, PyUnicode_FSConverter, &path_o, &prob_o,
                                     &frames_o, &trace_o, &method, &params_text, &overwrite))
        return NULL;
    sci_problem *p = NULL;
    sci_result r = {0};
    json_t *params = NULL;
    PyObject *res = NULL;
    if (py_problem_from_object(prob_o, &p) < 0 || py_cube_from_array(frames_o, 3, "frames", &r.frames) < 0 ||
        py_trace_from_array(trace_o, &r.trace) < 0 || json_from_text(params_text, "params", &params) < 0)
        goto done;
    if (!sci_cube_same_shape(r.frames, p->mask)) {
        py_error_input("frames have shape (%d, %d, %d) but the problem's masks (%d, %d, %d)", r.frames->n,
                       r.frames->h, r.frames->w, p->mask->n, p->mask->h, p->mask->w);
        goto done;
    }
    snprintf(r.method, sizeof r.method, "%s", method);
    r.iters_done = r.trace.len ? r.trace.e[r.trace.len - 1].iter : 0;
    sci_error err = {0};
    int rc;
    Py_BEGIN_ALLOW_THREADS
    rc = sci_recon_store_write(PyBytes_AS_STRING(path_o), p, &r, params, overwrite, &err);
    Py_END_ALLOW_THREADS
    res = rc < 0 ? py_error_raise(rc, &err) : Py_NewRef(Py_None);
done:
    Py_DECREF(path_o);
    json_decref(params);
    sci_result_free_contents(&r);
    sci_problem_free(p);
    return res;
}

PyMethodDef py_io_methods[] = {
    {"read", (PyCFunction)(void (*)(void))py_read, METH_VARARGS | METH_KEYWORDS,
     "read(path, *, mask=None, mask_var=None, meas_var=None, truth_var=None, scale=None, allow_large=False,\n"
     "     frames=0, mask_scale=0)\n\n"
     "The problems in a .mat file (values divided by scale: 255 by default, 'auto' reads the data's range; frames:\n"
     "the first N masks, 0 all; mask_scale: a fully open mask pixel's value, 0 inferred) or a problem folder, as a\n"
     "list of dicts (scicap.read wraps them in scicap.Problem). io/source.h, docs/formats.md."},
    {"probe", (PyCFunction)(void (*)(void))py_probe, METH_VARARGS | METH_KEYWORDS,
     "probe(path) -> {w, h, n, snapshots}\n\nThe sizes a source declares, without reading its data."},
    {"write_mat", (PyCFunction)(void (*)(void))py_write_mat, METH_VARARGS | METH_KEYWORDS,
     "write_mat(path, problems, scale=255)\n\nA benchmark-layout .mat (v5, compressed): mask, meas, orig."},
    {"write_problem_dir", (PyCFunction)(void (*)(void))py_write_problem_dir, METH_VARARGS | METH_KEYWORDS,
     "write_problem_dir(dir, problems, *, overwrite=False, previews=True, source=None)\n\n"
     "A problem folder (problem.json and float EXR stacks), written whole or not at all; source: JSON text."},
    {"write_recon", (PyCFunction)(void (*)(void))py_write_recon, METH_VARARGS | METH_KEYWORDS,
     "write_recon(dir, problem, frames, trace, *, method='', params=None, overwrite=False)\n\n"
     "A reconstruction folder as scicap recon writes it (frames, previews, trace.csv, result.json); params: JSON."},
    {NULL, NULL, 0, NULL},
};
