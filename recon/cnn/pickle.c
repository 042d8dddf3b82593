/* recon/cnn/pickle.c — the restricted pickle machine (see pickle.h).
 *
 * The stack is one array; a MARK records the stack height in `marks` (Python moves the stack aside instead: the
 * effect is the same, objects below the top mark are out of reach of POP, TUPLE, BINPUT ...). Every object made is
 * also recorded in `all`, which is how cnn_pickle_free finds them without walking the (possibly cyclic) graph.
 */
#include "recon/cnn/pickle.h"

#include <errno.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct cnn_pickle {
    cnn_pickle_limits lim;
    cnn_pickle_obj **all; /* every object made, for freeing */
    size_t nall, all_cap;
    size_t entries; /* container slots allocated so far */
    /* per-load state, reused */
    cnn_pickle_obj **stack;
    size_t sp, stack_cap;
    size_t *marks;
    size_t nmarks, marks_cap;
    cnn_pickle_obj **memo;
    size_t memo_cap, memo_count;
};

/* One load in progress. */
typedef struct loader {
    cnn_pickle *p;
    const unsigned char *buf;
    size_t len, pos;
    size_t op_off; /* offset of the opcode being run */
    unsigned char op;
    sci_error *err;
} loader;

void cnn_pickle_limits_default(cnn_pickle_limits *lim)
{
    *lim = (cnn_pickle_limits){.stack = 1u << 16,
                               .marks = 1u << 10,
                               .memo = 1u << 17,
                               .objects = 1u << 20,
                               .entries = 1u << 22,
                               .str_bytes = 1u << 20};
}

int cnn_pickle_new(const cnn_pickle_limits *lim, cnn_pickle **out)
{
    *out = NULL;
    cnn_pickle *p = calloc(1, sizeof *p);
    if (!p)
        return -ENOMEM;
    if (lim)
        p->lim = *lim;
    else
        cnn_pickle_limits_default(&p->lim);
    *out = p;
    return 0;
}

void cnn_pickle_free(cnn_pickle *p)
{
    if (!p)
        return;
    for (size_t k = 0; k < p->nall; k++) {
        free(p->all[k]->s);
        free(p->all[k]->items);
        free(p->all[k]);
    }
    free(p->all);
    free(p->stack);
    free(p->marks);
    free(p->memo);
    free(p);
}

const char *cnn_pickle_kind_name(cnn_pickle_kind k)
{
    switch (k) {
    case CNN_PICKLE_NONE: return "None";
    case CNN_PICKLE_BOOL: return "bool";
    case CNN_PICKLE_INT: return "int";
    case CNN_PICKLE_BIGINT: return "big int";
    case CNN_PICKLE_FLOAT: return "float";
    case CNN_PICKLE_STR: return "str";
    case CNN_PICKLE_BYTES: return "bytes";
    case CNN_PICKLE_TUPLE: return "tuple";
    case CNN_PICKLE_LIST: return "list";
    case CNN_PICKLE_DICT: return "dict";
    case CNN_PICKLE_GLOBAL: return "global";
    case CNN_PICKLE_CALL: return "call";
    case CNN_PICKLE_PERSID: return "persistent id";
    }
    return "?";
}

int cnn_pickle_is_global(const cnn_pickle_obj *o, const char *module, const char *name)
{
    return o && o->kind == CNN_PICKLE_GLOBAL && strcmp(o->s, module) == 0 && strcmp(o->name, name) == 0;
}

int cnn_pickle_is_str(const cnn_pickle_obj *o, const char *s)
{
    return o && o->kind == CNN_PICKLE_STR && o->len == strlen(s) && memcmp(o->s, s, o->len) == 0;
}

const cnn_pickle_obj *cnn_pickle_dict_get(const cnn_pickle_obj *d, const char *key)
{
    if (!d || (d->kind != CNN_PICKLE_DICT && d->kind != CNN_PICKLE_CALL))
        return NULL;
    const cnn_pickle_obj *v = NULL;
    for (size_t k = 0; k + 1 < d->n; k += 2)
        if (cnn_pickle_is_str(d->items[k], key))
            v = d->items[k + 1];
    return v;
}

/* --- the loader's helpers: each failure fills err and returns SCI_EFORMAT or -ENOMEM --- */

static int fail(loader *ld, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int fail(loader *ld, const char *fmt, ...)
{
    char what[SCI_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return sci_error_set(ld->err, SCI_EFORMAT, "offset %zu: opcode 0x%02x: %s", ld->op_off, ld->op, what);
}

static int nomem(loader *ld) { return sci_error_set(ld->err, -ENOMEM, "offset %zu: out of memory", ld->op_off); }

/* The next n argument bytes of the current opcode, or NULL (err filled) if the buffer ends first. */
static const unsigned char *take(loader *ld, size_t n, int *rc)
{
    if (ld->len - ld->pos < n) {
        *rc = fail(ld, "truncated: needs %zu bytes, %zu left", n, ld->len - ld->pos);
        return NULL;
    }
    const unsigned char *q = ld->buf + ld->pos;
    ld->pos += n;
    return q;
}

static uint32_t le32(const unsigned char *q)
{
    return (uint32_t)q[0] | (uint32_t)q[1] << 8 | (uint32_t)q[2] << 16 | (uint32_t)q[3] << 24;
}

static int obj_new(loader *ld, cnn_pickle_kind kind, cnn_pickle_obj **out)
{
    cnn_pickle *p = ld->p;
    if (p->nall >= p->lim.objects)
        return fail(ld, "more than %zu objects (limit)", p->lim.objects);
    if (p->nall == p->all_cap) {
        size_t cap = p->all_cap ? p->all_cap * 2 : 256;
        cnn_pickle_obj **a = realloc(p->all, cap * sizeof *a);
        if (!a)
            return nomem(ld);
        p->all = a;
        p->all_cap = cap;
    }
    cnn_pickle_obj *o = calloc(1, sizeof *o);
    if (!o)
        return nomem(ld);
    o->kind = kind;
    o->offset = ld->op_off;
    p->all[p->nall++] = o;
    *out = o;
    return 0;
}

/* Make room for `more` entries in container o, counting them against the entries limit. */
static int items_reserve(loader *ld, cnn_pickle_obj *o, size_t more)
{
    cnn_pickle *p = ld->p;
    if (more > p->lim.entries || o->n > p->lim.entries - more)
        return fail(ld, "more than %zu container entries (limit)", p->lim.entries);
    if (o->n + more > o->cap) {
        size_t cap = o->cap ? o->cap : 4;
        while (cap < o->n + more)
            cap *= 2;
        /* what is allocated counts, doubling included: p->entries never passes the limit */
        if (cap - o->cap > p->lim.entries - p->entries)
            return fail(ld, "more than %zu container entries (limit)", p->lim.entries);
        cnn_pickle_obj **a = realloc(o->items, cap * sizeof *a);
        if (!a)
            return nomem(ld);
        p->entries += cap - o->cap;
        o->items = a;
        o->cap = cap;
    }
    return 0;
}

/* Height of the stack's floor: objects below it belong to an outer MARK. */
static size_t floor_of(const cnn_pickle *p) { return p->nmarks ? p->marks[p->nmarks - 1] : 0; }

static int push(loader *ld, cnn_pickle_obj *o)
{
    cnn_pickle *p = ld->p;
    if (p->sp >= p->lim.stack)
        return fail(ld, "stack deeper than %zu (limit)", p->lim.stack);
    if (p->sp == p->stack_cap) {
        size_t cap = p->stack_cap ? p->stack_cap * 2 : 64;
        cnn_pickle_obj **a = realloc(p->stack, cap * sizeof *a);
        if (!a)
            return nomem(ld);
        p->stack = a;
        p->stack_cap = cap;
    }
    p->stack[p->sp++] = o;
    return 0;
}

static int pop(loader *ld, cnn_pickle_obj **out)
{
    cnn_pickle *p = ld->p;
    if (p->sp <= floor_of(p))
        return fail(ld, "stack underflow");
    *out = p->stack[--p->sp];
    return 0;
}

static int top(loader *ld, cnn_pickle_obj **out)
{
    cnn_pickle *p = ld->p;
    if (p->sp <= floor_of(p))
        return fail(ld, "stack underflow");
    *out = p->stack[p->sp - 1];
    return 0;
}

/* Close the top MARK: *first is the stack index of the first object above it, *count how many there are. The
 * objects stay in place (the caller copies them, then sets p->sp = *first). */
static int pop_mark(loader *ld, size_t *first, size_t *count)
{
    cnn_pickle *p = ld->p;
    if (!p->nmarks)
        return fail(ld, "no MARK to close");
    *first = p->marks[--p->nmarks];
    *count = p->sp - *first;
    return 0;
}

static int push_new(loader *ld, cnn_pickle_kind kind, cnn_pickle_obj **out)
{
    int rc = obj_new(ld, kind, out);
    return rc < 0 ? rc : push(ld, *out);
}

static int push_int(loader *ld, long long v, cnn_pickle_kind kind)
{
    cnn_pickle_obj *o = NULL;
    int rc = push_new(ld, kind, &o);
    if (rc == 0)
        o->i = v;
    return rc;
}

/* A string or bytes object of n bytes (n already read from the opcode's argument). */
static int push_bytes(loader *ld, size_t n, cnn_pickle_kind kind)
{
    int rc = 0;
    if (n > ld->p->lim.str_bytes)
        return fail(ld, "string of %zu bytes (limit %zu)", n, ld->p->lim.str_bytes);
    const unsigned char *q = take(ld, n, &rc);
    if (!q)
        return rc;
    cnn_pickle_obj *o = NULL;
    if ((rc = push_new(ld, kind, &o)) < 0)
        return rc;
    if (!(o->s = malloc(n + 1)))
        return nomem(ld);
    memcpy(o->s, q, n);
    o->s[n] = 0;
    o->len = n;
    return 0;
}

/* The objects above the top MARK into a new container of `kind` (TUPLE, LIST, DICT). */
static int push_from_mark(loader *ld, cnn_pickle_kind kind)
{
    cnn_pickle *p = ld->p;
    size_t first = 0, count = 0;
    int rc = pop_mark(ld, &first, &count);
    if (rc < 0)
        return rc;
    if (kind == CNN_PICKLE_DICT && count % 2)
        return fail(ld, "odd number of objects (%zu) for a dict", count);
    cnn_pickle_obj *o = NULL;
    if ((rc = obj_new(ld, kind, &o)) < 0 || (rc = items_reserve(ld, o, count)) < 0)
        return rc;
    if (count)
        memcpy(o->items, p->stack + first, count * sizeof *o->items);
    o->n = count;
    p->sp = first;
    return push(ld, o);
}

/* n objects from the top of the stack into a new tuple (TUPLE1..3). */
static int push_tuple_n(loader *ld, size_t n)
{
    cnn_pickle *p = ld->p;
    if (p->sp - floor_of(p) < n)
        return fail(ld, "stack underflow");
    cnn_pickle_obj *o = NULL;
    int rc;
    if ((rc = obj_new(ld, CNN_PICKLE_TUPLE, &o)) < 0 || (rc = items_reserve(ld, o, n)) < 0)
        return rc;
    memcpy(o->items, p->stack + p->sp - n, n * sizeof *o->items);
    o->n = n;
    p->sp -= n;
    return push(ld, o);
}

/* APPENDS and SETITEMS: the objects above the top MARK go into the object just below it. */
static int extend_from_mark(loader *ld, int pairs)
{
    cnn_pickle *p = ld->p;
    size_t first = 0, count = 0;
    int rc = pop_mark(ld, &first, &count);
    if (rc < 0)
        return rc;
    if (first <= floor_of(p))
        return fail(ld, "no container below the MARK");
    cnn_pickle_obj *c = p->stack[first - 1];
    if (pairs) {
        if (c->kind != CNN_PICKLE_DICT && c->kind != CNN_PICKLE_CALL)
            return fail(ld, "SETITEMS on a %s", cnn_pickle_kind_name(c->kind));
        if (count % 2)
            return fail(ld, "odd number of objects (%zu) for SETITEMS", count);
    } else if (c->kind != CNN_PICKLE_LIST) {
        return fail(ld, "APPENDS on a %s", cnn_pickle_kind_name(c->kind));
    }
    if ((rc = items_reserve(ld, c, count)) < 0)
        return rc;
    if (count)
        memcpy(c->items + c->n, p->stack + first, count * sizeof *c->items);
    c->n += count;
    p->sp = first;
    return 0;
}

static int memo_put(loader *ld, size_t idx)
{
    cnn_pickle *p = ld->p;
    cnn_pickle_obj *o = NULL;
    int rc = top(ld, &o);
    if (rc < 0)
        return rc;
    if (idx >= p->lim.memo)
        return fail(ld, "memo index %zu (limit %zu)", idx, p->lim.memo);
    if (idx >= p->memo_cap) {
        size_t cap = p->memo_cap ? p->memo_cap : 256;
        while (cap <= idx)
            cap *= 2;
        if (cap > p->lim.memo)
            cap = p->lim.memo;
        cnn_pickle_obj **a = realloc(p->memo, cap * sizeof *a);
        if (!a)
            return nomem(ld);
        memset(a + p->memo_cap, 0, (cap - p->memo_cap) * sizeof *a);
        p->memo = a;
        p->memo_cap = cap;
    }
    if (!p->memo[idx])
        p->memo_count++;
    p->memo[idx] = o;
    return 0;
}

static int memo_get(loader *ld, size_t idx)
{
    cnn_pickle *p = ld->p;
    if (idx >= p->memo_cap || !p->memo[idx])
        return fail(ld, "memo index %zu was never set", idx);
    return push(ld, p->memo[idx]);
}

/* GLOBAL's argument: "module\nname\n". */
static int op_global(loader *ld)
{
    size_t lim = ld->p->lim.str_bytes, at[2], n[2];
    for (int k = 0; k < 2; k++) {
        at[k] = ld->pos;
        const unsigned char *nl = memchr(ld->buf + ld->pos, '\n', ld->len - ld->pos);
        if (!nl)
            return fail(ld, "truncated: GLOBAL without its newline");
        n[k] = (size_t)(nl - (ld->buf + ld->pos));
        if (n[k] > lim || n[k] == 0 || memchr(ld->buf + at[k], 0, n[k]))
            return fail(ld, "bad GLOBAL name (%zu bytes)", n[k]);
        ld->pos += n[k] + 1;
    }
    cnn_pickle_obj *o = NULL;
    int rc = push_new(ld, CNN_PICKLE_GLOBAL, &o);
    if (rc < 0)
        return rc;
    if (!(o->s = malloc(n[0] + n[1] + 2)))
        return nomem(ld);
    memcpy(o->s, ld->buf + at[0], n[0]);
    o->s[n[0]] = 0;
    memcpy(o->s + n[0] + 1, ld->buf + at[1], n[1]);
    o->s[n[0] + 1 + n[1]] = 0;
    o->name = o->s + n[0] + 1;
    o->len = n[0];
    return 0;
}

/* STACK_GLOBAL: module and name are two strings on the stack. */
static int op_stack_global(loader *ld)
{
    cnn_pickle_obj *m = NULL, *nm = NULL, *o = NULL;
    int rc;
    if ((rc = pop(ld, &nm)) < 0 || (rc = pop(ld, &m)) < 0)
        return rc;
    if (m->kind != CNN_PICKLE_STR || nm->kind != CNN_PICKLE_STR || !m->len || !nm->len ||
        strlen(m->s) != m->len || strlen(nm->s) != nm->len)
        return fail(ld, "STACK_GLOBAL needs two non-empty strings");
    if ((rc = push_new(ld, CNN_PICKLE_GLOBAL, &o)) < 0)
        return rc;
    if (!(o->s = malloc(m->len + nm->len + 2)))
        return nomem(ld);
    memcpy(o->s, m->s, m->len + 1);
    memcpy(o->s + m->len + 1, nm->s, nm->len + 1);
    o->name = o->s + m->len + 1;
    o->len = m->len;
    return 0;
}

/* REDUCE (newobj 0) and NEWOBJ (newobj 1): a call node; nothing is called. */
static int op_call(loader *ld, int newobj)
{
    cnn_pickle_obj *fn = NULL, *args = NULL, *o = NULL;
    int rc;
    if ((rc = pop(ld, &args)) < 0 || (rc = pop(ld, &fn)) < 0)
        return rc;
    if (fn->kind != CNN_PICKLE_GLOBAL)
        return fail(ld, "calls a %s, not a global", cnn_pickle_kind_name(fn->kind));
    if (args->kind != CNN_PICKLE_TUPLE)
        return fail(ld, "arguments are a %s, not a tuple", cnn_pickle_kind_name(args->kind));
    if ((rc = push_new(ld, CNN_PICKLE_CALL, &o)) < 0)
        return rc;
    o->fn = fn;
    o->args = args;
    o->newobj = newobj;
    return 0;
}

/* LONG1: n little-endian two's-complement bytes. */
static int op_long1(loader *ld)
{
    int rc = 0;
    const unsigned char *q = take(ld, 1, &rc);
    if (!q)
        return rc;
    size_t n = q[0];
    if (n > 8)
        return push_bytes(ld, n, CNN_PICKLE_BIGINT); /* kept as its bytes (the magic number is 10 of them) */
    if (!(q = take(ld, n, &rc)))
        return rc;
    uint64_t u = 0;
    for (size_t k = 0; k < n; k++)
        u |= (uint64_t)q[k] << (8 * k);
    if (n && n < 8 && (q[n - 1] & 0x80))
        u |= ~(uint64_t)0 << (8 * n); /* sign extension */
    long long v;
    memcpy(&v, &u, sizeof v);
    return push_int(ld, v, CNN_PICKLE_INT);
}

static int op_binfloat(loader *ld)
{
    int rc = 0;
    const unsigned char *q = take(ld, 8, &rc);
    if (!q)
        return rc;
    uint64_t u = 0;
    for (int k = 0; k < 8; k++)
        u = u << 8 | q[k]; /* big-endian */
    double d;
    memcpy(&d, &u, sizeof d);
    cnn_pickle_obj *o = NULL;
    if ((rc = push_new(ld, CNN_PICKLE_FLOAT, &o)) == 0)
        o->f = d;
    return rc;
}

/* Lengths: 1 byte (SHORT_*), 4 bytes little-endian (BINUNICODE, BINBYTES unsigned; BINSTRING signed). */
static int op_sized(loader *ld, size_t width, int is_signed, cnn_pickle_kind kind)
{
    int rc = 0;
    const unsigned char *q = take(ld, width, &rc);
    if (!q)
        return rc;
    uint32_t n = width == 1 ? q[0] : le32(q);
    if (is_signed && n > INT32_MAX)
        return fail(ld, "negative string length");
    return push_bytes(ld, n, kind);
}

/* An index argument of 1 or 4 bytes. */
static int arg_index(loader *ld, size_t width, size_t *idx)
{
    int rc = 0;
    const unsigned char *q = take(ld, width, &rc);
    if (!q)
        return rc;
    *idx = width == 1 ? q[0] : le32(q);
    return 0;
}

static int op_build(loader *ld)
{
    cnn_pickle_obj *state = NULL, *o = NULL;
    int rc;
    if ((rc = pop(ld, &state)) < 0 || (rc = top(ld, &o)) < 0)
        return rc;
    if (o->kind != CNN_PICKLE_CALL)
        return fail(ld, "BUILD on a %s", cnn_pickle_kind_name(o->kind));
    o->state = state;
    return 0;
}

static int op_setitem(loader *ld)
{
    cnn_pickle_obj *k = NULL, *v = NULL, *d = NULL;
    int rc;
    if ((rc = pop(ld, &v)) < 0 || (rc = pop(ld, &k)) < 0 || (rc = top(ld, &d)) < 0)
        return rc;
    if (d->kind != CNN_PICKLE_DICT && d->kind != CNN_PICKLE_CALL)
        return fail(ld, "SETITEM on a %s", cnn_pickle_kind_name(d->kind));
    if ((rc = items_reserve(ld, d, 2)) < 0)
        return rc;
    d->items[d->n++] = k;
    d->items[d->n++] = v;
    return 0;
}

static int op_append(loader *ld)
{
    cnn_pickle_obj *v = NULL, *l = NULL;
    int rc;
    if ((rc = pop(ld, &v)) < 0 || (rc = top(ld, &l)) < 0)
        return rc;
    if (l->kind != CNN_PICKLE_LIST)
        return fail(ld, "APPEND on a %s", cnn_pickle_kind_name(l->kind));
    if ((rc = items_reserve(ld, l, 1)) < 0)
        return rc;
    l->items[l->n++] = v;
    return 0;
}

/* --- opcodes with no helper of their own above --------------------------------------------------------------- */

static int op_proto(loader *ld)
{
    int rc = 0;
    const unsigned char *q = take(ld, 1, &rc);
    if (!q)
        return rc;
    if (q[0] > 5)
        return fail(ld, "pickle protocol %u", q[0]);
    return 0;
}

/* FRAME: a length hint, the opcodes follow inline */
static int op_frame(loader *ld)
{
    int rc = 0;
    if (!take(ld, 8, &rc))
        return rc;
    return 0;
}

static int op_stop(loader *ld, const cnn_pickle_obj **result)
{
    cnn_pickle *p = ld->p;
    if (p->nmarks)
        return fail(ld, "STOP with %zu MARK(s) open", p->nmarks);
    if (p->sp != 1)
        return fail(ld, "STOP with %zu objects on the stack, not 1", p->sp);
    *result = p->stack[0];
    return 1;
}

static int op_mark(loader *ld)
{
    cnn_pickle *p = ld->p;
    if (p->nmarks >= p->lim.marks)
        return fail(ld, "more than %zu open MARKs (limit)", p->lim.marks);
    if (p->nmarks == p->marks_cap) {
        size_t cap = p->marks_cap ? p->marks_cap * 2 : 16;
        size_t *a = realloc(p->marks, cap * sizeof *a);
        if (!a)
            return nomem(ld);
        p->marks = a;
        p->marks_cap = cap;
    }
    p->marks[p->nmarks++] = p->sp;
    return 0;
}

/* POP: an object, or the MARK itself when nothing is above it (as Python does) */
static int op_pop(loader *ld)
{
    cnn_pickle *p = ld->p;
    if (p->sp > floor_of(p)) {
        p->sp--;
        return 0;
    }
    if (!p->nmarks)
        return fail(ld, "stack underflow");
    p->nmarks--;
    return 0;
}

static int op_pop_mark(loader *ld)
{
    size_t first = 0, count = 0;
    int rc;
    if ((rc = pop_mark(ld, &first, &count)) < 0)
        return rc;
    ld->p->sp = first;
    return 0;
}

static int op_dup(loader *ld)
{
    cnn_pickle_obj *o = NULL;
    int rc;
    if ((rc = top(ld, &o)) < 0)
        return rc;
    return push(ld, o);
}

/* BININT (4 bytes, signed), BININT1 (1), BININT2 (2, unsigned): little-endian. */
static int op_binint(loader *ld, size_t width)
{
    int rc = 0;
    const unsigned char *q = take(ld, width, &rc);
    if (!q)
        return rc;
    if (width == 4)
        return push_int(ld, (int32_t)le32(q), CNN_PICKLE_INT);
    if (width == 1)
        return push_int(ld, q[0], CNN_PICKLE_INT);
    return push_int(ld, q[0] | q[1] << 8, CNN_PICKLE_INT);
}

static int op_binpersid(loader *ld)
{
    cnn_pickle_obj *pid = NULL, *o = NULL;
    int rc;
    if ((rc = pop(ld, &pid)) < 0 || (rc = push_new(ld, CNN_PICKLE_PERSID, &o)) < 0)
        return rc;
    o->args = pid;
    return 0;
}

/* BINPUT, LONG_BINPUT: the memo index in 1 or 4 bytes. */
static int op_put(loader *ld, size_t width)
{
    size_t idx = 0;
    int rc;
    if ((rc = arg_index(ld, width, &idx)) < 0)
        return rc;
    return memo_put(ld, idx);
}

/* BINGET, LONG_BINGET: the memo index in 1 or 4 bytes. */
static int op_get(loader *ld, size_t width)
{
    size_t idx = 0;
    int rc;
    if ((rc = arg_index(ld, width, &idx)) < 0)
        return rc;
    return memo_get(ld, idx);
}

static int op_unsupported(const loader *ld)
{
    if (ld->op >= 0x20 && ld->op < 0x7f)
        return sci_error_set(ld->err, SCI_EFORMAT, "offset %zu: unsupported pickle opcode 0x%02x ('%c')", ld->op_off,
                             ld->op, ld->op);
    return sci_error_set(ld->err, SCI_EFORMAT, "offset %zu: unsupported pickle opcode 0x%02x", ld->op_off, ld->op);
}

/* One opcode at ld->pos. Returns 1 at STOP, 0 to go on, negative on error. */
static int step(loader *ld, const cnn_pickle_obj **result)
{
    cnn_pickle_obj *o = NULL;
    ld->op_off = ld->pos;
    ld->op = ld->buf[ld->pos++];
    switch (ld->op) {
    case 0x80: return op_proto(ld);                          /* PROTO */
    case 0x95: return op_frame(ld);                          /* FRAME */
    case '.': return op_stop(ld, result);                    /* STOP */
    case '(': return op_mark(ld);                            /* MARK */
    case '0': return op_pop(ld);                             /* POP */
    case '1': return op_pop_mark(ld);                        /* POP_MARK */
    case '2': return op_dup(ld);                             /* DUP */
    case 'N': return push_new(ld, CNN_PICKLE_NONE, &o);
    case 0x88: return push_int(ld, 1, CNN_PICKLE_BOOL);
    case 0x89: return push_int(ld, 0, CNN_PICKLE_BOOL);
    case 'J': return op_binint(ld, 4);                       /* BININT */
    case 'K': return op_binint(ld, 1);                       /* BININT1 */
    case 'M': return op_binint(ld, 2);                       /* BININT2 */
    case 0x8a: return op_long1(ld);
    case 'G': return op_binfloat(ld);
    case 'X': return op_sized(ld, 4, 0, CNN_PICKLE_STR);     /* BINUNICODE */
    case 0x8c: return op_sized(ld, 1, 0, CNN_PICKLE_STR);    /* SHORT_BINUNICODE */
    case 'T': return op_sized(ld, 4, 1, CNN_PICKLE_STR);     /* BINSTRING */
    case 'U': return op_sized(ld, 1, 0, CNN_PICKLE_STR);     /* SHORT_BINSTRING */
    case 'B': return op_sized(ld, 4, 0, CNN_PICKLE_BYTES);   /* BINBYTES */
    case 'C': return op_sized(ld, 1, 0, CNN_PICKLE_BYTES);   /* SHORT_BINBYTES */
    case ')': return push_new(ld, CNN_PICKLE_TUPLE, &o);     /* EMPTY_TUPLE */
    case 't': return push_from_mark(ld, CNN_PICKLE_TUPLE);   /* TUPLE */
    case 0x85: return push_tuple_n(ld, 1);
    case 0x86: return push_tuple_n(ld, 2);
    case 0x87: return push_tuple_n(ld, 3);
    case ']': return push_new(ld, CNN_PICKLE_LIST, &o);      /* EMPTY_LIST */
    case 'a': return op_append(ld);
    case 'e': return extend_from_mark(ld, 0);                /* APPENDS */
    case 'l': return push_from_mark(ld, CNN_PICKLE_LIST);    /* LIST */
    case '}': return push_new(ld, CNN_PICKLE_DICT, &o);      /* EMPTY_DICT */
    case 'd': return push_from_mark(ld, CNN_PICKLE_DICT);    /* DICT */
    case 's': return op_setitem(ld);
    case 'u': return extend_from_mark(ld, 1);                /* SETITEMS */
    case 'c': return op_global(ld);
    case 0x93: return op_stack_global(ld);
    case 'R': return op_call(ld, 0);                         /* REDUCE */
    case 0x81: return op_call(ld, 1);                        /* NEWOBJ */
    case 'b': return op_build(ld);
    case 'Q': return op_binpersid(ld);                       /* BINPERSID */
    case 'q': return op_put(ld, 1);                          /* BINPUT */
    case 'r': return op_put(ld, 4);                          /* LONG_BINPUT */
    case 0x94: return memo_put(ld, ld->p->memo_count);       /* MEMOIZE */
    case 'h': return op_get(ld, 1);                          /* BINGET */
    case 'j': return op_get(ld, 4);                          /* LONG_BINGET */
    default: return op_unsupported(ld);
    }
}

int cnn_pickle_load(cnn_pickle *p, const unsigned char *buf, size_t len, size_t *pos, const cnn_pickle_obj **out,
                    sci_error *err)
{
    *out = NULL;
    if (*pos > len)
        return sci_error_set(err, SCI_EFORMAT, "offset %zu: past the end (%zu bytes)", *pos, len);
    loader ld = {.p = p, .buf = buf, .len = len, .pos = *pos, .op_off = *pos, .err = err};
    p->sp = 0;
    p->nmarks = 0;
    p->memo_count = 0;
    if (p->memo_cap)
        memset(p->memo, 0, p->memo_cap * sizeof *p->memo);
    const cnn_pickle_obj *result = NULL;
    for (;;) {
        if (ld.pos >= len)
            return sci_error_set(err, SCI_EFORMAT, "offset %zu: truncated: the pickle ends without STOP", len);
        int rc = step(&ld, &result);
        if (rc < 0)
            return rc;
        if (rc == 1)
            break;
    }
    *out = result;
    *pos = ld.pos;
    return 0;
}
