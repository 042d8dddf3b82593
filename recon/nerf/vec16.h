/* recon/nerf/vec16.h — the 16-float vector of the NeRF kernels (attention.c, smallgemm.c): GCC vector extensions,
 * lowered to one zmm, two ymm or four xmm by the target clone that includes it.
 *
 * Loads and stores go through memcpy (any alignment, no aliasing question). Stores are a macro: no function here
 * takes a 64-byte vector parameter, and the helpers are always inlined, so the psABI note gcc prints about passing
 * such vectors never applies; the including file's remaining code gets the same silence (include it only from
 * kernel files).
 */
#ifndef SCICAP_RECON_NERF_VEC16_H
#define SCICAP_RECON_NERF_VEC16_H

#include <string.h>

#pragma GCC diagnostic ignored "-Wpsabi"

#define VW 16
typedef float vf __attribute__((vector_size(4 * VW)));
typedef struct vbox {
    vf v;
} vbox;

static inline __attribute__((always_inline)) vf vload(const float *p)
{
    vf v;
    memcpy(&v, p, sizeof v);
    return v;
}
#define vstore(p, x) memcpy((p), &(vbox){(x)}.v, sizeof(vf))
static inline __attribute__((always_inline)) vf vsplat(float x) { return (vf){0} + x; }

#endif
