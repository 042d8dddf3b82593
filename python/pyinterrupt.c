/* python/pyinterrupt.c — Ctrl-C during library calls made without the GIL (pyinterrupt.h). */
#include "python/pyinterrupt.h"

#include "base/clock.h"

void py_interrupt_begin(py_interrupt *in)
{
    in->raised = 0;
    in->last_ns = sci_clock_mono_ns();
    in->ts = PyEval_SaveThread();
}

void py_interrupt_end(py_interrupt *in)
{
    if (in->ts) {
        PyEval_RestoreThread(in->ts);
        in->ts = NULL;
    }
}

int py_interrupt_poll(py_interrupt *in)
{
    return py_interrupt_poll_call(in, NULL, NULL);
}

int py_interrupt_poll_call(py_interrupt *in, PyObject *(*make_row)(const void *), const void *arg)
{
    if (in->raised)
        return 1;
    const int64_t now = sci_clock_mono_ns();
    const int want_call = in->progress && make_row;
    if (!want_call && now - in->last_ns < PY_INTERRUPT_POLL_NS)
        return 0;
    in->last_ns = now;
    PyEval_RestoreThread(in->ts);
    in->ts = NULL;
    if (PyErr_CheckSignals() < 0) {
        in->raised = 1;
    } else if (want_call) {
        PyObject *row = make_row(arg);
        PyObject *r = row ? PyObject_CallOneArg(in->progress, row) : NULL;
        Py_XDECREF(row);
        /* A callable may stop the solve by returning True (or raising). */
        if (!r)
            in->raised = 1;
        else if (r != Py_None && PyObject_IsTrue(r) > 0)
            in->raised = 2;
        Py_XDECREF(r);
    }
    in->ts = PyEval_SaveThread();
    return in->raised != 0;
}
