#include "base/log.h"

#include <stdarg.h>
#include <stdio.h>
#include <unistd.h>

void sci_log_write(const sci_log *log, int level, const char *fmt, ...)
{
    if (!log || level > log->level)
        return;
    char line[SCI_LOG_LINE_MAX];
    int off = log->journal ? snprintf(line, sizeof line, "<%d>", level)
                           : snprintf(line, sizeof line, "%s: ", log->tag ? log->tag : "scicap");
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(line + off, sizeof line - (size_t)off - 1, fmt, ap);
    va_end(ap);
    size_t len = (size_t)off + (n < 0 ? 0 : (size_t)n);
    if (len > sizeof line - 2)
        len = sizeof line - 2;
    line[len++] = '\n';
    ssize_t w = write(log->fd, line, len);
    (void)w; /* a log that cannot be written has nowhere to report that */
}
