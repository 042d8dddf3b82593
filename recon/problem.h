/* recon/problem.h — what every solver takes and gives: problem, result, trace, progress callback.
 *
 * A sci_problem is one coded snapshot with everything needed to reconstruct it: the measurement y (w×h×1), the
 * masks M (w×h×N), optionally the truth X (w×h×N) and, for scenes seen by a moving camera, the camera
 * (intrinsics and N poses). The same problem comes from a .mat benchmark file, a simulator run or a capture
 * folder, so every method runs on every source.
 *
 * Scale: solvers work on whatever scale the problem is in; io/ divides 8-bit benchmark data by 255 so that truth
 * lies in [0, 1] (docs/conventions.md §1). `peak` says what "white" is on this scale (1 for /255 data).
 *
 * A sci_result is the reconstructed frames plus the trace: one entry per iteration with wall time, relative
 * residual ‖y − Ax‖/‖y‖ and, when truth is present, PSNR and SSIM. This is how the project shows what accuracy
 * costs in time. Wall time in the trace excludes the time spent computing the trace's own metrics.
 *
 * Ownership: sci_problem_free frees the cubes and camera the problem points to (it owns them);
 * sci_result_free frees frames and trace. Both accept NULL.
 */
#ifndef SCICAP_RECON_PROBLEM_H
#define SCICAP_RECON_PROBLEM_H

#include <stddef.h>

#include "base/cube.h"
#include "base/error.h"

/* Pinhole camera of a static3d scene (sim/), in the NeRF convention: camera-to-world poses, camera axes x right,
 * y up, looking along −z. Pixel (px, py) (column, row; centres at +0.5) sees direction
 * ((px + 0.5 − cx)/fx, −(py + 0.5 − cy)/fy, −1) in camera coordinates. Lengths in scene units, angles radians. */
typedef struct sci_camera {
    double fx, fy, cx, cy; /* pixels */
    int n;                 /* number of poses (= frames of the problem) */
    double (*pose)[12];    /* n poses, each row-major 3×4 [R | t], camera-to-world; owned */
    double near_m, far_m;  /* depth range along −z to sample (scene units) */
} sci_camera;

typedef struct sci_problem {
    sci_cube *meas;      /* y: w×h×1 */
    sci_cube *mask;      /* M: w×h×N */
    sci_cube *truth;     /* X: w×h×N, or NULL */
    sci_camera *camera;  /* or NULL */
    double peak;         /* value of white on the problem's scale (PSNR peak-1 convention); 1 for /255 data */
    char name[128];      /* e.g. "drop40_cacti.mat#1": shown in printouts and metadata */
} sci_problem;

/* Check shapes (meas w×h×1, mask and truth w×h×N), finiteness of every input, and camera consistency.
 * Returns 0, or SCI_ESHAPE / SCI_ENONFINITE / -EINVAL with a message naming the problem and the part at fault. */
int sci_problem_validate(const sci_problem *p, sci_error *err);
void sci_problem_free(sci_problem *p);
/* Free an array of k problems and the array itself (as returned by the io/ readers). NULL is harmless. */
void sci_problem_array_free(sci_problem **p, int k);
sci_camera *sci_camera_new(int n);
void sci_camera_free(sci_camera *c);

/* One row of the trace. Metrics the solver could not compute are NaN (psnr and ssim without truth). */
typedef struct sci_trace_entry {
    int iter;          /* 1-based iteration (or training step for NeRF methods) */
    double wall_s;     /* solver wall time since start, excluding trace-metric evaluation */
    double cpu_s;      /* process CPU time since start (all threads), same exclusion */
    double residual;   /* ‖y − A x‖ / ‖y‖ (NeRF methods: of the current render) */
    double loss;       /* method's objective if it has one, else NaN */
    double psnr;       /* mean over frames, peak = per-frame max of truth; NaN without truth */
    double psnr_peak1; /* mean over frames, peak = problem->peak */
    double ssim;       /* mean over frames (Gaussian window, data range problem->peak) */
    double meas_residual; /* NeRF methods, at full renders: ‖y − A x‖/‖y‖ over the whole snapshot; else NaN */
    double max_weight;    /* NeRF methods, at full renders: mean over the rays that hit something (opacity ≥ 0.5)
                             of the ray's largest sample weight (1: a surface, ≲ 0.3: fog); else NaN */
    int plane;            /* 0: the whole problem; 1-4: the CFA plane of a colour run solved plane by plane (its
                             iterations count from 1 again, its metrics are the plane's) */
} sci_trace_entry;

typedef struct sci_trace {
    sci_trace_entry *e;
    size_t len, cap;
} sci_trace;

int sci_trace_push(sci_trace *t, const sci_trace_entry *e);
void sci_trace_clear(sci_trace *t);
/* Write the trace as CSV with a header line. -errno with the path on failure. */
int sci_trace_write_csv(const sci_trace *t, const char *path, sci_error *err);

/* Bytes of a method name, the NUL included (recon/solver.h calls it SOLVER_NAME_MAX; its table check refuses a
 * longer name, so buffers of this size never cut one). */
#define SCI_METHOD_NAME_MAX 32

typedef struct sci_result {
    sci_cube *frames;   /* w×h×N reconstruction, owned */
    sci_trace trace;    /* owned */
    int iters_done;     /* iterations completed */
    int stopped;        /* 0 ran to the end; SCI_ECANCELED; SCI_EDIVERGED */
    sci_error error;    /* message when the solver returned an error */
    char method[SCI_METHOD_NAME_MAX]; /* "gap-tv", "admm-tv", ... */
    /* The metrics the tracer computed on its last iteration (truth known), per frame, so that writers of
     * result.json need not compute them again (an SSIM is ~25 ms for 256×256×8): 3·n values — PSNR (per-frame
     * max), PSNR (peak), SSIM — owned, or NULL. Valid for `final_of` (the frames' data they were computed on). */
    double *final_metrics;
    int final_n;
    const float *final_of;
} sci_result;

void sci_result_free_contents(sci_result *r); /* frees frames, trace and final_metrics, keeps the struct */

/* Called after every iteration with the newest trace entry. Return nonzero to cancel: the solver stops, keeps
 * its current estimate in result->frames, and returns SCI_ECANCELED. Called on the solver's thread. */
typedef int (*sci_progress_fn)(const sci_trace_entry *entry, void *user);

#endif
