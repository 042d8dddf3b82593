/* base/log.h — logging as an object, not a global.
 *
 * Library code never prints; programs (scicap, scicapd) create a sci_log and pass it to whatever may want to
 * report. A NULL log is valid everywhere and discards messages. Thread-safe: each message is written with one
 * write(2) call of at most SCI_LOG_LINE_MAX bytes.
 */
#ifndef SCICAP_BASE_LOG_H
#define SCICAP_BASE_LOG_H

enum sci_log_level { SCI_LOG_ERR = 3, SCI_LOG_WARNING = 4, SCI_LOG_NOTICE = 5, SCI_LOG_INFO = 6, SCI_LOG_DEBUG = 7 };

#define SCI_LOG_LINE_MAX 1024

typedef struct sci_log {
    int fd;          /* where lines go (e.g. 2) */
    int level;       /* messages above this level are dropped */
    int journal;     /* 1: prefix lines with "<N>" so journald records the priority (sd-daemon(3)) */
    const char *tag; /* program name printed before each message when journal == 0; borrowed */
} sci_log;

void sci_log_write(const sci_log *log, int level, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

#endif
