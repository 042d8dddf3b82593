/* io/sandbox.h — run a parser that may crash in a child process and take its output back as bytes.
 *
 * libhdf5 has heap overflows on malformed files; a MATLAB v7.3 file is parsed through it. A crash there must end
 * one read with an error, not the daemon or the CLI. sci_sandbox_run forks; the child runs fn, which writes its
 * result to a pipe, and exits; the parent reads every byte within a time limit and waits for the child.
 *
 *     void *bytes; size_t len;
 *     rc = sci_sandbox_run(parse_fn, &args, 60000, &bytes, &len, "x.mat", &err);  // fn(&args, fd) in the child
 *     ... decode bytes ... free(bytes);
 *
 * The child is a fork of a possibly threaded process: fn must use only this thread's state and async-signal-
 * safe-after-fork libraries (malloc is, in glibc; a library lock another thread held at the fork would hang it:
 * the time limit ends that as an error too). Blocks the calling thread for the child's run.
 */
#ifndef SCICAP_IO_SANDBOX_H
#define SCICAP_IO_SANDBOX_H

#include <stddef.h>

#include "base/error.h"

/* Writes the result to fd (all of it, or the parent sees a short read). 0 on success; the child exits with
 * status 0 either way: an error the parser reports is part of its output. */
typedef int (*sci_sandbox_fn)(void *arg, int fd);

/* Run fn(arg, fd) in a child; *bytes (caller frees with free()) and *len are what it wrote. 0; or, with err naming
 * `what`: SCI_EFORMAT when the child died of a signal (the input crashed the parser) or exited nonzero,
 * -ETIMEDOUT after timeout_ms (the child is killed), -ENOMEM, -errno of fork or pipe. */
int sci_sandbox_run(sci_sandbox_fn fn, void *arg, int timeout_ms, void **bytes, size_t *len, const char *what,
                    sci_error *err);

#endif
