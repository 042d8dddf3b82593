/* recon/nerf/trainer_run.h — private to trainer.c and trainer_ckpt.c: the state of one training run, and the
 * checkpoint functions that save and restore it (format in trainer.h). Not an API: nothing else includes it. */
#ifndef SCICAP_RECON_NERF_TRAINER_RUN_H
#define SCICAP_RECON_NERF_TRAINER_RUN_H

#include <stddef.h>
#include <stdint.h>

#include "base/rng.h"
#include "recon/nerf/adam.h"
#include "recon/nerf/poses.h"
#include "recon/nerf/trainer.h"

/* One rendering pass (coarse, or fine): its model, optimiser and buffers for up to G groups. The camera-frame
 * samples of the coarse pass depend only on the pixel (indexed by location b); those of the fine pass depend on
 * the pose through the coarse weights (indexed by group q). */
typedef struct nerf_trainer_pass {
    const nerf_model *m;
    nerf_adam *adam;
    float *params, *grad;
    float *ema;                           /* n_params: the weights' moving average (ema_steps > 0), or NULL */
    int L, per_group;
    float *t, *pcam, *delta;              /* camera frame: G·R·L (t: fine only) */
    float *pos, *sigma, *rgb;             /* G·R·L */
    float *color, *grey, *dC, *d_color;   /* G·R */
    float *d_sigma, *d_rgb, *d_pos, *d_dir;
    float *d_sigma_dist;                  /* G·R·L: the distortion loss's σ gradient (coarse pass, when on) */
    float *tn, *depth, *d_depth;          /* depth TV (coarse pass, when on): sample depths normalised over
                                             near … far (G·R·L), rendered depth and its gradient (G·R) */
} nerf_trainer_pass;

typedef struct nerf_trainer_run_state {
    const sci_problem *pb;
    const nerf_train_config *c;
    int w, h, n, R, B, G, n_pass;
    double near, far, y_rms;
    nerf_poses *poses;
    nerf_trainer_pass ps[2];
    int *px, *py;
    float *dcam, *dir, *Y, *M;
    sci_cube *prior;   /* GAP-TV frames (w×h×N) for the warm start, or NULL */
    float *Xp;         /* G·R: the prior at the step's pixels, laid out like the grey values */
    double (*T)[12];
    double *imp_cdf, *imp_u; /* importance sampling scratch: Lc, Lf */
    float *imp_tc, *imp_tf;
    sci_rng rng;
    int64_t wall0_ns, cpu0_ns; /* elapsed time carried over from a checkpoint */
    int ema_live;              /* the passes' ema arrays hold the weights' moving average (it has begun) */
} nerf_trainer_run_state;

/* Blob of the run's whole state after step `iter` (malloc'd into *out, the caller frees). 0 or -ENOMEM. */
int nerf_trainer_ckpt_save(nerf_trainer_run_state *r, int iter, double wall_s, double cpu_s, unsigned char **out,
                           size_t *bytes);
/* Restore the run from a blob: the step it was taken after (>= 0), or SCI_EFORMAT / SCI_ESHAPE / SCI_ENONFINITE
 * with a message. The run must have been built for the same method, problem size and models. */
int nerf_trainer_ckpt_load(nerf_trainer_run_state *r, const void *blob, size_t bytes, sci_error *err);
/* The scene box stored in a blob (validated first). */
int nerf_trainer_ckpt_box(const void *blob, size_t bytes, float lo[3], float hi[3], sci_error *err);

#endif
