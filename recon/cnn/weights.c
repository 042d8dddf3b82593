/* recon/cnn/weights.c — legacy torch.save state dicts (see weights.h).
 *
 * In three passes over what the pickles describe: (1) the state dict's entries become tensor_refs, each checked
 * on its own (rebuild call, persistent id, sizes, strides, bounds within its storage as declared); (2) the refs'
 * storage keys are merged into storages (sorted by key) and the key list and the data records after it are
 * matched against them, lengths checked before anything is allocated; (3) the float storages are decoded into
 * one pool and the tensors made to point into it, each checked finite.
 */
#include "recon/cnn/weights.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/file.h"
#include "recon/cnn/pickle.h"

#define WEIGHTS_MAX_FILE ((size_t)2 << 30)
#define WEIGHTS_MAX_DIMS 4

typedef struct storage_type {
    const char *name;
    int elsize;
    cnn_dtype dtype;
} storage_type;

/* torch.<name>, element size in the data records. */
static const storage_type storage_types[] = {
    {"FloatStorage", 4, CNN_F32},        {"LongStorage", 8, CNN_I64},          {"DoubleStorage", 8, CNN_OTHER},
    {"HalfStorage", 2, CNN_OTHER},       {"BFloat16Storage", 2, CNN_OTHER},    {"IntStorage", 4, CNN_OTHER},
    {"ShortStorage", 2, CNN_OTHER},      {"CharStorage", 1, CNN_OTHER},        {"ByteStorage", 1, CNN_OTHER},
    {"BoolStorage", 1, CNN_OTHER},       {"ComplexFloatStorage", 8, CNN_OTHER}, {"ComplexDoubleStorage", 16, CNN_OTHER},
};

/* One state-dict entry as the pickle describes it. */
typedef struct tensor_ref {
    const char *key;  /* state-dict key as stored */
    const char *skey; /* its storage's (root) key */
    const storage_type *type;
    long long numel;              /* the root storage's, as declared */
    long long base, extent;       /* first element in the root storage; elements reachable from there (view) */
    long long size[WEIGHTS_MAX_DIMS];
    long long count;
    int ndim;
    size_t storage; /* index into parser.st, after merging */
} tensor_ref;

typedef struct storage {
    const char *key;
    const storage_type *type;
    long long numel;
    const tensor_ref *first; /* a tensor using it, for messages */
    int listed;
    size_t data_off; /* first element's offset in the file */
    float *f32;      /* CNN_F32: numel values in the pool */
    size_t *bad;     /* ascending indices of non-finite values */
    size_t nbad;
} storage;

typedef struct parser {
    const char *name;
    const unsigned char *buf;
    size_t len;
    sci_error *err;
    cnn_pickle *pk;
    tensor_ref *refs;
    size_t nrefs;
    storage *st;
    size_t nst;
    float *pool;
} parser;

/* What cnn_weights_free releases: the public struct first, so a cnn_weights * is one of these. */
typedef struct weights_impl {
    cnn_weights pub;
    float *pool;
} weights_impl;

static int bad(parser *ps, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int bad(parser *ps, int code, const char *fmt, ...)
{
    char what[SCI_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    return sci_error_set(ps->err, code, "%s: %s", ps->name, what);
}

/* --- (0) the pickles --- */

static const char *const pickle_names[] = {"magic number", "protocol version", "system info", "state dict",
                                           "storage keys"};

static int load(parser *ps, int which, size_t *pos, const cnn_pickle_obj **o)
{
    int rc = cnn_pickle_load(ps->pk, ps->buf, ps->len, pos, o, ps->err);
    if (rc < 0)
        sci_error_prefix(ps->err, "%s: pickle %d (%s): ", ps->name, which + 1, pickle_names[which]);
    return rc;
}

static int check_header(parser *ps, size_t *pos)
{
    static const unsigned char magic[10] = {0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19};
    if (ps->len == 0)
        return bad(ps, SCI_EFORMAT, "empty file (not a PyTorch state dict)");
    if (ps->len >= 4 && memcmp(ps->buf, "PK\3\4", 4) == 0)
        return bad(ps, SCI_EFORMAT,
                   "a zip-format torch.save file (PyTorch >= 1.6), not the legacy format this reader takes; re-save "
                   "it with torch.save(sd, f, _use_new_zipfile_serialization=False)");
    const cnn_pickle_obj *o;
    int rc;
    if ((rc = load(ps, 0, pos, &o)) < 0)
        return rc;
    if (o->kind != CNN_PICKLE_BIGINT || o->len != sizeof magic || memcmp(o->s, magic, sizeof magic) != 0)
        return bad(ps, SCI_EFORMAT, "bad magic number (not a legacy torch.save file)");
    if ((rc = load(ps, 1, pos, &o)) < 0)
        return rc;
    if (o->kind != CNN_PICKLE_INT || o->i != 1001)
        return bad(ps, SCI_EFORMAT, "protocol version is not 1001");
    if ((rc = load(ps, 2, pos, &o)) < 0)
        return rc;
    if (o->kind != CNN_PICKLE_DICT)
        return bad(ps, SCI_EFORMAT, "system info is a %s, not a dict", cnn_pickle_kind_name(o->kind));
    const cnn_pickle_obj *le = cnn_pickle_dict_get(o, "little_endian");
    if (le && !(le->kind == CNN_PICKLE_BOOL && le->i == 1))
        return bad(ps, SCI_EFORMAT, "written on a big-endian machine (little_endian is not True): not supported");
    return 0;
}

/* --- (1) tensor references --- */

static int is_plain_str(const cnn_pickle_obj *o) { return o && o->kind == CNN_PICKLE_STR && strlen(o->s) == o->len; }

static int is_int(const cnn_pickle_obj *o, long long min) { return o && o->kind == CNN_PICKLE_INT && o->i >= min; }

/* A tuple of at most WEIGHTS_MAX_DIMS non-negative ints (sizes or strides) into v; *n its length. */
static int int_tuple(parser *ps, const char *key, const char *what, const cnn_pickle_obj *o, long long *v, int *n)
{
    if (!o || o->kind != CNN_PICKLE_TUPLE)
        return bad(ps, SCI_EFORMAT, "tensor '%s': %s is not a tuple", key, what);
    if (o->n > WEIGHTS_MAX_DIMS)
        return bad(ps, SCI_EFORMAT, "tensor '%s' has %zu dimensions (at most %d supported)", key, o->n,
                   WEIGHTS_MAX_DIMS);
    for (size_t k = 0; k < o->n; k++) {
        if (!is_int(o->items[k], 0))
            return bad(ps, SCI_EFORMAT, "tensor '%s': %s[%zu] is not an int >= 0", key, what, k);
        v[k] = o->items[k]->i;
    }
    *n = (int)o->n;
    return 0;
}

/* The persistent id ('storage', torch.<T>Storage, key, location, numel, view) into r's storage fields. */
static int parse_storage(parser *ps, const char *key, const cnn_pickle_obj *pid, tensor_ref *r, long long *extent)
{
    const cnn_pickle_obj *const *it = (const cnn_pickle_obj *const *)pid->items;
    if (pid->kind != CNN_PICKLE_TUPLE || pid->n != 6 || !cnn_pickle_is_str(it[0], "storage"))
        return bad(ps, SCI_EFORMAT, "tensor '%s': the persistent id is not ('storage', type, key, location, "
                                    "numel, view)", key);
    const cnn_pickle_obj *t = it[1];
    if (!t || t->kind != CNN_PICKLE_GLOBAL || (strcmp(t->s, "torch") != 0 && strcmp(t->s, "torch.cuda") != 0))
        return bad(ps, SCI_EFORMAT, "tensor '%s': the storage type is not a torch global", key);
    r->type = NULL;
    for (size_t k = 0; k < sizeof storage_types / sizeof storage_types[0]; k++)
        if (strcmp(t->name, storage_types[k].name) == 0)
            r->type = &storage_types[k];
    if (!r->type)
        return bad(ps, SCI_EFORMAT, "tensor '%s': unknown storage type %s.%s", key, t->s, t->name);
    if (!is_plain_str(it[2]) || it[3]->kind != CNN_PICKLE_STR)
        return bad(ps, SCI_EFORMAT, "tensor '%s': the storage key or location is not a string", key);
    if (!is_int(it[4], 0))
        return bad(ps, SCI_EFORMAT, "tensor '%s': the storage size is not an int >= 0", key);
    r->skey = it[2]->s;
    r->numel = it[4]->i;
    r->base = 0;
    *extent = r->numel;
    const cnn_pickle_obj *view = it[5];
    if (view->kind == CNN_PICKLE_NONE)
        return 0;
    /* (view_key, offset, size): the tensor lives in root[offset, offset + size) */
    if (view->kind != CNN_PICKLE_TUPLE || view->n != 3 || !is_int(view->items[1], 0) || !is_int(view->items[2], 0))
        return bad(ps, SCI_EFORMAT, "tensor '%s': the storage view is not (key, offset, size)", key);
    long long off = view->items[1]->i, size = view->items[2]->i;
    if (off > r->numel || size > r->numel - off)
        return bad(ps, SCI_EFORMAT, "tensor '%s': storage view [%lld, %lld + %lld) outside storage '%s' of %lld", key,
                   off, off, size, r->skey, r->numel);
    r->base = off;
    *extent = size;
    return 0;
}

/* Sizes and strides: contiguous (PyTorch's rule, size-1 dimensions' strides are free), count in range. */
static int parse_geometry(parser *ps, const char *key, const cnn_pickle_obj *const *a, tensor_ref *r,
                          long long extent)
{
    long long stride[WEIGHTS_MAX_DIMS];
    int ns = 0, rc;
    if (!is_int(a[1], 0))
        return bad(ps, SCI_EFORMAT, "tensor '%s': the storage offset is not an int >= 0", key);
    if ((rc = int_tuple(ps, key, "size", a[2], r->size, &r->ndim)) < 0 ||
        (rc = int_tuple(ps, key, "stride", a[3], stride, &ns)) < 0)
        return rc;
    if (ns != r->ndim)
        return bad(ps, SCI_EFORMAT, "tensor '%s': %d sizes but %d strides", key, r->ndim, ns);
    long long count = 1;
    for (int d = 0; d < r->ndim; d++) {
        if (r->size[d] && count > LLONG_MAX / r->size[d])
            return bad(ps, SCI_EFORMAT, "tensor '%s': element count overflows", key);
        count *= r->size[d];
    }
    long long expect = 1;
    for (int d = r->ndim - 1; d >= 0 && count; d--) {
        if (r->size[d] != 1 && stride[d] != expect)
            return bad(ps, SCI_EFORMAT, "tensor '%s' is not contiguous (dimension %d: stride %lld, expected %lld)",
                       key, d, stride[d], expect);
        expect *= r->size[d];
    }
    long long off = a[1]->i;
    if (off > extent || count > extent - off)
        return bad(ps, SCI_EFORMAT, "tensor '%s': elements [%lld, %lld + %lld) outside its storage '%s' of %lld",
                   key, off, off, count, r->skey, extent);
    r->base += off;
    r->extent = extent;
    r->count = count;
    return 0;
}

static int parse_tensor(parser *ps, const cnn_pickle_obj *k, const cnn_pickle_obj *v, tensor_ref *r)
{
    if (!is_plain_str(k))
        return bad(ps, SCI_EFORMAT, "a state-dict key is a %s, not a string", cnn_pickle_kind_name(k->kind));
    const char *key = r->key = k->s;
    if (v->kind == CNN_PICKLE_CALL && cnn_pickle_is_global(v->fn, "torch._utils", "_rebuild_parameter") &&
        v->args->n >= 1)
        v = v->args->items[0];
    if (v->kind != CNN_PICKLE_CALL)
        return bad(ps, SCI_EFORMAT, "the value of '%s' is a %s, not a tensor", key, cnn_pickle_kind_name(v->kind));
    int v1 = cnn_pickle_is_global(v->fn, "torch._utils", "_rebuild_tensor");
    int v2 = cnn_pickle_is_global(v->fn, "torch._utils", "_rebuild_tensor_v2");
    if (!v1 && !v2)
        return bad(ps, SCI_EFORMAT, "tensor '%s' is made by %s.%s (not supported)", key, v->fn->s, v->fn->name);
    const cnn_pickle_obj *a = v->args;
    if (v1 ? a->n != 4 : (a->n < 6 || a->n > 7))
        return bad(ps, SCI_EFORMAT, "tensor '%s': %s with %zu arguments", key, v->fn->name, a->n);
    if (a->items[0]->kind != CNN_PICKLE_PERSID)
        return bad(ps, SCI_EFORMAT, "tensor '%s': its storage is a %s, not a persistent id", key,
                   cnn_pickle_kind_name(a->items[0]->kind));
    long long extent = 0;
    int rc = parse_storage(ps, key, a->items[0]->args, r, &extent);
    return rc < 0 ? rc : parse_geometry(ps, key, (const cnn_pickle_obj *const *)a->items, r, extent);
}

static int collect_tensors(parser *ps, const cnn_pickle_obj *sd)
{
    int od = sd->kind == CNN_PICKLE_CALL && cnn_pickle_is_global(sd->fn, "collections", "OrderedDict");
    if (sd->kind != CNN_PICKLE_DICT && !od)
        return bad(ps, SCI_EFORMAT, "the saved object is a %s%s%s, not a state dict (save model.state_dict())",
                   cnn_pickle_kind_name(sd->kind), sd->kind == CNN_PICKLE_CALL ? " of " : "",
                   sd->kind == CNN_PICKLE_CALL ? sd->fn->name : "");
    ps->nrefs = sd->n / 2;
    if (!(ps->refs = calloc(ps->nrefs ? ps->nrefs : 1, sizeof *ps->refs)))
        return bad(ps, -ENOMEM, "out of memory");
    for (size_t k = 0; k < ps->nrefs; k++) {
        int rc = parse_tensor(ps, sd->items[2 * k], sd->items[2 * k + 1], &ps->refs[k]);
        if (rc < 0)
            return rc;
    }
    return 0;
}

/* --- (2) storages, the key list and the data records --- */

static int cmp_ref_skey(const void *a, const void *b)
{
    return strcmp((*(const tensor_ref *const *)a)->skey, (*(const tensor_ref *const *)b)->skey);
}

static int cmp_storage_key(const void *key, const void *s) { return strcmp(key, ((const storage *)s)->key); }

static int merge_storages(parser *ps)
{
    tensor_ref **by = malloc((ps->nrefs ? ps->nrefs : 1) * sizeof *by);
    if (!by || !(ps->st = calloc(ps->nrefs ? ps->nrefs : 1, sizeof *ps->st))) {
        free(by);
        return bad(ps, -ENOMEM, "out of memory");
    }
    for (size_t k = 0; k < ps->nrefs; k++)
        by[k] = &ps->refs[k];
    qsort(by, ps->nrefs, sizeof *by, cmp_ref_skey);
    int rc = 0;
    for (size_t k = 0; k < ps->nrefs && rc == 0; k++) {
        tensor_ref *r = by[k];
        storage *s = ps->nst ? &ps->st[ps->nst - 1] : NULL;
        if (s && strcmp(s->key, r->skey) == 0) {
            if (s->type != r->type || s->numel != r->numel)
                rc = bad(ps, SCI_EFORMAT, "storage '%s' declared as %s of %lld (tensor '%s') and %s of %lld (tensor "
                                          "'%s')", s->key, s->type->name, s->numel, s->first->key, r->type->name,
                         r->numel, r->key);
        } else {
            s = &ps->st[ps->nst++];
            *s = (storage){.key = r->skey, .type = r->type, .numel = r->numel, .first = r};
        }
        r->storage = (size_t)(s - ps->st);
    }
    free(by);
    return rc;
}

static uint64_t le64(const unsigned char *q)
{
    uint64_t u = 0;
    for (int k = 7; k >= 0; k--)
        u = u << 8 | q[k];
    return u;
}

/* Match the key list against the storages, in its order, and check each record's count and length. */
static int read_records(parser *ps, const cnn_pickle_obj *keys, size_t pos, size_t *pool_floats)
{
    if (keys->kind != CNN_PICKLE_LIST)
        return bad(ps, SCI_EFORMAT, "the storage key list is a %s, not a list", cnn_pickle_kind_name(keys->kind));
    *pool_floats = 0;
    for (size_t k = 0; k < keys->n; k++) {
        if (!is_plain_str(keys->items[k]))
            return bad(ps, SCI_EFORMAT, "storage key list entry %zu is not a string", k);
        const char *key = keys->items[k]->s;
        storage *s = bsearch(key, ps->st, ps->nst, sizeof *ps->st, cmp_storage_key);
        if (!s)
            return bad(ps, SCI_EFORMAT, "storage '%s' is in the key list but no tensor uses it", key);
        if (s->listed)
            return bad(ps, SCI_EFORMAT, "storage '%s' is twice in the key list", key);
        s->listed = 1;
        if (ps->len - pos < 8)
            return bad(ps, SCI_EFORMAT, "truncated: storage '%s' needs 8 bytes at offset %zu, file has %zu", key,
                       pos, ps->len);
        uint64_t count = le64(ps->buf + pos);
        pos += 8;
        if (count != (uint64_t)s->numel)
            return bad(ps, SCI_EFORMAT, "storage '%s': the record at offset %zu holds %llu elements, the pickle "
                                        "declared %lld (corrupted)", key, pos - 8, (unsigned long long)count,
                       s->numel);
        /* elsize ≤ 16: numel ≤ LLONG_MAX / 16 keeps the product in range, and no file holds more */
        if (s->numel > LLONG_MAX / 16)
            return bad(ps, SCI_EFORMAT, "truncated: storage '%s' needs %lld × %d bytes at offset %zu, file has %zu",
                       key, s->numel, s->type->elsize, pos, ps->len);
        long long need = s->numel * s->type->elsize;
        if ((unsigned long long)need > ps->len - pos)
            return bad(ps, SCI_EFORMAT, "truncated: storage '%s' needs %lld bytes at offset %zu, file has %zu", key,
                       need, pos, ps->len);
        s->data_off = pos;
        pos += (size_t)need;
        if (s->type->dtype == CNN_F32)
            *pool_floats += (size_t)s->numel;
    }
    if (pos != ps->len)
        return bad(ps, SCI_EFORMAT, "%zu unexpected bytes after the last storage (offset %zu)", ps->len - pos, pos);
    for (size_t k = 0; k < ps->nst; k++)
        if (!ps->st[k].listed)
            return bad(ps, SCI_EFORMAT, "storage '%s' (tensor '%s') is not in the key list: its data is missing",
                       ps->st[k].key, ps->st[k].first->key);
    return 0;
}

/* --- (3) float data --- */

static int decode_floats(parser *ps, storage *s, float *dst)
{
    const unsigned char *q = ps->buf + s->data_off;
    size_t n = (size_t)s->numel, nbad = 0;
    for (size_t i = 0; i < n; i++) {
        uint32_t u = (uint32_t)q[4 * i] | (uint32_t)q[4 * i + 1] << 8 | (uint32_t)q[4 * i + 2] << 16 |
                     (uint32_t)q[4 * i + 3] << 24;
        memcpy(&dst[i], &u, sizeof u);
        nbad += !isfinite(dst[i]);
    }
    s->f32 = dst;
    if (!nbad)
        return 0;
    if (!(s->bad = malloc(nbad * sizeof *s->bad)))
        return bad(ps, -ENOMEM, "out of memory");
    for (size_t i = 0; i < n; i++)
        if (!isfinite(dst[i]))
            s->bad[s->nbad++] = i;
    return 0;
}

/* The first non-finite element of tensor r, or -1. */
static long long first_nonfinite(const storage *s, const tensor_ref *r)
{
    size_t lo = 0, hi = s->nbad, base = (size_t)r->base;
    while (lo < hi) { /* first bad index >= base */
        size_t mid = lo + (hi - lo) / 2;
        if (s->bad[mid] < base)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo < s->nbad && s->bad[lo] < base + (size_t)r->count)
        return (long long)(s->bad[lo] - base);
    return -1;
}

static int cmp_tensor_name(const void *a, const void *b)
{
    return strcmp((*(const cnn_tensor *const *)a)->name, (*(const cnn_tensor *const *)b)->name);
}

static int check_unique(parser *ps, cnn_tensor *t, size_t n)
{
    if (n < 2)
        return 0;
    const cnn_tensor **by = malloc(n * sizeof *by);
    if (!by)
        return bad(ps, -ENOMEM, "out of memory");
    for (size_t k = 0; k < n; k++)
        by[k] = &t[k];
    qsort(by, n, sizeof *by, cmp_tensor_name);
    int rc = 0;
    for (size_t k = 1; k < n && rc == 0; k++)
        if (strcmp(by[k - 1]->name, by[k]->name) == 0)
            rc = bad(ps, SCI_EFORMAT, "two tensors are named '%s' (keys '%s' and '%s')", by[k]->name,
                     ps->refs[by[k - 1] - t].key, ps->refs[by[k] - t].key);
    free(by);
    return rc;
}

static int make_tensor(parser *ps, const tensor_ref *r, cnn_tensor *t)
{
    const char *name = strncmp(r->key, "module.", 7) == 0 ? r->key + 7 : r->key;
    if (!*name || strlen(name) >= sizeof t->name)
        return bad(ps, SCI_EFORMAT, "tensor '%s': name empty or longer than %zu bytes", r->key, sizeof t->name - 1);
    strcpy(t->name, name);
    t->dtype = r->type->dtype;
    t->ndim = r->ndim;
    for (int d = 0; d < r->ndim; d++)
        t->shape[d] = (long)r->size[d];
    t->count = (size_t)r->count;
    if (t->dtype != CNN_F32)
        return 0;
    const storage *s = &ps->st[r->storage];
    t->data = s->f32 + r->base;
    long long i = s->nbad ? first_nonfinite(s, r) : -1;
    if (i >= 0)
        return bad(ps, SCI_ENONFINITE, "tensor '%s' element %lld (of %lld) is %s", r->key, i, r->count,
                   isnan(t->data[i]) ? "NaN" : t->data[i] > 0 ? "+Inf" : "-Inf");
    return 0;
}

static int build(parser *ps, size_t pool_floats, cnn_weights **out)
{
    weights_impl *w = calloc(1, sizeof *w);
    if (!w || !(w->pub.t = calloc(ps->nrefs ? ps->nrefs : 1, sizeof *w->pub.t)) ||
        !(w->pool = malloc((pool_floats ? pool_floats : 1) * sizeof *w->pool))) {
        if (w)
            free(w->pub.t);
        free(w);
        return bad(ps, -ENOMEM, "out of memory (%zu floats)", pool_floats);
    }
    snprintf(w->pub.source, sizeof w->pub.source, "%s", ps->name);
    w->pub.n = (int)ps->nrefs;
    int rc = 0;
    size_t at = 0;
    for (size_t k = 0; k < ps->nst && rc == 0; k++)
        if (ps->st[k].type->dtype == CNN_F32) {
            rc = decode_floats(ps, &ps->st[k], w->pool + at);
            at += (size_t)ps->st[k].numel;
        }
    for (size_t k = 0; k < ps->nrefs && rc == 0; k++)
        rc = make_tensor(ps, &ps->refs[k], &w->pub.t[k]);
    if (rc == 0)
        rc = check_unique(ps, w->pub.t, ps->nrefs);
    if (rc < 0) {
        cnn_weights_free(&w->pub);
        return rc;
    }
    *out = &w->pub;
    return 0;
}

int cnn_weights_parse(const void *buf, size_t len, const char *name, cnn_weights **out, sci_error *err)
{
    *out = NULL;
    parser ps = {.name = name ? name : "(memory)", .buf = buf, .len = len, .err = err};
    const cnn_pickle_obj *sd, *keys;
    size_t pos = 0, pool_floats = 0;
    int rc = cnn_pickle_new(NULL, &ps.pk);
    if (rc < 0) {
        rc = bad(&ps, rc, "out of memory");
        goto out;
    }
    if ((rc = check_header(&ps, &pos)) < 0 || (rc = load(&ps, 3, &pos, &sd)) < 0 ||
        (rc = load(&ps, 4, &pos, &keys)) < 0 || (rc = collect_tensors(&ps, sd)) < 0 ||
        (rc = merge_storages(&ps)) < 0 || (rc = read_records(&ps, keys, pos, &pool_floats)) < 0)
        goto out;
    rc = build(&ps, pool_floats, out);
out:
    for (size_t k = 0; k < ps.nst; k++)
        free(ps.st[k].bad);
    free(ps.st);
    free(ps.refs);
    cnn_pickle_free(ps.pk);
    return rc;
}

int cnn_weights_read(const char *path, cnn_weights **out, sci_error *err)
{
    *out = NULL;
    void *buf;
    size_t len;
    int rc = sci_file_read(path, WEIGHTS_MAX_FILE, &buf, &len, err);
    if (rc < 0)
        return rc;
    rc = cnn_weights_parse(buf, len, path, out, err);
    free(buf);
    return rc;
}

const cnn_tensor *cnn_weights_find(const cnn_weights *w, const char *name)
{
    for (int k = 0; w && k < w->n; k++)
        if (strcmp(w->t[k].name, name) == 0)
            return &w->t[k];
    return NULL;
}

static void shape_str(char *buf, size_t n, int ndim, const long *shape)
{
    size_t at = (size_t)snprintf(buf, n, "[");
    for (int d = 0; d < ndim && at < n; d++)
        at += (size_t)snprintf(buf + at, n - at, "%s%ld", d ? ", " : "", shape[d]);
    if (at < n)
        snprintf(buf + at, n - at, "]");
}

int cnn_weights_expect(const cnn_weights *w, const char *name, int ndim, const long *shape, const cnn_tensor **out,
                       sci_error *err)
{
    if (out)
        *out = NULL;
    const cnn_tensor *t = cnn_weights_find(w, name);
    char want[128], have[128];
    shape_str(want, sizeof want, ndim < 0 ? 0 : ndim > 4 ? 4 : ndim, shape);
    if (!t)
        return sci_error_set(err, -EINVAL, "%s: no tensor '%s' (expected shape %s)", w->source, name, want);
    shape_str(have, sizeof have, t->ndim, t->shape);
    if (t->dtype != CNN_F32)
        return sci_error_set(err, -EINVAL, "%s: tensor '%s' %s is not float32", w->source, name, have);
    int same = t->ndim == ndim;
    for (int d = 0; same && d < ndim; d++)
        same = t->shape[d] == shape[d];
    if (!same)
        return sci_error_set(err, -EINVAL, "%s: tensor '%s' has shape %s, expected %s", w->source, name, have, want);
    if (out)
        *out = t;
    return 0;
}

void cnn_weights_free(cnn_weights *w)
{
    if (!w)
        return;
    weights_impl *impl = (weights_impl *)w;
    free(impl->pool);
    free(w->t);
    free(impl);
}
