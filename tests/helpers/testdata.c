#include "tests/helpers/testdata.h"

#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

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
