/* tests/unit/test_nerf_smallgemm.c — the narrow matrix products against a plain double product, over every
 * vector count (1 … 8 of 16 floats), widths that are not multiples of 16, row counts that leave rows over after
 * the blocks of 4, 3 or 2, leading dimensions wider than the rows, both layouts of B, with and without bias and
 * accumulation. Every buffer is allocated to its exact size, so a read or write past a row's end is caught under
 * ASan; the cells between rows (ld > width) must stay untouched.
 *
 * Tolerance: float sums of up to 128 (rows) or 301 (atb) products of values in [−1, 1], against double: the
 * relative error per element stays below ~1e-6 of the sum of magnitudes; the bound 1e-5 separates that from any
 * wrong or missing term (≥ 1e-2).
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "base/rng.h"
#include "recon/nerf/smallgemm.h"

static float *random_floats(sci_rng *rng, size_t n)
{
    float *p = malloc(n * sizeof *p);
    assert_non_null(p);
    for (size_t i = 0; i < n; i++) p[i] = (float)(2.0 * sci_rng_uniform(rng) - 1.0);
    return p;
}

static const float PAD = 12345.0f; /* the cells between rows (ld > width): never written */

static void check_rows(sci_rng *rng, int m, int ka, int nb, int trans_b, int with_bias, int accumulate)
{
    const int lda = ka + 3, ldb = (trans_b ? ka : nb) + 2, ldc = nb + 5;
    float *A = random_floats(rng, (size_t)m * lda);
    float *B = random_floats(rng, (size_t)(trans_b ? nb : ka) * ldb);
    float *bias = with_bias ? random_floats(rng, (size_t)nb) : NULL;
    float *C = random_floats(rng, (size_t)m * ldc);
    for (int i = 0; i < m; i++)
        for (int o = nb; o < ldc; o++) C[(size_t)i * ldc + o] = PAD;
    double *want = malloc((size_t)m * nb * sizeof *want), worst = 0.0;
    for (int i = 0; i < m; i++)
        for (int o = 0; o < nb; o++) {
            double s = bias ? bias[o] : 0.0, mag = fabs(s);
            for (int j = 0; j < ka; j++) {
                double b = trans_b ? B[(size_t)o * ldb + j] : B[(size_t)j * ldb + o];
                s += (double)A[(size_t)i * lda + j] * b, mag += fabs(A[(size_t)i * lda + j] * b);
            }
            if (accumulate) s += C[(size_t)i * ldc + o], mag += fabs(C[(size_t)i * ldc + o]);
            want[(size_t)i * nb + o] = s, worst = mag > worst ? mag : worst;
        }
    nerf_smallgemm_rows(m, ka, nb, A, lda, B, ldb, trans_b, bias, accumulate, C, ldc);
    double err = 0.0;
    for (int i = 0; i < m; i++) {
        for (int o = 0; o < nb; o++) err = fmax(err, fabs(C[(size_t)i * ldc + o] - want[(size_t)i * nb + o]));
        for (int o = nb; o < ldc; o++) assert_true(C[(size_t)i * ldc + o] == PAD);
    }
    if (!(err <= 1e-5 * (worst > 1 ? worst : 1)))
        fail_msg("rows m %d ka %d nb %d trans_b %d bias %d accumulate %d: error %.3g", m, ka, nb, trans_b, with_bias,
                 accumulate, err);
    free(A), free(B), free(bias), free(C), free(want);
}

static void check_atb(sci_rng *rng, int m, int nb, int k)
{
    const int lda = nb + 1, ldx = k + 4, ldd = k + 2;
    float *A = random_floats(rng, (size_t)m * lda), *X = random_floats(rng, (size_t)m * ldx);
    float *D = random_floats(rng, (size_t)nb * ldd);
    for (int o = 0; o < nb; o++)
        for (int c = k; c < ldd; c++) D[(size_t)o * ldd + c] = PAD;
    double *want = malloc((size_t)nb * k * sizeof *want), err = 0.0, worst = 1.0;
    for (int o = 0; o < nb; o++)
        for (int c = 0; c < k; c++) {
            double s = D[(size_t)o * ldd + c], mag = fabs(s);
            for (int i = 0; i < m; i++) {
                double t = (double)A[(size_t)i * lda + o] * X[(size_t)i * ldx + c];
                s += t, mag += fabs(t);
            }
            want[(size_t)o * k + c] = s, worst = mag > worst ? mag : worst;
        }
    nerf_smallgemm_atb(m, nb, k, A, lda, X, ldx, D, ldd);
    for (int o = 0; o < nb; o++) {
        for (int c = 0; c < k; c++) err = fmax(err, fabs(D[(size_t)o * ldd + c] - want[(size_t)o * k + c]));
        for (int c = k; c < ldd; c++) assert_true(D[(size_t)o * ldd + c] == PAD);
    }
    if (!(err <= 1e-5 * worst)) fail_msg("atb m %d nb %d k %d: error %.3g (of %.3g)", m, nb, k, err, worst);
    free(A), free(X), free(D), free(want);
}

/* Widths 1 … 128 through every vector count and tail; the RayFormer's own shapes among them. */
static const int WIDTHS[] = {1, 3, 15, 16, 17, 19, 32, 33, 48, 64, 70, 80, 96, 100, 112, 127, 128};
#define N_WIDTHS (int)(sizeof WIDTHS / sizeof *WIDTHS)

static void test_rows_match_double(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, 20261206u, 1);
    int cases = 0;
    for (int a = 0; a < N_WIDTHS; a++)
        for (int b = 0; b < N_WIDTHS; b++) {
            const int m = 1 + (a * 7 + b * 3) % 13; /* 1 … 13 rows: every remainder of the row blocks */
            check_rows(&rng, m, WIDTHS[a], WIDTHS[b], (a + b) % 2, b % 3 == 0, a % 2);
            cases++;
        }
    check_rows(&rng, 1024, 32, 96, 1, 1, 0); /* a RayFormer group: QKV */
    check_rows(&rng, 1024, 96, 32, 0, 0, 1);
    printf("%d shapes of C = [C +] bias + A·B match the double product\n", cases + 2);
}

static void test_atb_match_double(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, 20261206u, 2);
    int cases = 0;
    for (int a = 0; a < N_WIDTHS; a++)
        for (int b = 0; b < N_WIDTHS; b++) {
            check_atb(&rng, 1 + (a * 5 + b) % 9, WIDTHS[a], WIDTHS[b]);
            cases++;
        }
    check_atb(&rng, 301, 64, 32);
    printf("%d shapes of D += Aᵀ·X match the double product\n", cases + 1);
}

/* Hard cases: a NaN in A reaches exactly its own row of C (and its own column of D), a padded lane never leaks
 * into a real one; products of 1e30 overflow to ±inf as float arithmetic does; denormal inputs give their exact
 * (tiny) sums; zero rows give zeros (or the bias). */
static void test_hard_cases(void **state)
{
    (void)state;
    enum { M = 9, KA = 19, NB = 33 };
    float A[M * KA], B[KA * NB], C[M * NB], bias[NB];
    for (int i = 0; i < M * KA; i++) A[i] = (float)((i % 7) - 3) * 0.25f;
    for (int i = 0; i < KA * NB; i++) B[i] = (float)((i % 5) - 2) * 0.5f;
    for (int o = 0; o < NB; o++) bias[o] = (float)o;
    A[4 * KA + 7] = NAN;
    for (int j = 0; j < KA; j++) A[6 * KA + j] = 0.0f; /* a zero row */
    nerf_smallgemm_rows(M, KA, NB, A, KA, B, NB, 0, bias, 0, C, NB);
    for (int i = 0; i < M; i++)
        for (int o = 0; o < NB; o++) {
            if (i == 4) assert_true(isnan(C[i * NB + o]));
            else assert_true(isfinite(C[i * NB + o]));
            if (i == 6) assert_true(C[i * NB + o] == bias[o]);
        }
    /* overflow: 1e30 · 1e30 is +inf in float, −inf where a factor is negative; +inf + (−inf) is NaN */
    float a2[2] = {1e30f, 1e30f}, b2[2 * 3] = {1e30f, -1e30f, 1e30f, 1e30f, -1e30f, -1e30f}, c2[3];
    nerf_smallgemm_rows(1, 2, 3, a2, 2, b2, 3, 0, NULL, 0, c2, 3);
    assert_true(isinf(c2[0]) && c2[0] > 0);
    assert_true(isinf(c2[1]) && c2[1] < 0);
    assert_true(isnan(c2[2])); /* +inf + (−inf) */
    /* denormals: 1e-39 · 1 summed 3 times */
    float a3[3] = {1e-39f, 1e-39f, 1e-39f}, b3[3] = {1.0f, 1.0f, 1.0f}, c3[1];
    nerf_smallgemm_rows(1, 3, 1, a3, 3, b3, 1, 0, NULL, 0, c3, 1);
    assert_true(c3[0] == (1e-39f + 1e-39f) + 1e-39f && c3[0] > 0.0f);
    /* D += Aᵀ·X with a NaN in X: only its column of D */
    float X[M * KA], D[NB * KA];
    for (int i = 0; i < M * KA; i++) X[i] = (float)((i % 3) - 1);
    for (int i = 0; i < NB * KA; i++) D[i] = 0.0f;
    X[2 * KA + 5] = NAN;
    float Aw[M * NB];
    for (int i = 0; i < M * NB; i++) Aw[i] = 0.5f;
    nerf_smallgemm_atb(M, NB, KA, Aw, NB, X, KA, D, KA);
    for (int o = 0; o < NB; o++)
        for (int c = 0; c < KA; c++) assert_true(c == 5 ? isnan(D[o * KA + c]) : isfinite(D[o * KA + c]));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rows_match_double),
        cmocka_unit_test(test_atb_match_double),
        cmocka_unit_test(test_hard_cases),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
