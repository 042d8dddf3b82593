#include "cli/progress.h"

#include <math.h>
#include <stdio.h>
#include <unistd.h>

#include "base/clock.h"

void cli_progress_init(cli_progress *p, int fd, int total)
{
    *p = (cli_progress){.fd = fd, .tty = fd >= 0 && isatty(fd), .total = total, .last_pct = -1,
                        .t0_ns = sci_clock_mono_ns(), .last_psnr = NAN};
}

int cli_progress_update(const sci_trace_entry *e, void *user)
{
    cli_progress *p = user;
    if (p->fd < 0)
        return 0;
    if (!isnan(e->psnr))
        p->last_psnr = e->psnr;
    int64_t now = sci_clock_mono_ns();
    int pct = p->total > 0 ? (int)(100.0 * e->iter / p->total) : 0;
    double el = sci_clock_s(p->t0_ns, now);
    double eta = e->iter > 0 ? el * (p->total - e->iter) / e->iter : 0;
    char psnr[32] = "";
    if (!isnan(p->last_psnr))
        snprintf(psnr, sizeof psnr, "  PSNR %.2f dB", p->last_psnr);
    if (p->tty) {
        if (now - p->last_ns < 100000000 && e->iter < p->total)
            return 0; /* at most 10 redraws a second */
        p->last_ns = now;
        dprintf(p->fd, "\r  iter %d/%d %3d%%  residual %.3g%s  ETA %.1fs   ", e->iter, p->total, pct, e->residual,
                psnr, eta);
    } else if (pct / 10 != p->last_pct / 10 || e->iter == p->total) {
        p->last_pct = pct;
        dprintf(p->fd, "  iter %d/%d %3d%%  residual %.3g%s  ETA %.1fs\n", e->iter, p->total, pct, e->residual,
                psnr, eta);
    }
    return 0;
}

void cli_progress_done(cli_progress *p)
{
    if (p->fd >= 0 && p->tty)
        dprintf(p->fd, "\n");
}
