/* recon/nerf/adam.h — Adam with per-parameter step counts and lazy updates, plus learning-rate schedules.
 *
 * For parameter j with gradient g (plus weight_decay·p when the range asks for decay):
 *   t_j += 1;  m = β1 m + (1 − β1) g;  s = sqrt(β2 s² + (1 − β2) g²)   (s = sqrt(v), kept instead of v)
 *   p −= lr · sqrt(1 − β2^t_j)/(1 − β1^t_j) · m / (s + ε)
 * (tiny-cuda-nn `optimizers/adam.h`). Keeping s rather than v lets float32 storage hold gradients up to ~1e38:
 * v would overflow at |g| > 1.8e19 and freeze the parameter (m/inf = 0); arithmetic is in double.
 * Lazy ranges (hash tables): a parameter whose gradient is exactly 0 is skipped — no moment decay, no step
 * increment — so rarely touched entries keep their moments and their own bias correction.
 *
 * The factor lr·sqrt(1 − β2^t)/(1 − β1^t) comes from a table by step count, filled once per call (in a lazily
 * stepped table neighbours rarely share a count: two expm1 per parameter took 7 % of a RayFormer step).
 * Memory: 3 floats + 1 int32 per parameter (m, s, step), 3 doubles per step count reached. Elementwise, split
 * across OpenMP threads: the result does not depend on the thread count. Not thread-safe per object.
 */
#ifndef SCICAP_RECON_NERF_ADAM_H
#define SCICAP_RECON_NERF_ADAM_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

typedef struct nerf_adam_config {
    double beta1, beta2; /* 0.9, 0.999 (instant-ngp NeRF: 0.9, 0.99) */
    double eps;          /* 1e-8 (instant-ngp: 1e-15); > 0 */
    double weight_decay; /* L2 added to the gradient on ranges stepped with decay = 1 */
} nerf_adam_config;

typedef struct nerf_adam nerf_adam;

/* SCI_ECONFIG for β outside [0, 1), ε <= 0 or a negative decay; -ENOMEM. Moments and steps start at 0. */
int nerf_adam_new(nerf_adam **out, size_t n_params, const nerf_adam_config *cfg, sci_error *err);
void nerf_adam_free(nerf_adam *a);
void nerf_adam_reset(nerf_adam *a);

/* Update params[begin, end) from grad[begin, end) with learning rate lr. lazy: skip exact-zero gradients.
 * decay: apply weight_decay on this range. */
void nerf_adam_step(nerf_adam *a, float *params, const float *grad, size_t begin, size_t end, double lr, int lazy,
                    int decay);
/* Step count of parameter j (tests, diagnostics). */
uint32_t nerf_adam_steps_of(const nerf_adam *a, size_t j);
/* The optimiser's state for checkpoints: n_params floats m and s (= sqrt(v)) and n_params step counts; borrowed,
 * live as long as the object; writing them restores a state. */
void nerf_adam_buffers(nerf_adam *a, float **m, float **s, uint32_t **steps);
size_t nerf_adam_param_count(const nerf_adam *a);

/* lr(step) = lr0 · decay_rate^(step / decay_steps) · warm-up factor, warm-up rising linearly from warmup_start
 * (fraction of lr0) at step 0 to 1 at warmup_steps. decay_steps <= 0: no decay; warmup_steps <= 0: no warm-up.
 * SCINeRF: lr0 5e-4, decay_rate 0.1, decay_steps 200000. */
typedef struct nerf_lr_schedule {
    double lr0, decay_rate;
    long decay_steps, warmup_steps;
    double warmup_start;
} nerf_lr_schedule;

double nerf_lr_at(const nerf_lr_schedule *s, long step);

#endif
