/* tests/helpers/gradcheck.h — the gradient checks' arithmetic (tests/unit/test_nerf_mlp.c, test_nerf_rayformer.c):
 * central differences of a double reference loss, and the norm-wise relative error ‖a − g‖ / ‖g‖ of a float
 * analytic gradient a against them.
 *
 * Pure arithmetic on the caller's arrays: nothing is allocated, nothing fails. */
#ifndef SCICAP_TESTS_GRADCHECK_H
#define SCICAP_TESTS_GRADCHECK_H

#include <stddef.h>

/* The loss as a function of the double inputs it reads through ctx. */
typedef double (*gradcheck_loss)(void *ctx);

/* Running sums of ‖a − g‖² and ‖g‖². */
typedef struct gradcheck_err {
    double num, den;
} gradcheck_err;

/* d loss / d *x by central differences, h = 1e-6; *x is restored. */
double gradcheck_fd(double *x, gradcheck_loss loss, void *ctx);

/* Adds one analytic value a against its reference g. */
void gradcheck_add(gradcheck_err *e, double a, double g);

/* Adds n float values a[i] against the double references g[i] (e.g. a forward against the double path). */
void gradcheck_add_array(gradcheck_err *e, const float *a, const double *g, size_t n);

/* ‖a − g‖ / ‖g‖ of the values added; NaN when nothing nonzero was added. */
double gradcheck_rel(const gradcheck_err *e);

/* The relative error of the analytic gradient da[0 … n) of the inputs x[0 … n) (each differenced in turn). */
double gradcheck_inputs(const float *da, double *x, size_t n, gradcheck_loss loss, void *ctx);

#endif
