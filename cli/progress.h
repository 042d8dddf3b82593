/* cli/progress.h — progress of a long solver run on a terminal: iteration, loss (NeRF methods), PSNR and SSIM
 * against the truth when known, iterations per second, ETA. On a TTY a single line is redrawn; otherwise a line
 * is printed about every 10% of the run. */
#ifndef SCICAP_CLI_PROGRESS_H
#define SCICAP_CLI_PROGRESS_H

#include <signal.h>
#include <stdint.h>

#include "recon/problem.h"

typedef struct cli_progress {
    int fd;         /* -1: silent */
    int tty;
    int total;      /* expected iterations */
    int last_pct;   /* last percentage printed (non-TTY) */
    int64_t t0_ns, last_ns;
    int iter0;      /* the iteration before the first one seen (a resumed run starts past 0); -1: none yet */
    double last_psnr, last_ssim;
    const volatile sig_atomic_t *stop; /* nonzero (set by a signal handler): ask the solver to stop; NULL: never */
} cli_progress;

void cli_progress_init(cli_progress *p, int fd, int total);
/* A sci_progress_fn: cancels the run (returns 1) once *p->stop is set. */
int cli_progress_update(const sci_trace_entry *e, void *user);
void cli_progress_done(cli_progress *p);

#endif
