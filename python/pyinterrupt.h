/* python/pyinterrupt.h — long library calls with the GIL released that still stop on Ctrl-C.
 *
 * Python's own SIGINT handler only sets a flag; the KeyboardInterrupt is raised when the main thread next runs
 * Python code, which it does not do inside a solve. So the library's progress callbacks call py_interrupt_poll:
 * at most every PY_INTERRUPT_POLL_NS it takes the GIL back, runs the pending signal handlers
 * (PyErr_CheckSignals) and, when one raised (KeyboardInterrupt, or whatever a user's handler raises), answers
 * nonzero so the callback cancels the call; the exception stays set for the caller to return.
 *
 *     py_interrupt in;
 *     py_interrupt_begin(&in);               // releases the GIL
 *     rc = solve(..., callback that returns py_interrupt_poll(&in), ...);
 *     py_interrupt_end(&in);                 // takes it back; in.raised: an exception is set
 *
 * Signals are only handled on the main thread; elsewhere the poll never cancels. Not shared between threads.
 */
#ifndef SCICAP_PYTHON_PYINTERRUPT_H
#define SCICAP_PYTHON_PYINTERRUPT_H

#include "python/pyscicap.h"

#include <stdint.h>

#define PY_INTERRUPT_POLL_NS 20000000 /* 20 ms: prompt for a person, negligible GIL traffic for a solver */

typedef struct py_interrupt {
    PyThreadState *ts; /* saved while the GIL is released; NULL while held */
    int64_t last_ns;   /* last poll */
    int raised;        /* 1: a signal handler or the progress callable raised (the exception is set once the GIL
                          is back); 2: the progress callable returned True (stop, no exception) */
    PyObject *progress; /* optional Python callable given each trace row (borrowed), or NULL */
} py_interrupt;

void py_interrupt_begin(py_interrupt *in);
void py_interrupt_end(py_interrupt *in);
/* With the GIL released: 1 when the call must stop (in->raised), else 0. */
int py_interrupt_poll(py_interrupt *in);
/* Same, and when in->progress is set, call it (every time, with the GIL) with make_row(arg), a new object; the
 * callable stops the call by raising or by returning True. */
int py_interrupt_poll_call(py_interrupt *in, PyObject *(*make_row)(const void *), const void *arg);

#endif
