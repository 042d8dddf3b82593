/* python/pyerror.c — library errors as Python exceptions (pyscicap.h). */
#include "python/pyscicap.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>

PyObject *py_error_type;
PyObject *py_input_error_type;

/* Bad input is the caller's to fix: it is also a ValueError, so generic handlers catch it. */
static int is_input_code(int code)
{
    return code == -EINVAL || code == SCI_ESHAPE || code == SCI_ENONFINITE || code == -ERANGE;
}

static PyObject *raise_with(PyObject *type, int code, const char *msg)
{
    PyObject *exc = PyObject_CallFunction(type, "s", msg);
    if (!exc)
        return NULL;
    PyObject *c = PyLong_FromLong(code), *name = PyUnicode_FromString(sci_strerror(code));
    if (c && name && PyObject_SetAttrString(exc, "code", c) == 0 && PyObject_SetAttrString(exc, "errname", name) == 0)
        PyErr_SetObject(type, exc);
    Py_XDECREF(c);
    Py_XDECREF(name);
    Py_DECREF(exc);
    return NULL;
}

PyObject *py_error_raise(int code, const sci_error *err)
{
    if (code == -ENOMEM)
        return PyErr_NoMemory();
    const char *msg = err && err->msg[0] ? err->msg : sci_strerror(code);
    return raise_with(is_input_code(code) ? py_input_error_type : py_error_type, code, msg);
}

PyObject *py_error_input(const char *fmt, ...)
{
    sci_error err = {0};
    va_list ap;
    va_start(ap, fmt);
    sci_error_setv(&err, -EINVAL, fmt, ap);
    va_end(ap);
    return raise_with(py_input_error_type, -EINVAL, err.msg);
}
