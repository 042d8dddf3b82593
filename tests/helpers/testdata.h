/* tests/helpers/testdata.h — finding the shared benchmark data from tests.
 *
 * Data live in $SCICAP_DATA (default ../shared/data, relative to the checkout). A missing file is a test failure
 * under CI (CI set in the environment); elsewhere the test is skipped *loudly*: it prints why, and the test
 * runner counts and lists skips.
 */
#ifndef SCICAP_TESTS_TESTDATA_H
#define SCICAP_TESTS_TESTDATA_H

#include <stddef.h>

/* Full path of data file `name` into buf. Returns 1 if the file is readable, 0 if not (after printing why). */
int testdata_path(const char *name, char *buf, size_t n);
/* For use inside a cmocka test: find `name` or fail (CI) / skip with a message (elsewhere). */
#define TESTDATA_REQUIRE(name, buf)                                                                            \
    do {                                                                                                       \
        if (!testdata_path((name), (buf), sizeof(buf))) {                                                      \
            if (testdata_is_ci())                                                                              \
                fail_msg("test data %s missing under CI (set SCICAP_DATA)", (name));                           \
            else                                                                                               \
                skip();                                                                                        \
        }                                                                                                      \
    } while (0)
int testdata_is_ci(void);

#include "recon/problem.h"
/* For use inside a cmocka test: data file `name` (a .mat of the benchmark) read by sci_mat_read at white 255, its
 * k problems (the caller frees them: sci_problem_array_free). A missing file fails or skips as TESTDATA_REQUIRE;
 * one that cannot be read fails the test. */
sci_problem **testdata_read_mat(const char *name, int *k);

#include <jansson.h>
/* For use inside a cmocka test: the result.json (object `result`) of a reconstruction of data/real's capture shows the
 * scene: frames neither black nor saturated (levels' 1st percentile in [0, 0.2), 99th in (0.3, 1)), the measurement
 * fitted (0 < residual < 5 %), no warnings. Prints the levels under `who`; fails the test otherwise. */
void testdata_expect_real_levels(const json_t *result, const char *who);

#endif
