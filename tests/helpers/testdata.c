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
