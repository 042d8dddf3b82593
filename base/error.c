#include "base/error.h"

#include <stdio.h>
#include <string.h>

int sci_error_setv(sci_error *err, int code, const char *fmt, va_list ap)
{
    if (err) {
        err->code = code;
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    }
    return code;
}

int sci_error_set(sci_error *err, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    sci_error_setv(err, code, fmt, ap);
    va_end(ap);
    return code;
}

int sci_error_prefix(sci_error *err, const char *fmt, ...)
{
    if (!err)
        return 0;
    char pre[SCI_ERROR_MSG_MAX], old[SCI_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(pre, sizeof pre, fmt, ap);
    va_end(ap);
    memcpy(old, err->msg, sizeof old);
    snprintf(err->msg, sizeof err->msg, "%s%s", pre, old);
    return err->code;
}

const char *sci_strerror(int code)
{
    switch (code) {
    case 0: return "success";
    case SCI_EFORMAT: return "bad or truncated format";
    case SCI_ESHAPE: return "sizes disagree or out of range";
    case SCI_ENONFINITE: return "NaN or Inf in input";
    case SCI_ECANCELED: return "canceled";
    case SCI_EDIVERGED: return "solver diverged";
    case SCI_EDEVICE: return "device error";
    case SCI_ECONFIG: return "invalid configuration";
    case SCI_EPROTO: return "protocol error";
    case SCI_EBUSY: return "queue full";
    default: break;
    }
    if (code < 0 && code > -4000)
        return strerror(-code); /* glibc's strerror returns static strings for known codes */
    return "unknown error";
}
