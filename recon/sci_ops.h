/* recon/sci_ops.h — the SCI forward operator and its friends (docs/conventions.md §1).
 *
 *   A(x)    = Σ_f M_f ⊙ x_f            (w×h×N → w×h×1)
 *   Aᵀ(y)_f = M_f ⊙ y                  (no normalisation)
 *   Φ_sum   = Σ_f M_f²                 (the diagonal of AAᵀ)
 *
 * Sums over frames are accumulated in double and rounded once to float, so the result does not depend on thread
 * count and A of an integer-valued scene under 0/1 masks is exact. Threads: OpenMP over rows; call from one
 * thread at a time per output. Shapes are the caller's contract (asserted, not checked at run time): mask and x
 * w×h×N, y and phi w×h×1.
 */
#ifndef SCICAP_RECON_SCI_OPS_H
#define SCICAP_RECON_SCI_OPS_H

#include "base/cube.h"

/* Below this many elements of work a loop runs on one thread: a parallel region costs a few microseconds on a
 * quiet machine but a scheduler time slice per barrier on a loaded one, which would make small problems (and the
 * 10,000-iteration stability runs) thousands of times slower than serial. */
#define SCI_PARALLEL_MIN 65536

/* y = A(x). */
void sci_op_forward(const sci_cube *mask, const sci_cube *x, sci_cube *y);
/* x = Aᵀ(y). */
void sci_op_adjoint(const sci_cube *mask, const sci_cube *y, sci_cube *x);
/* phi = Σ_f M_f², with every 0 replaced by 1 (the zero guard: pixels no mask ever opens get no data update and
 * take their value from the denoiser alone). Returns how many pixels were guarded. */
long sci_op_phi_sum(const sci_cube *mask, sci_cube *phi);
/* yhat = A(x) (if yhat is not NULL) and the return value ‖y − A(x)‖ / ‖y‖, in one pass; rowbuf is scratch of
 * 2·h doubles. Deterministic for any thread count. yhat must not alias y. */
double sci_op_forward_residual(const sci_cube *mask, const sci_cube *x, const sci_cube *y, sci_cube *yhat,
                               double *rowbuf);
/* ‖y − A(x)‖ / ‖y‖ in double (‖y − A(x)‖ alone when ‖y‖ = 0). */
double sci_op_residual(const sci_cube *mask, const sci_cube *x, const sci_cube *y);

#endif
