/* libFuzzer target: the legacy torch.save state-dict reader (recon/cnn/weights.h) and its pickle machine
 * (recon/cnn/pickle.h), from memory. Seeds in tests/fuzz/corpus/weights/: small files written by torch 1.13 with
 * _use_new_zipfile_serialization=False (two tensors in a dict; an OrderedDict with views, 0-d, Long and Double
 * storages and _metadata) and a truncated copy. On success every F32 tensor's data is read once, so ASan sees any
 * pointer past its storage, and the lookups run on what came back. */
#include <stdint.h>
#include <stdlib.h>

#include "recon/cnn/weights.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    cnn_weights *w = NULL;
    sci_error err = {0};
    if (cnn_weights_parse(data, size, "fuzz.pth", &w, &err) < 0) {
        if (w || !err.msg[0] || err.code >= 0)
            abort(); /* an error must leave no object and say what went wrong */
        return 0;
    }
    volatile float sink = 0;
    for (int k = 0; k < w->n; k++) {
        const cnn_tensor *t = &w->t[k];
        if (t->ndim < 0 || t->ndim > 4 || (t->dtype == CNN_F32) != (t->data != NULL))
            abort();
        size_t count = 1;
        for (int d = 0; d < t->ndim; d++)
            count *= (size_t)t->shape[d];
        if (count != t->count)
            abort();
        for (size_t i = 0; t->data && i < t->count; i++)
            sink += t->data[i];
        if (cnn_weights_find(w, t->name) != t)
            abort(); /* names are unique */
        cnn_weights_expect(w, t->name, t->ndim, t->shape, NULL, &err);
    }
    (void)sink;
    cnn_weights_free(w);
    return 0;
}
