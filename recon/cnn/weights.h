/* recon/cnn/weights.h — PyTorch state dicts from legacy torch.save files (pre-1.6, not zip), read without Python.
 *
 *     cnn_weights *w;
 *     if (cnn_weights_read("net_gray.pth", &w, &err) < 0) return err.code;
 *     const cnn_tensor *t;
 *     long shape[4] = {64, 5, 3, 3};
 *     if (cnn_weights_expect(w, "intermediate_dncnn.itermediate_dncnn.0.weight", 4, shape, &t, &err) < 0) ...;
 *     ... t->data[0 .. t->count) ...
 *     cnn_weights_free(w);
 *
 * The file format (torch/serialization.py, _legacy_save): five pickles (protocol 2) back to back — the magic
 * number 0x1950a86a20f9469cfc6c, the protocol version 1001, a sys_info dict (little_endian must not be False), the
 * state dict, the list of storage keys — then, for each key in that list's order, the storage's element count
 * (int64, little-endian) and its elements (little-endian). The state dict is a dict or an OrderedDict (REDUCE of
 * collections.OrderedDict, entries by SETITEMS, maybe a BUILD with `_metadata`, which is ignored) whose values are
 * torch._utils._rebuild_tensor(storage, offset, size, stride) or _rebuild_tensor_v2(storage, offset, size,
 * stride, requires_grad, hooks[, metadata]) (also wrapped in _rebuild_parameter), `storage` being a persistent id
 * ('storage', torch.<Type>Storage, key, location, numel, view) with view None or (view_key, offset, size).
 * The pickles are read by recon/cnn/pickle.h: bounded, nothing is ever called.
 *
 * What is checked (each failure names the file and, where there is one, the tensor or storage key):
 *   - magic, version, byte order; a zip-format file (PyTorch ≥ 1.6's default) is recognised and refused with a hint;
 *   - every storage the state dict uses is in the key list, has its record, and the record's count equals the
 *     numel the pickle declared; a record running past the end is "truncated: storage 'k' needs N bytes at
 *     offset O, file has M"; bytes after the last record are refused;
 *   - each tensor: 0 to 4 dimensions, sizes ≥ 0, contiguous strides (PyTorch's rule: strides of size-1
 *     dimensions are free), offset + count within its storage (or view);
 *   - float32 values: every element of every tensor finite (else "tensor 'name' element i is NaN/Inf");
 *   - keys: unique after the "module." prefix (torch.nn.DataParallel's) is removed, and shorter than 160 bytes.
 * Storage types: Float → CNN_F32 with data; Long → CNN_I64 and Double, Half, BFloat16, Int, Short, Char, Byte,
 * Bool, Complex* → CNN_OTHER, both without data (their bytes are skipped); an unknown storage type is refused
 * (its element size, hence the layout of what follows, is unknown).
 *
 * Error codes: -errno from opening/reading the file (message "path: strerror"), -EFBIG for a file over 2 GiB,
 * SCI_EFORMAT for anything malformed, truncated or refused above, SCI_ENONFINITE for a NaN/Inf, -ENOMEM.
 * Memory: the tensors of a float storage point into one copy of it (views share it: treat data as read-only);
 * about the file's size in all. Reading net_gray.pth (2 MB) takes about a millisecond.
 * Thread-safety: no shared state; a cnn_weights is immutable after reading and may be read by many threads.
 */
#ifndef SCICAP_RECON_CNN_WEIGHTS_H
#define SCICAP_RECON_CNN_WEIGHTS_H

#include <stddef.h>

#include "base/error.h"

typedef enum cnn_dtype { CNN_F32, CNN_I64, CNN_OTHER } cnn_dtype;

typedef struct cnn_tensor {
    char name[160];  /* the state-dict key with a leading "module." removed */
    cnn_dtype dtype; /* storage type; only CNN_F32 tensors carry data */
    int ndim;        /* 0..4 */
    long shape[4];   /* row-major (PyTorch) sizes; entries past ndim are 0 */
    size_t count;    /* elements (1 for ndim 0) */
    float *data;     /* CNN_F32: count floats, owned by the cnn_weights, possibly shared with other tensors
                      * viewing the same storage (do not write); else NULL */
} cnn_tensor;

typedef struct cnn_weights {
    cnn_tensor *t;     /* n tensors, in the state dict's order */
    int n;
    char source[256];  /* the path or name it was read from, for messages */
} cnn_weights;

/* Read a state dict from `path` (legacy .pth). On success *out is new (cnn_weights_free) and 0 returned; on
 * error *out is NULL and err names the file (and tensor). See the overview for what is checked and the codes. */
int cnn_weights_read(const char *path, cnn_weights **out, sci_error *err);
/* The same from memory (the fuzz target's entry): `buf` is only read during the call; `name` is used in
 * messages and copied into source. */
int cnn_weights_parse(const void *buf, size_t len, const char *name, cnn_weights **out, sci_error *err);
/* The tensor called `name` (without "module."), or NULL. Borrowed: lives as long as w. O(n). */
const cnn_tensor *cnn_weights_find(const cnn_weights *w, const char *name);
/* 0 and *out (may be NULL) = the tensor if tensor `name` exists, is CNN_F32 and has exactly `ndim` dimensions of
 * sizes shape[0..ndim); otherwise -EINVAL naming the file, the tensor and both shapes (or that it is missing or
 * not float32). */
int cnn_weights_expect(const cnn_weights *w, const char *name, int ndim, const long *shape, const cnn_tensor **out,
                       sci_error *err);
/* NULL is harmless. */
void cnn_weights_free(cnn_weights *w);

#endif
