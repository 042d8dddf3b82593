/* daemon/workers.h — the reconstruction worker pool.
 *
 * Each worker pops a reconstruct job, reads the capture folder as a problem (io/problem_dir.h), runs the solver
 * (any method of recon/solver.h, by name) with a progress callback that updates the job, streams "recon.progress" events
 * (iteration, PSNR when the truth is known, ETA; at most every 100 ms plus the last iteration) and stops at once
 * when the job is canceled or the pool is stopping. A finished run is written atomically (io/recon_store.h) to
 * <capture>/recon/<method>/, or <method>.2, .3, ... when the method already has one (daemon/reconout.h: nothing
 * is replaced); its "recon.done" names the folder. A canceled or failed run writes nothing. A finished run that finds
 * no room to be written (ENOSPC, EDQUOT) is not failed: it keeps its queue entry and its result in memory, says
 * "recon.waiting", and writes again after a back-off (1 s doubling to 60 s) until there is room, a user cancels
 * it or the daemon stops (then it is resumed at the next start). A job that ends for good (done,
 * failed, canceled by a user) has its saved copy removed (daemon/reconq.h); one stopped by the daemon's own
 * stop keeps it, to be resumed at the next start. A method with checkpoints (the NeRF methods) saves one beside
 * that copy every env->checkpoint_every steps and when the daemon stops ("recon.checkpoint" event), and a resumed
 * job continues from it (daemon/reconq.h); a checkpoint that does not fit the run is dropped and the run starts over.
 * The input is the problem the capture's writer handed over with the job (scicapd_job.problem) when there is one,
 * else the capture folder read back (requests, resumed jobs). Each stage's time is counted in env->timing.
 * Threads: `count` POSIX threads, each running OpenMP with `omp_threads` threads (0: the CPUs this process may
 * use divided by `count`, at least 1 — several single-threaded solves in parallel outrun one solve on every core
 * when writers share the cores: OpenMP's barriers stall whenever one of its threads is preempted).
 */
#ifndef SCICAP_DAEMON_WORKERS_H
#define SCICAP_DAEMON_WORKERS_H

#include "base/log.h"
#include "daemon/jobs.h"
#include "daemon/mailbox.h"
#include "daemon/queue.h"
#include "daemon/store.h"
#include "daemon/timing.h"

typedef struct scicapd_workers scicapd_workers;

typedef struct scicapd_workers_env {
    scicapd_jobs *jobs;   /* borrowed */
    scicapd_mailbox *mailbox;
    scicapd_store *store;
    scicapd_queue *in;    /* reconstruct jobs (references) */
    scicapd_timing *timing; /* recon_read, recon_solve, recon_write; may be NULL */
    const sci_log *log;
    int checkpoint_every; /* steps between checkpoints of a method that has them (0: only at a daemon stop) */
} scicapd_workers_env;

int scicapd_workers_start(scicapd_workers **out, const scicapd_workers_env *env, int count, int omp_threads,
                          sci_error *err);
/* Cancel running reconstructions, cancel what is queued (each announced), join the threads, free. The caller
 * closes env->in first. NULL is harmless. */
void scicapd_workers_stop(scicapd_workers *w);
/* OpenMP threads per worker for `count` workers when none are configured (see above). */
int scicapd_workers_auto_threads(int count);
/* Workers busy right now. */
int scicapd_workers_busy(scicapd_workers *w);

#endif
