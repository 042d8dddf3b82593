/* io/source.h — open any problem source by its path: a benchmark .mat file or a problem folder (written by
 * `scicap sim` or by the daemon's capture store). Dispatch is by what the path is: a .mat extension goes to
 * io/matfile.h (values /255), a folder or a problem.json to io/problem_dir.h. Anything else is SCI_EFORMAT with
 * a message that says what was expected. Result and errors as the underlying readers. */
#ifndef SCICAP_IO_SOURCE_H
#define SCICAP_IO_SOURCE_H

#include "recon/problem.h"

int sci_source_read(const char *path, sci_problem ***out, int *k, sci_error *err);

#endif
