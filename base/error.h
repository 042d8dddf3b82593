/* base/error.h — the project's one error convention.
 *
 * Every fallible function returns 0 on success or a negative code: either -errno (-ENOMEM, -EINVAL, -EIO, ...)
 * or one of the project codes below, which sit in a reserved range (-4000 ... -4099) that no errno reaches.
 * Where the caller needs to know *what* failed, the function also takes a `sci_error *` (last argument, may
 * be NULL) and fills a message that names the thing at fault: the file, key, device or value.
 *
 *     sci_error err = {0};
 *     if (sci_mat_read(path, &set, &err) < 0)
 *         fprintf(stderr, "scicap: %s\n", err.msg);
 *
 * Library and backend code never prints and never exits; it returns an error.
 */
#ifndef SCICAP_BASE_ERROR_H
#define SCICAP_BASE_ERROR_H

#include <stdarg.h>

enum {
    SCI_EFORMAT    = -4001, /* file or message is not in the expected format (or is truncated) */
    SCI_ESHAPE     = -4002, /* sizes disagree or are out of range */
    SCI_ENONFINITE = -4003, /* NaN or Inf in an input */
    SCI_ECANCELED  = -4004, /* the progress callback asked to stop */
    SCI_EDIVERGED  = -4005, /* a solver noticed divergence (NaN loss, growing residual) and stopped */
    SCI_EDEVICE    = -4006, /* a device answered with an error (its code and text are in the message) */
    SCI_ECONFIG    = -4007, /* configuration or scene file failed validation */
    SCI_EPROTO     = -4008, /* protocol violation by a peer */
    SCI_EBUSY      = -4009, /* a bounded queue is full */
    SCI_ECODE_MIN  = -4099,
};

#define SCI_ERROR_MSG_MAX 512

typedef struct sci_error {
    int code;                    /* the code last set, 0 if none */
    char msg[SCI_ERROR_MSG_MAX]; /* human-readable, names the thing at fault; "" if none */
} sci_error;

/* Set `err` (if not NULL) to `code` and a printf-style message. Returns `code`, so callers can write
 * `return sci_error_set(err, -EINVAL, "%s: bad width %d", path, w);`. */
int sci_error_set(sci_error *err, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
int sci_error_setv(sci_error *err, int code, const char *fmt, va_list ap);

/* Prefix the existing message with more context ("file.json: " + msg). Returns err->code (0 if err is NULL). */
int sci_error_prefix(sci_error *err, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* A static description of `code` (project codes and -errno alike). Never NULL. Thread-safe. */
const char *sci_strerror(int code);

#endif
