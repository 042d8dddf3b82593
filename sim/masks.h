/* sim/masks.h — the N coded-aperture masks of a scene, as the sensor sees them when the optics are perfect.
 *
 * Kinds ("masks" object of a scene, docs/scene-format.md):
 *   "random"     each DMD mirror of each frame on with probability `density`
 *   "shifting"   CACTI: frame i is frame 0 translated by i·step pixels along `direction` ("x": right, "y": down);
 *                cut from one random pattern larger than the DMD, so nothing wraps around
 *   "superpixel" random on/off blocks of `block`×`block` mirrors (long constant runs: the DLPC900 upload
 *                compresses them well)
 *   "file"       values from a stack sidecar (.json, io/image.h) or a multi-page image; N frames of the DMD's
 *                size, values in [0, 1] (8/16-bit files are divided by their full scale)
 * DMD → sensor mapping ("dmd": width, height, scale = sensor pixels per mirror, offset = sensor position of the
 * DMD's corner, pixels): each sensor pixel takes the area-weighted mean of the mirrors it sees (mirrors outside
 * the DMD count as off). Without "dmd" the DMD has the sensor's size and maps 1:1, and masks stay exactly 0/1.
 * Random kinds draw from their own stream (sim_masks_make's `seed`, stream SIM_STREAM_MASKS), serially, so the
 * masks do not depend on thread count.
 */
#ifndef SCICAP_SIM_MASKS_H
#define SCICAP_SIM_MASKS_H

#include <stdint.h>

#include "base/cube.h"
#include "base/json.h"

#define SIM_STREAM_MASKS 0x4d41534bu /* "MASK" */

typedef enum sim_mask_kind { SIM_MASK_RANDOM, SIM_MASK_SHIFTING, SIM_MASK_SUPERPIXEL, SIM_MASK_FILE } sim_mask_kind;

typedef struct sim_mask_spec {
    sim_mask_kind kind;
    double density;         /* probability of "on", (0, 1] */
    int block;              /* superpixel size, mirrors */
    int step;               /* shifting: pixels per frame (may be negative) */
    int dir_y;              /* shifting: 0 along x, 1 along y */
    char path[4096];        /* file */
    int dmd_w, dmd_h;       /* mirrors */
    double scale;           /* sensor pixels per mirror */
    double off_x, off_y;    /* sensor pixels */
    int mapped;             /* 0: DMD = sensor, 1:1 */
} sim_mask_spec;

/* Parse the scene's "masks" object (absent: random, density 0.5). `base_dir` resolves a relative path. */
int sim_masks_parse(const sci_json_doc *doc, const json_t *root, const char *base_dir, int w, int h,
                    sim_mask_spec *out, sci_error *err);
/* Make the n masks at the DMD, then map them onto the w×h sensor. New cube in *out (caller frees).
 * Errors: file masks of the wrong size or range (-EINVAL/SCI_ESHAPE naming the file), -ENOMEM. */
int sim_masks_make(const sim_mask_spec *spec, int w, int h, int n, uint64_t seed, sci_cube **out, sci_error *err);

#endif
