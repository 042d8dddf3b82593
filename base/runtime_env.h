/* base/omp_env.h — how the programs' OpenMP threads wait.
 *
 * GNU OpenMP's threads spin at every barrier by default. On a machine whose cores are shared (a lab PC running a
 * viewer, the daemon's own acquisition thread, another job), a spinning thread burns the time slice its partner
 * needs: 100 GAP-TV iterations took 2.4 s instead of 0.12 s with one other busy process here. Passive waiting
 * costs a futex wake per barrier (microseconds) and removes that cliff. libgomp reads OMP_WAIT_POLICY once, when it
 * is loaded, before main() runs, so a program that wants it must set it and re-execute itself.
 */
#ifndef SCICAP_BASE_OMP_ENV_H
#define SCICAP_BASE_OMP_ENV_H

/* If OMP_WAIT_POLICY is unset, set it to "passive" and re-execute /proc/self/exe with argv; returns only if that
 * was not needed (the user chose a policy, or this is already the re-executed process) or the exec failed (the
 * program then runs with the default policy). Call first thing in main(), before any thread exists. */
void sci_omp_env_prefer_passive(char **argv);

#endif
