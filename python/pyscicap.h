/* python/pyscicap.h — what the files of the extension module scicap._scicap share: Python and numpy's C API (one
 * import table for the whole module: scicapmodule.c imports it, the others use it), the conversions between numpy
 * arrays and the library's types, and library errors as Python exceptions.
 *
 * Arrays: a cube (base/cube.h) of n frames of h rows by w columns is a C-contiguous float32 array of shape (n, h, w)
 * — the same memory order, so conversion is one copy; a single frame (a measurement) is (h, w). Inputs of any real
 * dtype and order are accepted and converted (a copy: the library owns its cubes, 64-byte aligned).
 *
 * Problems (recon/problem.h) travel as mappings or objects with the attributes meas (h, w), mask (n, h, w),
 * truth (n, h, w) or None, camera (None or {fx, fy, cx, cy, near, far, poses (n, 3, 4) camera-to-world}), peak,
 * name: scicap.Problem (python/scicap/__init__.py) is one, a dict another.
 *
 * Errors: every function that fails returns NULL (or -1) with a Python exception set: scicap.Error (a
 * RuntimeError) carrying the library's message and its code (.code, .errname), scicap.InputError (also a
 * ValueError) for bad input (-EINVAL, SCI_ESHAPE, SCI_ENONFINITE), KeyboardInterrupt for Ctrl-C, MemoryError.
 */
#ifndef SCICAP_PYTHON_PYSCICAP_H
#define SCICAP_PYTHON_PYSCICAP_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#define PY_ARRAY_UNIQUE_SYMBOL scicap_numpy_api
#ifndef SCICAP_PY_IMPORTS_NUMPY
#define NO_IMPORT_ARRAY
#endif
#include <numpy/arrayobject.h>

#include "base/cube.h"
#include "base/error.h"
#include "recon/problem.h"

/* The exception classes, created at import (scicapmodule.c); borrowed references owned by the module. */
extern PyObject *py_error_type;       /* scicap.Error(RuntimeError) */
extern PyObject *py_input_error_type; /* scicap.InputError(Error, ValueError) */

/* Raise the exception for library code `code` with the message in err (or sci_strerror(code) when it has none).
 * The library speaks to the command line ("give --scale N", "--set weights=PATH", "use --force"): each option is
 * named as the keyword argument a Python caller gives instead (py_error_keywords). Always returns NULL. */
PyObject *py_error_raise(int code, const sci_error *err);
/* `msg` with every command-line option of the table that Python has a keyword for rewritten as that keyword:
 * "--meas-var NAME" -> "meas_var=NAME", "--set weights=P" -> "weights=P", "--force" -> "overwrite=True", a bare
 * "--scale" in a list -> "scale". Into out (n bytes, truncated). */
void py_error_keywords(const char *msg, char *out, size_t n);
/* Raise scicap.InputError with a printf-style message. Returns NULL. */
PyObject *py_error_input(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* A new cube holding a copy of `obj` (anything numpy turns into a real array): 2 dimensions (h, w) give one frame
 * when `dims` is 2, 3 dimensions (n, h, w) a stack when `dims` is 3 (0: either). `what` names the argument in the
 * message of the InputError raised otherwise. 0 or -1 (exception set). */
int py_cube_from_array(PyObject *obj, int dims, const char *what, sci_cube **out);
/* A new float32 array holding a copy of c: (h, w) when `as_frame` (c->n must be 1), else (n, h, w). */
PyObject *py_array_from_cube(const sci_cube *c, int as_frame);

/* A new problem from a scicap.Problem, a dict, or any object with the attributes above; validated
 * (sci_problem_validate). 0 or -1 (exception set). Free with sci_problem_free. */
int py_problem_from_object(PyObject *obj, sci_problem **out);
/* A new dict {meas, mask, truth, camera, peak, name} holding copies. */
PyObject *py_problem_to_dict(const sci_problem *p);
/* A list of dicts for problems[0..k-1]. */
PyObject *py_problem_list(sci_problem *const *problems, int k);
/* problems from a sequence of problem objects: *out is a malloc'd array of *k problems (sci_problem_array_free).
 * 0 or -1 (exception set). */
int py_problem_array_from_sequence(PyObject *seq, sci_problem ***out, int *k);

/* The dtype of a trace row: the fields of sci_trace_entry at their C offsets (a new reference; scicap.TRACE_DTYPE). */
PyObject *py_trace_dtype(void);
/* The trace as a numpy structured array of that dtype: one record per sci_trace_entry. */
PyObject *py_trace_to_array(const sci_trace *t);
/* The trace back from such an array (for writing a result folder). 0 or -1 (exception set). */
int py_trace_from_array(PyObject *obj, sci_trace *t);

/* The functions of the module, one file each (their docstrings are in the tables there). */
extern PyMethodDef py_ops_methods[];   /* pyops.c: forward, adjoint, phi_sum, residual, psnr, ssim */
extern PyMethodDef py_io_methods[];    /* pyio.c: read, write_mat, write_problem_dir, write_recon */
extern PyMethodDef py_sim_methods[];   /* pysim.c: simulate, default_scene */
extern PyMethodDef py_solve_methods[]; /* pysolve.c: methods, settings, solve */

#endif
