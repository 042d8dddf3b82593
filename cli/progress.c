#include "cli/progress.h"

#include <math.h>
#include <stdio.h>
#include <unistd.h>

#include "base/clock.h"

void cli_progress_init(cli_progress *p, int fd, int total)
{
    *p = (cli_progress){.fd = fd, .tty = fd >= 0 && isatty(fd), .total = total, .last_pct = -1,
                        .t0_ns = sci_clock_mono_ns(), .last_psnr = NAN, .last_ssim = NAN, .iter0 = -1};
}

int cli_progress_update(const sci_trace_entry *e, void *user)
{
    cli_progress *p = user;
    if (p->stop && *p->stop)
        return 1;
    if (p->fd < 0)
        return 0;
    if (!isnan(e->psnr))
        p->last_psnr = e->psnr;
    if (!isnan(e->ssim))
        p->last_ssim = e->ssim;
    if (p->iter0 < 0)
        p->iter0 = e->iter - 1;
    int64_t now = sci_clock_mono_ns();
    int pct = p->total > 0 ? (int)(100.0 * e->iter / p->total) : 0;
    double el = sci_clock_s(p->t0_ns, now);
    const int done = e->iter - p->iter0; /* iterations run by this process */
    double eta = done > 0 ? el * (p->total - e->iter) / done : 0;
    double rate = el > 0 ? done / el : 0;
    if (p->tty && now - p->last_ns < 100000000 && e->iter < p->total)
        return 0; /* at most 10 redraws a second */
    if (!p->tty && pct / 10 == p->last_pct / 10 && e->iter != p->total)
        return 0;
    char line[256];
    int n = snprintf(line, sizeof line, "  iter %d/%d %3d%%", e->iter, p->total, pct);
    if (isfinite(e->loss))
        n += snprintf(line + n, sizeof line - (size_t)n, "  loss %.4g", e->loss);
    else
        n += snprintf(line + n, sizeof line - (size_t)n, "  residual %.3g", e->residual);
    if (!isnan(p->last_psnr))
        n += snprintf(line + n, sizeof line - (size_t)n, "  PSNR %.2f dB", p->last_psnr);
    if (!isnan(p->last_ssim))
        n += snprintf(line + n, sizeof line - (size_t)n, "  SSIM %.3f", p->last_ssim);
    snprintf(line + n, sizeof line - (size_t)n, "  %.3g it/s  ETA %.*fs", rate, eta < 10 ? 1 : 0, eta);
    p->last_ns = now;
    p->last_pct = pct;
    dprintf(p->fd, p->tty ? "\r%s   " : "%s\n", line);
    return 0;
}

void cli_progress_done(cli_progress *p)
{
    if (p->fd >= 0 && p->tty)
        dprintf(p->fd, "\n");
}
