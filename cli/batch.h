/* cli/batch.h — `scicap batch` (and `scicap recon` with several inputs): many reconstructions, each one
 * `scicap recon INPUT -o OUTDIR/NAME` run as a child process (a crash or a failure stays that job's), locally or
 * as a Slurm array job, resumable.
 *
 * The output folder holds the results in the usual layout (OUTDIR/NAME/, written by scicap recon under a staging
 * name and renamed when complete) and the batch's own files in OUTDIR/.batch/:
 *     state.json        the jobs (name, input, state, time, PSNR, error, attempts, Slurm task), the recon options,
 *                       the last Slurm array job; rewritten atomically after every change
 *     logs/NAME.log     each job's standard output (metrics) and, under Slurm, slurm-JOB_TASK.log
 *     tasks/NAME.json   what a Slurm task recorded at its end (state, exit status, seconds, PSNR, host)
 *     slurm-N.sh        the sbatch scripts submitted
 * A job is finished when OUTDIR/NAME exists: that folder only appears complete, so a re-run (local or --slurm)
 * runs exactly the jobs whose folder is missing, whatever the state file says.
 *
 * Functions return 0 or a negative code with a message in err (nothing here exits). Not thread-safe.
 */
#ifndef SCICAP_CLI_BATCH_H
#define SCICAP_CLI_BATCH_H

#include <stddef.h>

#include "base/error.h"

typedef enum batch_state {
    BATCH_PENDING,   /* not run yet, or interrupted */
    BATCH_RUNNING,   /* running here, now */
    BATCH_DONE,      /* OUTDIR/NAME written */
    BATCH_FAILED,    /* ran and failed: error says why */
    BATCH_SUBMITTED, /* handed to Slurm (slurm_task) */
} batch_state;

typedef struct batch_job {
    char name[256];    /* output folder name under OUTDIR, unique in the batch */
    char input[4096];  /* absolute path of the .mat file or problem folder */
    batch_state state;
    double seconds;    /* wall time of the last run, 0 if none */
    double psnr;       /* mean PSNR (peak = frame max) of the first snapshot when the truth is known, else NaN */
    int attempts;
    char error[512];   /* the last line the failed run printed on stderr */
    char slurm_task[64]; /* "JOBID_INDEX" once submitted */
} batch_job;

typedef struct batch {
    char outdir[4096];   /* absolute */
    char bin[4096];      /* the scicap executable the jobs run */
    char **recon_args;   /* options for every scicap recon (owned, NULL-terminated) */
    int nrecon_args;
    batch_job *jobs;     /* owned */
    int njobs, capjobs;
    char slurm_job[64];  /* the last array job submitted, "" if none */
} batch;

#define BATCH_STATE_DIR ".batch"

/* Inputs to jobs (appended to b->jobs, skipping inputs already there): a .mat file, a problem folder (has
 * problem.json), a folder of those (each .mat and each problem folder inside, one level), a shell glob (expanded
 * here, for quoted patterns and Slurm), or a capture id of scicapd's store (cNNNNNN: STORE/captures/ID; store
 * NULL: $SCICAP_STORE, else /var/lib/scicapd). -ENOENT naming an input that matches nothing. */
int batch_add_inputs(batch *b, char *const *inputs, int n, const char *store, sci_error *err);

/* OUTDIR/.batch/state.json: load (1 when there is none yet, b untouched), save (atomically). */
int batch_state_load(batch *b, sci_error *err);
int batch_state_save(const batch *b, sci_error *err);
/* Fold in what Slurm tasks recorded (OUTDIR/.batch/tasks/NAME.json). */
void batch_state_merge_tasks(batch *b);
/* Replace the recon options (copied). */
int batch_set_recon_args(batch *b, char *const *args, int n, sci_error *err);
void batch_free(batch *b);

/* Is the job's output there (OUTDIR/NAME)? Also refreshes its PSNR from result.json and marks it DONE. */
int batch_job_finished(const batch *b, batch_job *j);
/* Remove OUTDIR/NAME.tmp-PID folders left by a scicap recon that was killed (its process is gone). */
void batch_job_clean_staging(const batch *b, const batch_job *j);
/* "OUTDIR/.batch/<rel>" into buf (mkdir -p of OUTDIR/.batch and its logs, tasks folders). */
int batch_path(const batch *b, char *buf, size_t n, const char *rel, sci_error *err);
/* The argv of the job's scicap recon (malloc'd array of borrowed and malloc'd strings; free with
 * batch_argv_free). */
char **batch_job_argv(const batch *b, const batch_job *j);
void batch_argv_free(char **argv);

/* Run the unfinished jobs here, `parallel` at a time, with a progress line per job and an overall one on stderr
 * and the summary table on stdout. 0 when every job is done, 1 when some failed, or 128 + the signal (SIGINT,
 * SIGTERM, SIGHUP, SIGQUIT) that interrupted it (the children were stopped; the state saved): apart from 1, since
 * SIGHUP is 1. */
int batch_run_local(batch *b, int parallel, int quiet);
/* Print the summary table of every job to stdout. */
void batch_print_summary(const batch *b);

/* Slurm (cli/batch_slurm.c). Resources: what the method's rows of bench/results.csv measured, scaled to the
 * input's size, unless given (0: estimate). */
typedef struct batch_slurm_opts {
    int cpus;             /* per task; 0: 2 */
    long mem_mib;         /* per task; 0: estimated */
    long time_min;        /* per task; 0: estimated */
    int max_parallel;     /* %N on the array; 0: no limit */
    const char *partition; /* NULL: the cluster's default */
    const char *results;  /* bench/results.csv to estimate from; NULL: looked up */
    int dry_run;          /* write the script, do not submit */
} batch_slurm_opts;

/* Submit the unfinished jobs that are not already queued or running as one array job. 0, or an error. */
int batch_slurm_submit(batch *b, const batch_slurm_opts *o, sci_error *err);
/* Print each job's state (from the outputs, the task records and squeue) and the counts. Returns 0 when every
 * job is done, 3 while some are queued or running, 1 otherwise (failed or not finished, nothing queued). */
int batch_slurm_status(batch *b);
/* Inside an array task: run job `name` (stdout and stderr are Slurm's log) and record the outcome in
 * OUTDIR/.batch/tasks/NAME.json. The exit status of scicap recon. */
int batch_task_run(batch *b, const char *name);

/* Run one job as a child with stdout to `log_fd` (-1: inherit) and stderr to `err_fd` (-1: inherit); returns
 * the pid or -errno. */
int batch_job_spawn(const batch *b, const batch_job *j, int log_fd, int err_fd, int threads);

#endif
