/* python/pyerror.c — library errors as Python exceptions (pyscicap.h). */
#include "python/pyscicap.h"

#include <ctype.h>
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

PyObject *py_error_type;
PyObject *py_input_error_type;

/* Bad input is the caller's to fix: it is also a ValueError, so generic handlers catch it. */
static int is_input_code(int code)
{
    return code == -EINVAL || code == SCI_ESHAPE || code == SCI_ENONFINITE || code == -ERANGE;
}

static PyObject *raise_with(PyObject *type, int code, const char *msg)
{
    PyObject *exc = PyObject_CallFunction(type, "s", msg);
    if (!exc)
        return NULL;
    PyObject *c = PyLong_FromLong(code), *name = PyUnicode_FromString(sci_strerror(code));
    if (c && name && PyObject_SetAttrString(exc, "code", c) == 0 && PyObject_SetAttrString(exc, "errname", name) == 0)
        PyErr_SetObject(type, exc);
    Py_XDECREF(c);
    Py_XDECREF(name);
    Py_DECREF(exc);
    return NULL;
}

/* Command-line options of the library's messages and the keyword a Python caller uses instead (longest first where
 * one is a prefix of another). `flag` 1: a switch, named with its value; "" keyword: the option only introduces a
 * KEY=VALUE, which is the keyword itself. */
static const struct { const char *option, *keyword; int flag; } keywords[] = {
    {"--mask-scale", "mask_scale", 0}, {"--mask-var", "mask_var", 0}, {"--meas-var", "meas_var", 0},
    {"--truth-var", "truth_var", 0}, {"--mask", "mask", 0}, {"--scale", "scale", 0}, {"--frames", "frames", 0},
    {"--set", "", 0}, {"--force", "overwrite=True", 1}, {"--allow-large", "allow_large=True", 1},
};

/* The option of the table at s (ending there: not a prefix of a longer word), or -1. */
static int option_at(const char *s)
{
    for (size_t i = 0; i < sizeof keywords / sizeof keywords[0]; i++) {
        size_t l = strlen(keywords[i].option);
        if (!strncmp(s, keywords[i].option, l) && !(isalnum((unsigned char)s[l]) || s[l] == '-' || s[l] == '_'))
            return (int)i;
    }
    return -1;
}

/* An option's value as the messages write it: a placeholder (NAME, FILE, N), a number, "auto", a KEY=VALUE. */
static int is_value(const char *s)
{
    size_t key = strspn(s, "abcdefghijklmnopqrstuvwxyz_0123456789");
    return isupper((unsigned char)s[0]) || isdigit((unsigned char)s[0]) || (key > 0 && s[key] == '=') ||
           (!strncmp(s, "auto", 4) && !isalnum((unsigned char)s[4]));
}

void py_error_keywords(const char *msg, char *out, size_t n)
{
    size_t o = 0;
    for (const char *p = msg; *p && o + 1 < n;) {
        int k = p[0] == '-' && (p == msg || !isalnum((unsigned char)p[-1])) ? option_at(p) : -1;
        if (k < 0) {
            out[o++] = *p++;
            continue;
        }
        p += strlen(keywords[k].option);
        const int valued = !keywords[k].flag && p[0] == ' ' && is_value(p + 1);
        o += (size_t)snprintf(out + o, n - o, "%s%s", keywords[k].keyword, valued && keywords[k].keyword[0] ? "=" : "");
        if (valued || (!keywords[k].keyword[0] && p[0] == ' '))
            p++;
        o = o < n ? o : n - 1;
    }
    out[o < n ? o : n - 1] = '\0';
}

PyObject *py_error_raise(int code, const sci_error *err)
{
    if (code == -ENOMEM)
        return PyErr_NoMemory();
    char msg[2 * SCI_ERROR_MSG_MAX];
    py_error_keywords(err && err->msg[0] ? err->msg : sci_strerror(code), msg, sizeof msg);
    return raise_with(is_input_code(code) ? py_input_error_type : py_error_type, code, msg);
}

PyObject *py_error_input(const char *fmt, ...)
{
    sci_error err = {0};
    va_list ap;
    va_start(ap, fmt);
    sci_error_setv(&err, -EINVAL, fmt, ap);
    va_end(ap);
    return raise_with(py_input_error_type, -EINVAL, err.msg);
}
