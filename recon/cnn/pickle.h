/* recon/cnn/pickle.h — a restricted, bounds-checked Python pickle reader, enough for torch.save's legacy format.
 *
 * It runs the pickle machine over untrusted bytes and returns the object graph it describes, calling nothing:
 * GLOBAL yields a name (module, name), REDUCE and NEWOBJ yield a "call" node holding the callable and its
 * arguments, BINPERSID a node holding the persistent id. Interpreting the graph (this call rebuilds a tensor, that
 * one makes an OrderedDict) is the caller's business (recon/cnn/weights.c).
 *
 *     cnn_pickle *pk;  cnn_pickle_new(NULL, &pk);
 *     size_t pos = 0;  const cnn_pickle_obj *o;
 *     while (...) if (cnn_pickle_load(pk, buf, len, &pos, &o, &err) < 0) ...;   // one pickle per call
 *     cnn_pickle_free(pk);                                                        // frees every object
 *
 * Opcodes (protocol 2 and the few of 4 that are cheap): PROTO STOP MARK POP POP_MARK DUP NONE NEWTRUE NEWFALSE
 * BININT BININT1 BININT2 LONG1 BINFLOAT BINUNICODE SHORT_BINUNICODE BINSTRING SHORT_BINSTRING BINBYTES
 * SHORT_BINBYTES EMPTY_TUPLE TUPLE TUPLE1 TUPLE2 TUPLE3 EMPTY_LIST APPEND APPENDS LIST EMPTY_DICT DICT SETITEM
 * SETITEMS GLOBAL STACK_GLOBAL REDUCE BUILD NEWOBJ BINPERSID BINPUT LONG_BINPUT BINGET LONG_BINGET MEMOIZE FRAME.
 * Any other opcode (the text protocol 0, INST/OBJ, EXT*, sets, LONG4, PERSID ...) is refused naming its byte and
 * offset.
 *
 * What must stay true (the input is untrusted): every read is checked against the bytes left; every declared
 * length is compared with the bytes left before anything is allocated for it; the stack, the marks, the memo
 * index, the number of objects, container entries and string length have hard limits (cnn_pickle_limits); there
 * is no recursion anywhere (freeing walks a flat list). The graph may share nodes and may contain cycles (a list
 * appended to itself through the memo): walk it with a fixed schema or a depth bound, never blindly.
 * Memory: about 100 bytes per object plus 8 per container entry plus the strings, so O(input bytes).
 *
 * Errors: SCI_EFORMAT with "offset N: ..." for anything malformed, over a limit or truncated (truncation says
 * "truncated"); -ENOMEM. Not thread-safe per cnn_pickle; separate cnn_pickle objects are independent.
 */
#ifndef SCICAP_RECON_CNN_PICKLE_H
#define SCICAP_RECON_CNN_PICKLE_H

#include <stddef.h>

#include "base/error.h"

typedef enum cnn_pickle_kind {
    CNN_PICKLE_NONE,
    CNN_PICKLE_BOOL,   /* i: 0 or 1 */
    CNN_PICKLE_INT,    /* i: an integer that fits 64 bits */
    CNN_PICKLE_BIGINT, /* s, len: LONG1's little-endian two's-complement bytes, more than 8 of them */
    CNN_PICKLE_FLOAT,  /* f */
    CNN_PICKLE_STR,    /* s, len: the bytes of a str (UTF-8, not validated), NUL-terminated; may hold NULs */
    CNN_PICKLE_BYTES,  /* s, len: as STR */
    CNN_PICKLE_TUPLE,  /* items[0..n) */
    CNN_PICKLE_LIST,   /* items[0..n) */
    CNN_PICKLE_DICT,   /* items[0..n): n/2 pairs key, value in insertion order (a repeated key is kept twice) */
    CNN_PICKLE_GLOBAL, /* s: module, name: attribute ("collections", "OrderedDict") */
    CNN_PICKLE_CALL,   /* fn(*args) by REDUCE (newobj 0) or fn.__new__(fn, *args) by NEWOBJ (newobj 1); fn is a
                        * GLOBAL and args a TUPLE; state: what BUILD gave it (or NULL); items: pairs set on it by
                        * SETITEM(S), as in a DICT (an OrderedDict gets its entries this way) */
    CNN_PICKLE_PERSID, /* args: the persistent id BINPERSID popped */
} cnn_pickle_kind;

typedef struct cnn_pickle_obj cnn_pickle_obj;
struct cnn_pickle_obj {
    cnn_pickle_kind kind;
    size_t offset; /* of the opcode that made it, for messages */
    long long i;
    double f;
    char *s;
    size_t len;
    const char *name;
    cnn_pickle_obj **items;
    size_t n, cap;
    cnn_pickle_obj *fn, *args, *state;
    int newobj;
};

typedef struct cnn_pickle_limits {
    size_t stack;     /* objects on the stack at once (over all marks) */
    size_t marks;     /* open MARKs */
    size_t memo;      /* memo indices 0 .. memo-1 */
    size_t objects;   /* objects made, over every load of one cnn_pickle */
    size_t entries;   /* container entries (tuple, list and dict slots), over every load */
    size_t str_bytes; /* one string, bytes object or GLOBAL line */
} cnn_pickle_limits;

/* The defaults: stack 1<<16, marks 1<<10, memo 1<<17, objects 1<<20, entries 1<<22, str_bytes 1<<20. A state dict
 * of a few thousand tensors needs a few percent of each. */
void cnn_pickle_limits_default(cnn_pickle_limits *lim);

typedef struct cnn_pickle cnn_pickle;

/* A machine with limits `lim` (copied; NULL: the defaults). 0 or -ENOMEM. */
int cnn_pickle_new(const cnn_pickle_limits *lim, cnn_pickle **out);
/* Frees the machine and every object any load returned. NULL is harmless. */
void cnn_pickle_free(cnn_pickle *p);

/* Run one pickle: from buf[*pos] up to and including its STOP, with a fresh stack and memo (as one
 * pickle.load). On success *out is the object STOP returned (owned by p, valid until cnn_pickle_free) and *pos the
 * offset just past STOP. STOP must find exactly one object on the stack and no open MARK. buf is not kept.
 * Errors as above; *out is NULL and *pos unchanged on error. */
int cnn_pickle_load(cnn_pickle *p, const unsigned char *buf, size_t len, size_t *pos, const cnn_pickle_obj **out,
                    sci_error *err);

/* "str", "tuple", "call" ... for messages. */
const char *cnn_pickle_kind_name(cnn_pickle_kind k);
/* 1 if o is a GLOBAL module.name, else 0 (o may be NULL). */
int cnn_pickle_is_global(const cnn_pickle_obj *o, const char *module, const char *name);
/* 1 if o is a STR equal to `s` (no embedded NUL), else 0. */
int cnn_pickle_is_str(const cnn_pickle_obj *o, const char *s);
/* The value for STR key `key` in a DICT or CALL's pairs (the last one if repeated), or NULL. */
const cnn_pickle_obj *cnn_pickle_dict_get(const cnn_pickle_obj *d, const char *key);

#endif
