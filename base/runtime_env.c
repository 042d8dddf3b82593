#include "base/runtime_env.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* OpenBLAS's own report of its kernels. Weak: base/ does not depend on OpenBLAS; a program without it sees NULL. */
extern char *openblas_get_corename(void) __attribute__((weak));

const char *sci_runtime_env_blas_running(void) { return openblas_get_corename ? openblas_get_corename() : NULL; }

const char *sci_runtime_env_blas_core(const char *detected, int avx512)
{
    /* OpenBLAS 0.3.21's cores with AVX-512 kernels (names as openblas_get_corename spells them) */
    static const char *const with_avx512[] = {"SkylakeX", "Cooperlake", "SapphireRapids", NULL};
    if (!detected || !avx512)
        return NULL;
    for (const char *const *c = with_avx512; *c; c++)
        if (strcasecmp(detected, *c) == 0)
            return NULL;
    return "SkylakeX";
}

static int cpu_has_avx512(void)
{
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
           __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
           __builtin_cpu_supports("avx512vl");
}

void sci_runtime_env_apply(char **argv)
{
    int changed = 0;
    if (!getenv("OMP_WAIT_POLICY") && setenv("OMP_WAIT_POLICY", "passive", 1) == 0)
        changed = 1;
    const char *core = getenv("OPENBLAS_CORETYPE") ? NULL
                                                  : sci_runtime_env_blas_core(sci_runtime_env_blas_running(),
                                                                              cpu_has_avx512());
    if (core && setenv("OPENBLAS_CORETYPE", core, 1) == 0)
        changed = 1;
    if (changed)
        execv("/proc/self/exe", argv);
    /* nothing to change, or exec failed: go on with the libraries' defaults */
}
