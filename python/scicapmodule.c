/* python/scicapmodule.c — the extension module scicap._scicap: its function table (gathered from the files that
 * implement them: pyops.c, pyio.c, pysim.c, pysolve.c), the exception classes, and numpy's C API import.
 * The Python package scicap (python/scicap/__init__.py) wraps it; docs/python.md documents both. */
#define SCICAP_PY_IMPORTS_NUMPY
#include "python/pyscicap.h"

#include "recon/problem.h"

static PyMethodDef *const method_tables[] = {py_ops_methods, py_io_methods, py_sim_methods, py_solve_methods};

static int add_functions(PyObject *mod)
{
    for (size_t t = 0; t < sizeof method_tables / sizeof method_tables[0]; t++)
        if (PyModule_AddFunctions(mod, method_tables[t]) < 0)
            return -1;
    return 0;
}

static int add_exceptions(PyObject *mod)
{
    py_error_type = PyErr_NewExceptionWithDoc(
        "scicap.Error", "A library error: the message names the file, key or value at fault; .code is the "
        "library's negative code (-errno or a SCI_E* code of base/error.h) and .errname its description.",
        PyExc_RuntimeError, NULL);
    if (!py_error_type || PyModule_AddObjectRef(mod, "Error", py_error_type) < 0)
        return -1;
    PyObject *bases = PyTuple_Pack(2, py_error_type, PyExc_ValueError);
    if (!bases)
        return -1;
    py_input_error_type = PyErr_NewExceptionWithDoc(
        "scicap.InputError", "Bad input (a shape, a value out of range, NaN or Inf, an unknown name): a "
        "scicap.Error and a ValueError.", bases, NULL);
    Py_DECREF(bases);
    if (!py_input_error_type || PyModule_AddObjectRef(mod, "InputError", py_input_error_type) < 0)
        return -1;
    return 0;
}

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, "_scicap",
    "scicap's C library on numpy arrays: operators, metrics, files, simulator, solvers (see the scicap package).",
    -1, NULL, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__scicap(void)
{
    import_array();
    PyObject *mod = PyModule_Create(&module_def);
    if (!mod)
        return NULL;
    PyObject *dtype = py_trace_dtype();
    if (!dtype || PyModule_AddObject(mod, "TRACE_DTYPE", dtype) < 0) {
        Py_XDECREF(dtype);
        Py_DECREF(mod);
        return NULL;
    }
    if (add_functions(mod) < 0 || add_exceptions(mod) < 0 ||
        PyModule_AddStringConstant(mod, "VERSION", SCICAP_VERSION) < 0) {
        Py_DECREF(mod);
        return NULL;
    }
    return mod;
}
