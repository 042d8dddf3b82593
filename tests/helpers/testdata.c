#include "tests/helpers/testdata.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>
#include <cmocka.h>

#include "io/matfile.h"

int testdata_is_ci(void)
{
    const char *ci = getenv("CI");
    return ci && *ci && ci[0] != '0';
}

int testdata_path(const char *name, char *buf, size_t n)
{
    const char *dir = getenv("SCICAP_DATA");
    if (!dir || !*dir)
        dir = "../shared/data";
    snprintf(buf, n, "%s/%s", dir, name);
    if (access(buf, R_OK) == 0)
        return 1;
    fprintf(stderr, "TEST DATA MISSING: %s (set SCICAP_DATA to the folder holding %s)%s\n", buf, name,
            testdata_is_ci() ? " -- a failure under CI" : " -- skipping this test");
    return 0;
}

sci_problem **testdata_read_mat(const char *name, int *k)
{
    char path[4096];
    TESTDATA_REQUIRE(name, path);
    sci_problem **p = NULL;
    sci_error err = {0};
    if (sci_mat_read(path, 255, &p, k, &err) < 0)
        fail_msg("%s", err.msg);
    return p;
}

void testdata_expect_real_levels(const json_t *result, const char *who)
{
    json_t *lv = json_object_get(result, "levels");
    double p1 = json_number_value(json_object_get(lv, "p1")), p99 = json_number_value(json_object_get(lv, "p99"));
    double res = json_number_value(json_object_get(result, "residual"));
    printf("%s: frames 1st percentile %.3f, 99th %.3f of white; residual %.2g\n", who, p1, p99, res);
    assert_true(p1 >= 0 && p1 < 0.2);
    assert_true(p99 > 0.3 && p99 < 1.0);
    assert_true(res > 0 && res < 0.05);
    assert_null(json_object_get(result, "warnings"));
}
