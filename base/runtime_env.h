/* base/runtime_env.h — what the programs set before their libraries read the environment.
 *
 * Two libraries read a setting once, when they are loaded, before main() runs, so a program that wants another
 * value must set it and re-execute itself:
 *
 * - GNU OpenMP's threads spin at every barrier by default (OMP_WAIT_POLICY). On a machine whose cores are shared
 *   (a lab PC running a viewer, the daemon's own acquisition thread, another job), a spinning thread burns the
 *   time slice its partner needs: 100 GAP-TV iterations took 2.4 s instead of 0.12 s with one other busy process
 *   here. Passive waiting costs a futex wake per barrier (microseconds) and removes that cliff.
 * - OpenBLAS's DYNAMIC_ARCH build picks its kernels by CPU family and model (OPENBLAS_CORETYPE overrides). A CPU
 *   it does not know gets the generic Prescott (SSE3) kernels although it has AVX-512: on this machine's virtual
 *   "Intel Xeon Processor" a RayFormer step spent 39 % of its time in Prescott's sgemm, and 30 steps took 40.6 s of
 *   CPU against 25.1 s with the SkylakeX (AVX-512) kernels, same PSNR to 0.01 dB. When the CPU has AVX-512 (F, CD,
 *   BW, DQ, VL) and OpenBLAS chose a core without it, SkylakeX is asked for.
 *
 * A variable the user set is always left as it is. Not thread-safe: call first thing in main().
 */
#ifndef SCICAP_BASE_RUNTIME_ENV_H
#define SCICAP_BASE_RUNTIME_ENV_H

/* Set OMP_WAIT_POLICY=passive and, where sci_runtime_env_blas_core says so, OPENBLAS_CORETYPE, when unset, then
 * re-execute /proc/self/exe with argv; returns only if nothing needed setting (the user chose, or this is already
 * the re-executed process) or the exec failed (the program then runs with the libraries' defaults). Call before
 * any thread exists. */
void sci_runtime_env_apply(char **argv);

/* The OpenBLAS core to ask for, or NULL to keep OpenBLAS's choice: `detected` is the core OpenBLAS chose (NULL when
 * the program is not linked with OpenBLAS), `avx512` whether the CPU has AVX-512 F, CD, BW, DQ and VL. Pure. */
const char *sci_runtime_env_blas_core(const char *detected, int avx512);

/* The core OpenBLAS runs with (e.g. "SkylakeX"), or NULL when the program is not linked with OpenBLAS. Borrowed,
 * static storage. */
const char *sci_runtime_env_blas_running(void);

#endif
