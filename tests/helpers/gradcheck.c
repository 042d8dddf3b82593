/* tests/helpers/gradcheck.c — see gradcheck.h. */
#include "tests/helpers/gradcheck.h"

#include <math.h>

double gradcheck_fd(double *x, gradcheck_loss loss, void *ctx)
{
    const double h = 1e-6, x0 = *x;
    *x = x0 + h;
    double lp = loss(ctx);
    *x = x0 - h;
    double lm = loss(ctx);
    *x = x0;
    return (lp - lm) / (2 * h);
}

void gradcheck_add(gradcheck_err *e, double a, double g)
{
    e->num += (a - g) * (a - g);
    e->den += g * g;
}

void gradcheck_add_array(gradcheck_err *e, const float *a, const double *g, size_t n)
{
    for (size_t i = 0; i < n; i++) gradcheck_add(e, a[i], g[i]);
}

double gradcheck_rel(const gradcheck_err *e) { return e->den > 0 ? sqrt(e->num / e->den) : NAN; }

double gradcheck_inputs(const float *da, double *x, size_t n, gradcheck_loss loss, void *ctx)
{
    gradcheck_err e = {0};
    for (size_t i = 0; i < n; i++) gradcheck_add(&e, da[i], gradcheck_fd(&x[i], loss, ctx));
    return gradcheck_rel(&e);
}
