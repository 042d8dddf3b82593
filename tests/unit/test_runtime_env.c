/* base/runtime_env: which OpenBLAS core a program asks for, and that the programs run with it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "base/runtime_env.h"

/* A generic core on an AVX-512 CPU is replaced by SkylakeX; an AVX-512 core, a CPU without AVX-512 or a program
 * without OpenBLAS keep what they have. */
static void test_blas_core_choice(void **state)
{
    assert_string_equal(sci_runtime_env_blas_core("Prescott", 1), "SkylakeX");
    assert_string_equal(sci_runtime_env_blas_core("Haswell", 1), "SkylakeX");
    assert_null(sci_runtime_env_blas_core("SkylakeX", 1));
    assert_null(sci_runtime_env_blas_core("cooperlake", 1));
    assert_null(sci_runtime_env_blas_core("SapphireRapids", 1));
    assert_null(sci_runtime_env_blas_core("Prescott", 0));
    assert_null(sci_runtime_env_blas_core("Haswell", 0));
    assert_null(sci_runtime_env_blas_core(NULL, 1));
}

/* `scicap --version` names the kernels it runs with: on an AVX-512 CPU never a core without AVX-512 unless the user
 * asked for it, and a core the user names is the one used. */
static void test_programs_run_with_the_choice(void **state)
{
    const char *build = getenv("BUILD");
    char cmd[1024], line[256] = "";
    __builtin_cpu_init();
    int avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
                 __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
                 __builtin_cpu_supports("avx512vl");
    snprintf(cmd, sizeof cmd, "env -u OPENBLAS_CORETYPE %s/scicap --version | grep '^OpenBLAS kernels:'",
             build ? build : "build");
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    assert_non_null(fgets(line, sizeof line, p));
    assert_int_equal(pclose(p), 0);
    print_message("  %s", line);
    if (avx512)
        assert_true(strstr(line, "SkylakeX") || strstr(line, "Cooperlake") || strstr(line, "SapphireRapids"));
    snprintf(cmd, sizeof cmd, "OPENBLAS_CORETYPE=Haswell %s/scicap --version | grep '^OpenBLAS kernels:'",
             build ? build : "build");
    p = popen(cmd, "r");
    assert_non_null(p);
    assert_non_null(fgets(line, sizeof line, p));
    assert_int_equal(pclose(p), 0);
    assert_non_null(strstr(line, "Haswell (OPENBLAS_CORETYPE=Haswell)"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_blas_core_choice),
                                       cmocka_unit_test(test_programs_run_with_the_choice)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
