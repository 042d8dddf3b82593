/* base/runtime_env: which OpenBLAS core a program asks for, and that the programs run with it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>
#include <glob.h>

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

/* Every program of the tree (scicap, scicapd, each bench/ program) applies the runtime environment first thing in
 * main(): a bench that left it out measured its methods with OpenBLAS's generic kernels, 1.44 times slower than
 * scicap runs them (900 RayFormer steps on photo_llff: 387 s against 269 s). The checker is tried on two texts. */
static int applies_first(const char *text)
{
    const char *m = strstr(text, "int main(");
    const char *body = m ? strchr(m, '{') : NULL;
    if (!body)
        return -1; /* no main: not a program */
    body++;
    body += strspn(body, " \n");
    return strncmp(body, "sci_runtime_env_apply(argv);", 28) == 0;
}

static void test_every_program_applies_it(void **state)
{
    assert_int_equal(applies_first("int main(int argc, char **argv)\n{\n    sci_runtime_env_apply(argv); /* */\n"), 1);
    assert_int_equal(applies_first("int main(void)\n{\n    int x = 0;\n    sci_runtime_env_apply(argv);\n"), 0);
    assert_int_equal(applies_first("static int helper(void) { return 0; }\n"), -1);
    glob_t g;
    assert_int_equal(glob("bench/*.c", 0, NULL, &g), 0);
    assert_int_equal(glob("cli/main.c", GLOB_APPEND, NULL, &g), 0);
    assert_int_equal(glob("daemon/main.c", GLOB_APPEND, NULL, &g), 0);
    int programs = 0;
    for (size_t i = 0; i < g.gl_pathc; i++) {
        FILE *f = fopen(g.gl_pathv[i], "r");
        assert_non_null(f);
        static char text[1 << 20];
        size_t n = fread(text, 1, sizeof text - 1, f);
        fclose(f);
        text[n] = 0;
        int r = applies_first(text);
        if (r == 0)
            fail_msg("%s: main() does not begin with sci_runtime_env_apply(argv)", g.gl_pathv[i]);
        programs += r == 1;
    }
    print_message("  %d programs apply the runtime environment first\n", programs);
    assert_true(programs >= 12);
    globfree(&g);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_blas_core_choice),
                                       cmocka_unit_test(test_programs_run_with_the_choice),
                                       cmocka_unit_test(test_every_program_applies_it)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
