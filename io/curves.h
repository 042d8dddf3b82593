/* io/curves.h — choosing a reconstruction setting by time budget, from the measured accuracy-against-time curves
 * (bench/results.csv, written by `scicap bench`; installed as <prefix>/share/scicap/results.csv).
 *
 * The curves were measured on a fixed suite of scenes of known size. For a new problem of `voxels` = w·h·N, a
 * point's time is predicted by scaling its wall time with voxels (the classical solvers and the NeRF renders are
 * linear in it; training cost per step is not, which makes the prediction conservative for larger problems).
 * Only scenes of the problem's kind count: with a camera (static3d) or without (video2d, benchmark data). A
 * setting qualifies when it ran on every such scene; it fits the budget when its largest predicted time does;
 * among those that fit, the one with the highest mean PSNR wins.
 *
 * Not thread-safe per object; read-only after load, so concurrent picks on one loaded object are fine.
 */
#ifndef SCICAP_IO_CURVES_H
#define SCICAP_IO_CURVES_H

#include <jansson.h>

#include "base/error.h"
#include "recon/solver.h"

typedef struct sci_curves sci_curves;

/* Bytes of a setting's text ("iters=100 tv_iters=5"), its NUL included: longer ones are refused where they are
 * read or made, never cut. */
#define SCI_CURVE_SETTING_MAX 256

typedef struct sci_curve_choice {
    char method[SOLVER_NAME_MAX];
    char setting[SCI_CURVE_SETTING_MAX]; /* "iters=100 tv_iters=5" */
    double predicted_s; /* largest predicted wall time over the scenes of the kind */
    double mean_psnr;   /* mean PSNR over those scenes, dB (peak = frame max) */
    int scenes;         /* how many scenes the mean is over */
} sci_curve_choice;

/* Load the CSV. -errno with the path, SCI_EFORMAT with the line for a malformed file. */
int sci_curves_load(sci_curves **out, const char *csv_path, sci_error *err);
void sci_curves_free(sci_curves *c);

/* Pick for a problem of `voxels` (w·h·N) with or without a camera, within `budget_s` seconds of solver time.
 * `method` restricts the choice to one method (NULL: any). Returns 0 and fills *out; -ERANGE when nothing fits
 * (the message names the cheapest setting and its predicted time, and *out holds it); -ENOENT when no setting of
 * that method and kind was measured. */
int sci_curves_pick(const sci_curves *c, const char *method, int has_camera, double voxels, double budget_s,
                    sci_curve_choice *out, sci_error *err);

/* The setting as a JSON object, each KEY=VALUE token read as sci_json_set_kv (base/json.h) reads `--set`:
 * {"iters": 100, "lambda": 0.5, "preset": "fast"}; new reference, NULL if malformed (a token without "=", an
 * empty key or value, a key of 128 bytes or more, a value not in UTF-8, SCI_CURVE_SETTING_MAX bytes or more). */
json_t *sci_curves_setting_json(const char *setting);

/* The text of a settings object, what sci_curves_setting_json reads back to an equal object: KEY=VALUE tokens in the
 * object's order, true/false, null, an integer, a real in the fewest digits (15 … 17) that read back to the same
 * double, a list of numbers as its values joined by '/' (50/25: no comma in a CSV column), a string as itself unless
 * it would read back as another value ("5", "true", "[1]"), then JSON-quoted. Writes at most n bytes to buf, always
 * terminated. Returns 0; -ENAMETOOLONG when the text needs n bytes or more; -EINVAL for a value the text cannot hold
 * (an object, a list of other than numbers, a string with a space, a comma or a control character, an empty string
 * or key, a key with '='). */
int sci_curves_setting_text(const json_t *settings, char *buf, size_t n);

#endif
