/* python/pysolve.c — every reconstruction method by name, from the table the command line and the daemon use
 * (recon/solver.h): the methods and their settings, presets and keys, and solve(). A solve runs with the GIL
 * released; Ctrl-C cancels it (pyinterrupt.h) and raises KeyboardInterrupt, and an optional Python callable sees
 * every trace row (returning True stops the run, keeping the estimate so far). */
#include "python/pyinterrupt.h"

#include <errno.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "recon/solver.h"

/* A jansson value as a new Python object (through Python's json: the numbers and strings keep their meaning). */
static PyObject *json_to_py(const json_t *j)
{
    char *text = json_dumps(j, JSON_ENCODE_ANY | JSON_COMPACT);
    if (!text)
        return PyErr_NoMemory();
    PyObject *mod = PyImport_ImportModule("json");
    PyObject *v = mod ? PyObject_CallMethod(mod, "loads", "s", text) : NULL;
    Py_XDECREF(mod);
    free(text);
    return v;
}

static const char *const field_type_names[] = {"int", "float", "bool", "seed", "enum", "action", "string", "list"};

static PyObject *field_to_dict(const solver_field *f)
{
    PyObject *names = Py_NewRef(Py_None);
    if (f->names) {
        Py_DECREF(names);
        if (!(names = PyList_New(0)))
            return NULL;
        for (int i = 0; f->names[i]; i++) {
            PyObject *s = PyUnicode_FromString(f->names[i]);
            if (!s || PyList_Append(names, s) < 0) {
                Py_XDECREF(s);
                Py_DECREF(names);
                return NULL;
            }
            Py_DECREF(s);
        }
    }
    const int ranged = f->type == SOLVER_FIELD_INT || f->type == SOLVER_FIELD_DOUBLE || f->type == SOLVER_FIELD_SEED;
    return Py_BuildValue("{s:s,s:s,s:N,s:N,s:N,s:O,s:s}", "key", f->key, "type",
                         field_type_names[f->type < 8 ? f->type : 0], "min",
                         ranged ? PyFloat_FromDouble(f->lo) : Py_NewRef(Py_None), "max",
                         ranged ? PyFloat_FromDouble(f->hi) : Py_NewRef(Py_None), "choices", names, "alias",
                         (f->flags & SOLVER_FIELD_ALIAS) ? Py_True : Py_False, "help", f->help ? f->help : "");
}

static PyObject *method_to_dict(const solver_ops *m)
{
    PyObject *keys = PyList_New(0), *presets = PyDict_New(), *defaults = NULL;
    if (!keys || !presets)
        goto fail;
    for (int g = 0; g < 2; g++)
        for (int i = 0; i < m->fields[g].n; i++) {
            PyObject *d = field_to_dict(&m->fields[g].f[i]);
            if (!d || PyList_Append(keys, d) < 0) {
                Py_XDECREF(d);
                goto fail;
            }
            Py_DECREF(d);
        }
    void *s = solver_settings_new(m);
    if (!s) {
        PyErr_NoMemory();
        goto fail;
    }
    json_t *j = solver_settings_to_json(m, s);
    defaults = j ? json_to_py(j) : PyErr_NoMemory();
    json_decref(j);
    for (int p = 0; defaults && p < SOLVER_PRESET_COUNT; p++) {
        m->defaults(s);
        solver_settings_preset(m, s, (solver_preset)p);
        j = solver_settings_to_json(m, s);
        PyObject *v = j ? json_to_py(j) : PyErr_NoMemory();
        json_decref(j);
        const int bad = !v || PyDict_SetItemString(presets, solver_preset_names[p], v) < 0;
        Py_XDECREF(v);
        if (bad)
            Py_CLEAR(defaults);
    }
    solver_settings_free(s);
    if (!defaults)
        goto fail;
    return Py_BuildValue("{s:s,s:s,s:O,s:O,s:O,s:N,s:N,s:N}", "name", m->name, "summary", m->summary, "needs_camera",
                         (m->caps & SOLVER_NEEDS_CAMERA) ? Py_True : Py_False, "checkpoints",
                         (m->caps & SOLVER_CHECKPOINTS) ? Py_True : Py_False, "poses",
                         (m->caps & SOLVER_POSES) ? Py_True : Py_False, "keys", keys, "defaults", defaults, "presets",
                         presets);
fail:
    Py_XDECREF(keys);
    Py_XDECREF(presets);
    Py_XDECREF(defaults);
    return NULL;
}

static PyObject *py_methods(PyObject *self, PyObject *unused)
{
    const solver_ops *const *list = solver_list(NULL);
    PyObject *out = PyList_New(0);
    for (size_t i = 0; out && list[i]; i++) {
        PyObject *d = method_to_dict(list[i]);
        if (!d || PyList_Append(out, d) < 0)
            Py_CLEAR(out);
        Py_XDECREF(d);
    }
    return out;
}

/* The method's settings: defaults, then the JSON object `text` (its "preset" first: solver.h). NULL with an
 * exception on failure. */
static void *settings_load(const solver_ops *m, const char *text)
{
    void *s = solver_settings_new(m);
    if (!s) {
        PyErr_NoMemory();
        return NULL;
    }
    if (!text)
        return s;
    json_error_t je;
    json_t *obj = json_loads(text, 0, &je);
    sci_error err = {0};
    int rc = !obj                 ? sci_error_set(&err, -EINVAL, "settings: not JSON: %s", je.text)
             : !json_is_object(obj) ? sci_error_set(&err, -EINVAL, "settings must be a mapping of keys to values")
                                    : solver_settings_from_json(m, s, obj, NULL, "settings", &err);
    json_decref(obj);
    if (rc < 0) {
        solver_settings_free(s);
        py_error_raise(rc, &err);
        return NULL;
    }
    return s;
}

static const solver_ops *method_find(const char *name)
{
    sci_error err = {0};
    const solver_ops *m = solver_find_err(name, &err);
    if (!m)
        py_error_raise(err.code, &err);
    return m;
}

static PyObject *py_settings(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"method", "settings", NULL};
    const char *name, *text = NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "s|z:settings", kws, &name, &text))
        return NULL;
    const solver_ops *m = method_find(name);
    void *s = m ? settings_load(m, text) : NULL;
    if (!s)
        return NULL;
    json_t *j = solver_settings_to_json(m, s);
    PyObject *v = j ? json_to_py(j) : PyErr_NoMemory();
    json_decref(j);
    solver_settings_free(s);
    return v;
}

typedef struct solve_ctx {
    py_interrupt in;
    atomic_int cancel;
} solve_ctx;

static PyObject *row_to_dict(const void *arg)
{
    const sci_trace_entry *e = arg;
    return Py_BuildValue("{s:i,s:d,s:d,s:d,s:d,s:d,s:d,s:d,s:d,s:d}", "iter", e->iter, "wall_s", e->wall_s, "cpu_s",
                         e->cpu_s, "residual", e->residual, "loss", e->loss, "psnr", e->psnr, "psnr_peak1",
                         e->psnr_peak1, "ssim", e->ssim, "meas_residual", e->meas_residual, "max_weight",
                         e->max_weight);
}

/* Runs on the solver's thread, without the GIL. */
static int on_row(const sci_trace_entry *e, void *user)
{
    solve_ctx *c = user;
    if (py_interrupt_poll_call(&c->in, row_to_dict, e)) {
        atomic_store(&c->cancel, 1);
        return 1;
    }
    return 0;
}

static PyObject *py_solve(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"problem", "method", "settings", "progress", NULL};
    PyObject *prob_o, *progress = Py_None;
    const char *name = solver_list(NULL)[0]->name, *text = NULL; /* the table's first row, as scicap recon */
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|sz$O:solve", kws, &prob_o, &name, &text, &progress))
        return NULL;
    if (progress != Py_None && !PyCallable_Check(progress))
        return py_error_input("progress must be callable (it is given each trace row as a dict)");
    const solver_ops *m = method_find(name);
    if (!m)
        return NULL;
    sci_problem *p = NULL;
    void *s = settings_load(m, text);
    if (!s || py_problem_from_object(prob_o, &p) < 0) {
        solver_settings_free(s);
        return NULL;
    }
    solve_ctx ctx = {.in = {.progress = progress == Py_None ? NULL : progress}};
    atomic_init(&ctx.cancel, 0);
    solver_io io = {.progress = on_row, .user = &ctx, .cancel = &ctx.cancel};
    sci_result r = {0};
    py_interrupt_begin(&ctx.in);
    int rc = solver_run(m, p, s, &io, &r);
    py_interrupt_end(&ctx.in);
    PyObject *res = NULL;
    if (ctx.in.raised == 1)
        goto done; /* KeyboardInterrupt, or what the progress callable raised */
    if (rc < 0 && rc != SCI_ECANCELED) {
        py_error_raise(rc, &r.error);
        goto done;
    }
    json_t *sj = solver_settings_to_json(m, s);
    PyObject *frames = r.frames ? py_array_from_cube(r.frames, 0) : Py_NewRef(Py_None);
    PyObject *trace = frames ? py_trace_to_array(&r.trace) : NULL;
    PyObject *settings = trace && sj ? json_to_py(sj) : NULL;
    json_decref(sj);
    if (settings)
        res = Py_BuildValue("{s:N,s:N,s:N,s:s,s:i,s:s}", "frames", frames, "trace", trace, "settings", settings,
                            "method", m->name, "iters_done", r.iters_done, "stopped",
                            rc == SCI_ECANCELED ? "canceled" : "");
    else {
        Py_XDECREF(frames);
        Py_XDECREF(trace);
        if (!PyErr_Occurred())
            PyErr_NoMemory();
    }
done:
    sci_result_free_contents(&r);
    sci_problem_free(p);
    solver_settings_free(s);
    return res;
}

PyMethodDef py_solve_methods[] = {
    {"methods", py_methods, METH_NOARGS,
     "methods() -> list of dicts\n\nEvery reconstruction method of the table (recon/solver.h): name, summary,\n"
     "needs_camera, checkpoints, poses, keys (key, type, min, max, choices, alias, help), defaults, presets\n"
     "(fast, balanced, best: the settings each gives)."},
    {"settings", (PyCFunction)(void (*)(void))py_settings, METH_VARARGS | METH_KEYWORDS,
     "settings(method, settings=None) -> dict\n\nThe method's settings: its defaults, then the JSON object "
     "`settings` (\"preset\" first), checked."},
    {"solve", (PyCFunction)(void (*)(void))py_solve, METH_VARARGS | METH_KEYWORDS,
     "solve(problem, method='gap-tv', settings=None, *, progress=None) -> dict\n\n"
     "Reconstruct one problem: {frames (n, h, w), trace (structured array), settings, method, iters_done, "
     "stopped}.\nsettings: JSON text of the method's keys (and \"preset\"). The GIL is released; Ctrl-C raises\n"
     "KeyboardInterrupt; progress(row) is called after every iteration, True from it stops the run "
     "(stopped='canceled')."},
    {NULL, NULL, 0, NULL},
};
