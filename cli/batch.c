/* scicap batch — many reconstructions: inputs (files, folders, globs, capture ids) to jobs, each run as
 * `scicap recon INPUT -o OUTDIR/NAME` in a child process, here (with progress and a summary) or as a Slurm array
 * job; resumable: a re-run runs only what has not finished (cli/batch.h). */
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <jansson.h>

#include "base/clock.h"
#include "base/json.h"
#include "cli/batch.h"
#include "cli/commands.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: scicap batch [OPTIONS] INPUT... -o OUTDIR [-- RECON OPTIONS]\n"
            "       scicap batch -o OUTDIR [OPTIONS]            (again: only what has not finished)\n"
            "       scicap batch --slurm [OPTIONS] [INPUT...] -o OUTDIR [-- RECON OPTIONS]\n"
            "       scicap batch --status OUTDIR\n"
            "\n"
            "Reconstruct many inputs, each with 'scicap recon INPUT -o OUTDIR/NAME RECON OPTIONS' in its own process,\n"
            "so one failure stops only its job. INPUT: a .mat file, a problem folder, a folder of those, a glob\n"
            "(quoted: expanded here) or a capture id of scicapd's store (c000012). NAME is the input's name (file\n"
            "without .mat, folder, capture id). A progress line per job and an overall one go to stderr, a summary\n"
            "table to stdout. OUTDIR/.batch/ keeps the state: running it again (with or without the inputs) runs only\n"
            "the jobs whose OUTDIR/NAME is missing (failed, interrupted, new); OUTDIR/NAME appears only complete.\n"
            "\n"
            "  -o, --output DIR       the batch's folder (required)\n"
            "  -m, --method NAME      the method for every job (scicap recon --method)\n"
            "      --preset P         fast, balanced or best (scicap recon --preset)\n"
            "  -P, --parallel N       jobs at once here (default 1); each gets cores/N OpenMP threads\n"
            "      --store DIR        scicapd's storage root for capture ids (default $SCICAP_STORE, else\n"
            "                         /var/lib/scicapd)\n"
            "  -q, --quiet            no per-job progress lines\n"
            "  Slurm:\n"
            "      --slurm            write OUTDIR/.batch/slurm-N.sh, an sbatch array job with one task per job that\n"
            "                         has not finished and is not queued or running, and submit it (sbatch)\n"
            "      --status           each job's state (output, task record, squeue) and the counts; exit 0 all\n"
            "                         done, 3 some queued or running, 1 otherwise\n"
            "      --cpus N           CPUs per task (default 2)\n"
            "      --mem MIB          memory per task (default: the method's largest peak RSS in bench/results.csv,\n"
            "                         scaled to the input's size, x1.5, at least 512)\n"
            "      --time MIN         time limit per task (default: the method's slowest time per voxel there, x4,\n"
            "                         at least 5 min)\n"
            "      --partition P      the partition (default: the cluster's)\n"
            "      --array-limit N    at most N tasks at once (sbatch --array=...%%N)\n"
            "      --results FILE     bench/results.csv to estimate from (default: beside the program, installed,\n"
            "                         or ./bench/results.csv)\n"
            "      --dry-run          write the script, do not submit it\n"
            "      --task NAME        run the one job NAME of OUTDIR (what each array task of the script runs)\n"
            "  -h, --help             this text\n"
            "\n"
            "'scicap recon' given several inputs runs this with its options. Exit status: 0 every job done, 1 some\n"
            "failed, 2 usage; interrupted (SIGINT, SIGTERM, SIGHUP, SIGQUIT): the jobs are stopped, the state kept, and\n"
            "it dies of the signal.\n");
}

static volatile sig_atomic_t stop_signal;

static void on_signal(int sig)
{
    stop_signal = sig;
}

typedef struct slot {
    pid_t pid;     /* 0: free */
    int job;
    int idx;       /* the job's place in this run's order, shown as [idx/N name] */
    int errfd;     /* the child's stderr, -1 once at EOF */
    char buf[2048];
    size_t len;
    char last[512]; /* last non-empty line */
    int64_t t0_ns;
    int signaled;  /* the stop was passed on to it */
} slot;

/* After a stop, how long a child gets to end on its own: Ctrl-C on a terminal reaches it directly, and scicap recon
 * dies at once on a second signal (its handler is one-shot), which would leave its staging folder behind. */
#define STOP_GRACE_NS 1500000000LL

int batch_job_spawn(const batch *b, const batch_job *j, int log_fd, int err_fd, int threads)
{
    char **argv = batch_job_argv(b, j);
    if (!argv)
        return -ENOMEM;
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        int e = -errno;
        batch_argv_free(argv);
        return e;
    }
    if (pid == 0) {
        if (log_fd >= 0)
            dup2(log_fd, 1);
        if (err_fd >= 0)
            dup2(err_fd, 2);
        if (threads > 0 && !getenv("OMP_NUM_THREADS")) {
            char t[16];
            snprintf(t, sizeof t, "%d", threads);
            setenv("OMP_NUM_THREADS", t, 1);
        }
        signal(SIGINT, SIG_DFL);
        signal(SIGTERM, SIG_DFL);
        signal(SIGHUP, SIG_DFL);
        signal(SIGQUIT, SIG_DFL);
        execv(argv[0], argv);
        fprintf(stderr, "scicap batch: cannot run %s: %s\n", argv[0], strerror(errno));
        _exit(127);
    }
    batch_argv_free(argv);
    return pid;
}

/* Read what the child printed on stderr; complete lines are shown prefixed with [idx/N name] (or [name] when
 * s->idx is 0) and the last one kept. Returns 0 at EOF. */
static int slot_read(slot *s, const batch *b, int quiet)
{
    ssize_t n = read(s->errfd, s->buf + s->len, sizeof s->buf - 1 - s->len);
    if (n < 0 && errno == EINTR)
        return 1;
    const int eof = n <= 0;
    if (n > 0)
        s->len += (size_t)n;
    s->buf[s->len] = 0;
    char *start = s->buf, *nl;
    while ((nl = strchr(start, '\n')) || (eof && *start) || (s->len == sizeof s->buf - 1 && start == s->buf)) {
        if (nl)
            *nl = 0;
        char *line = start;
        for (char *cr; (cr = strrchr(line, '\r'));) /* a TTY-style redraw: keep the newest text */
            line = cr + 1;
        if (*line) {
            snprintf(s->last, sizeof s->last, "%s", line);
            if (!quiet && s->idx <= 0)
                fprintf(stderr, "  [%s] %s\n", b->jobs[s->job].name, line);
            else if (!quiet)
                fprintf(stderr, "  [%d/%d %s] %s\n", s->idx, b->njobs, b->jobs[s->job].name, line);
        }
        start = nl ? nl + 1 : s->buf + s->len;
        if (!nl)
            break;
    }
    s->len = (size_t)(s->buf + s->len - start);
    memmove(s->buf, start, s->len);
    return !eof;
}

static void fmt_duration(char *buf, size_t n, double s)
{
    if (s < 60)
        snprintf(buf, n, "%.1f s", s);
    else if (s < 3600)
        snprintf(buf, n, "%d:%02d", (int)s / 60, (int)s % 60);
    else
        snprintf(buf, n, "%d:%02d:%02d", (int)s / 3600, (int)s / 60 % 60, (int)s % 60);
}

static void finish_slot(batch *b, slot *s, int status)
{
    const int idx = s->idx;
    batch_job *j = &b->jobs[s->job];
    j->seconds = sci_clock_s(s->t0_ns, sci_clock_mono_ns());
    char t[32];
    fmt_duration(t, sizeof t, j->seconds);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0 && batch_job_finished(b, j)) {
        if (isnan(j->psnr))
            fprintf(stderr, "[%d/%d %s] done in %s -> %s/%s\n", idx, b->njobs, j->name, t, b->outdir, j->name);
        else
            fprintf(stderr, "[%d/%d %s] done in %s, %.2f dB -> %s/%s\n", idx, b->njobs, j->name, t, j->psnr,
                    b->outdir, j->name);
    } else {
        j->state = BATCH_FAILED;
        if (WIFSIGNALED(status))
            snprintf(j->error, sizeof j->error, "killed by signal %d%s%s", WTERMSIG(status), s->last[0] ? ": " : "",
                     s->last);
        else
            snprintf(j->error, sizeof j->error, "%s", s->last[0] ? s->last : "failed without a message");
        fprintf(stderr, "[%d/%d %s] FAILED after %s: %s\n", idx, b->njobs, j->name, t, j->error);
    }
    s->pid = 0;
}

/* One local run's bookkeeping, shared by batch_run_local's steps. todo and slots are owned. err is one buffer for
 * the whole run: a start that fails names its message when one is there. */
typedef struct batch_local {
    batch *b;
    int parallel, quiet, threads;
    int *todo, ntodo, finished; /* the jobs to run, in order; how many had finished before */
    slot *slots;                /* parallel of them */
    int64_t t0, stop_ns;
    int next, running, ran, failed;
    double ran_s;               /* the finished jobs' seconds, for the estimate */
    sci_error err;
} batch_local;

/* Starts the next job of todo in a free slot (a failure to start counts as ran and failed). */
static void batch_local_start_next(batch_local *L)
{
    batch *b = L->b;
    slot *s = NULL;
    for (int k = 0; k < L->parallel && !s; k++)
        if (!L->slots[k].pid)
            s = &L->slots[k];
    batch_job *j = &b->jobs[L->todo[L->next]];
    char logp[PATH_MAX + 300], rel[300];
    snprintf(rel, sizeof rel, "logs/%s.log", j->name);
    int fds[2] = {-1, -1}, logfd = -1;
    if (batch_path(b, logp, sizeof logp, rel, &L->err) == 0)
        logfd = open(logp, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (logfd < 0 || pipe2(fds, O_CLOEXEC) != 0) {
        fprintf(stderr, "scicap batch: %s: %s\n", j->name, L->err.msg[0] ? L->err.msg : strerror(errno));
        if (logfd >= 0)
            close(logfd);
        j->state = BATCH_FAILED;
        snprintf(j->error, sizeof j->error, "could not start: %s", strerror(errno));
        L->next++, L->ran++, L->failed++;
        return;
    }
    batch_job_clean_staging(b, j);
    memset(s, 0, sizeof *s);
    s->job = L->todo[L->next++];
    s->t0_ns = sci_clock_mono_ns();
    int pid = batch_job_spawn(b, j, logfd, fds[1], L->threads);
    close(logfd);
    close(fds[1]);
    if (pid < 0) {
        close(fds[0]);
        j->state = BATCH_FAILED;
        snprintf(j->error, sizeof j->error, "could not start: %s", strerror(-pid));
        fprintf(stderr, "scicap batch: %s: %s\n", j->name, j->error);
        L->ran++, L->failed++;
        return;
    }
    s->pid = pid, s->errfd = fds[0], s->idx = L->finished + L->ran + L->running + 1;
    j->state = BATCH_RUNNING;
    j->attempts++;
    L->running++;
    if (!L->quiet)
        fprintf(stderr, "[%d/%d %s] started: %s\n", s->idx, b->njobs, j->name, j->input);
    batch_state_save(b, &L->err);
}

/* After a stop signal, passes SIGTERM on to each child still running once its grace time is over. */
static void batch_local_pass_stop(batch_local *L)
{
    if (!L->stop_ns)
        L->stop_ns = sci_clock_mono_ns();
    for (int k = 0; k < L->parallel; k++)
        if (L->slots[k].pid && !L->slots[k].signaled && sci_clock_mono_ns() - L->stop_ns > STOP_GRACE_NS) {
            kill(L->slots[k].pid, SIGTERM);
            L->slots[k].signaled = 1;
        }
}

/* Waits up to 0.5 s for the children's stderr and reads what came; closes each at EOF. */
static void batch_local_read(batch_local *L)
{
    struct pollfd pf[64];
    int np = 0, map[64];
    for (int k = 0; k < L->parallel && np < 64; k++)
        if (L->slots[k].pid && L->slots[k].errfd >= 0)
            pf[np] = (struct pollfd){.fd = L->slots[k].errfd, .events = POLLIN}, map[np++] = k;
    if (np)
        poll(pf, (nfds_t)np, 500);
    else
        usleep(50000);
    for (int p = 0; p < np; p++)
        if (pf[p].revents) {
            slot *s = &L->slots[map[p]];
            if (!slot_read(s, L->b, L->quiet)) {
                close(s->errfd);
                s->errfd = -1;
            }
        }
}

/* Reaps each child whose stderr is closed and has ended: its result, the saved state and the overall line. */
static void batch_local_reap(batch_local *L)
{
    batch *b = L->b;
    for (int k = 0; k < L->parallel; k++) {
        slot *s = &L->slots[k];
        int status;
        if (!s->pid || s->errfd >= 0 || waitpid(s->pid, &status, WNOHANG) != s->pid)
            continue;
        L->running--;
        if (stop_signal) {
            b->jobs[s->job].state = BATCH_PENDING; /* interrupted: runs again next time */
            s->pid = 0;
            continue;
        }
        L->ran++;
        finish_slot(b, s, status);
        L->ran_s += b->jobs[s->job].seconds;
        L->failed += b->jobs[s->job].state == BATCH_FAILED;
        batch_state_save(b, &L->err);
        char el[32], eta[32];
        fmt_duration(el, sizeof el, sci_clock_s(L->t0, sci_clock_mono_ns()));
        fmt_duration(eta, sizeof eta, L->ran ? L->ran_s / L->ran * (L->ntodo - L->ran) / L->parallel : 0);
        fprintf(stderr, "batch: %d/%d finished: %d done, %d failed; %d running; %s elapsed%s%s\n",
                L->finished + L->ran, b->njobs, L->finished + L->ran - L->failed, L->failed, L->running, el,
                L->ntodo - L->ran > 0 ? ", about " : "", L->ntodo - L->ran > 0 ? eta : "");
    }
}

/* The jobs not finished into L->todo, and the opening line. */
static void batch_local_plan(batch_local *L)
{
    batch *b = L->b;
    for (int i = 0; i < b->njobs; i++)
        if (batch_job_finished(b, &b->jobs[i]))
            L->finished++;
        else
            L->todo[L->ntodo++] = i;
    fprintf(stderr, "batch: %d job(s), %d already done, %d to run", b->njobs, L->finished, L->ntodo);
    if (L->parallel > 1)
        fprintf(stderr, ", %d at once with %d thread(s) each", L->parallel, L->threads);
    fprintf(stderr, "\n");
}

int batch_run_local(batch *b, int parallel, int quiet)
{
    batch_local L = {.b = b, .quiet = quiet};
    if (parallel < 1)
        parallel = 1;
    L.parallel = parallel;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    L.threads = parallel > 1 ? (int)(cores / parallel > 0 ? cores / parallel : 1) : 0;
    L.todo = malloc((size_t)(b->njobs > 0 ? b->njobs : 1) * sizeof *L.todo);
    L.slots = calloc((size_t)parallel, sizeof *L.slots);
    if (!L.todo || !L.slots) {
        free(L.todo), free(L.slots);
        fprintf(stderr, "scicap batch: out of memory\n");
        return 1;
    }
    batch_local_plan(&L);
    struct sigaction sa = {.sa_handler = on_signal}, old_int, old_term, old_hup, old_quit;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old_int);
    sigaction(SIGTERM, &sa, &old_term);
    sigaction(SIGHUP, &sa, &old_hup); /* a closed terminal or Ctrl-\ stops the jobs as Ctrl-C does */
    sigaction(SIGQUIT, &sa, &old_quit);
    L.t0 = sci_clock_mono_ns();
    while (L.next < L.ntodo || L.running) {
        while (!stop_signal && L.next < L.ntodo && L.running < parallel)
            batch_local_start_next(&L);
        if (stop_signal && L.running)
            batch_local_pass_stop(&L);
        if (!L.running)
            break;
        batch_local_read(&L);
        batch_local_reap(&L);
    }
    sigaction(SIGINT, &old_int, NULL);
    sigaction(SIGTERM, &old_term, NULL);
    sigaction(SIGHUP, &old_hup, NULL);
    sigaction(SIGQUIT, &old_quit, NULL);
    batch_state_save(b, &L.err);
    free(L.todo);
    free(L.slots);
    batch_print_summary(b);
    if (stop_signal) {
        fprintf(stderr, "scicap batch: interrupted; the state is in %s/%s (run again to go on)\n", b->outdir,
                BATCH_STATE_DIR);
        return 128 + stop_signal;
    }
    for (int i = 0; i < b->njobs; i++)
        if (b->jobs[i].state != BATCH_DONE)
            return 1;
    return 0;
}

void batch_print_summary(const batch *b)
{
    static const char *const names[] = {"pending", "running", "done", "FAILED", "submitted"};
    int w = 4, done = 0, bad = 0;
    for (int i = 0; i < b->njobs; i++)
        if ((int)strlen(b->jobs[i].name) > w)
            w = (int)strlen(b->jobs[i].name);
    if (w > 40)
        w = 40;
    printf("%-*s  %-9s  %9s  %8s  %s\n", w, "job", "state", "time", "PSNR dB", "output / error");
    for (int i = 0; i < b->njobs; i++) {
        const batch_job *j = &b->jobs[i];
        char t[32] = "-", ps[16] = "-";
        if (j->seconds > 0)
            fmt_duration(t, sizeof t, j->seconds);
        if (!isnan(j->psnr))
            snprintf(ps, sizeof ps, "%.2f", j->psnr);
        char out[PATH_MAX + 300];
        if (j->state == BATCH_DONE)
            snprintf(out, sizeof out, "%s/%s", b->outdir, j->name);
        else
            snprintf(out, sizeof out, "%s", j->error[0] ? j->error : j->slurm_task[0] ? j->slurm_task : "");
        printf("%-*s  %-9s  %9s  %8s  %s\n", w, j->name, names[j->state], t, ps, out);
        done += j->state == BATCH_DONE;
        bad += j->state == BATCH_FAILED;
    }
    printf("%d job(s): %d done, %d failed, %d not finished\n", b->njobs, done, bad, b->njobs - done - bad);
    fflush(stdout);
}

int batch_task_run(batch *b, const char *name)
{
    batch_job *j = NULL;
    for (int i = 0; i < b->njobs && !j; i++)
        if (strcmp(b->jobs[i].name, name) == 0)
            j = &b->jobs[i];
    if (!j) {
        fprintf(stderr, "scicap batch: --task %s: no such job in %s/%s/state.json\n", name, b->outdir,
                BATCH_STATE_DIR);
        return 2;
    }
    const char *aj = getenv("SLURM_ARRAY_JOB_ID"), *at = getenv("SLURM_ARRAY_TASK_ID");
    char task[64] = "", host[256] = "";
    if (aj && at)
        snprintf(task, sizeof task, "%s_%s", aj, at);
    gethostname(host, sizeof host - 1);
    fprintf(stderr, "scicap batch: task %s on %s: %s -> %s/%s\n", task[0] ? task : "(no Slurm)", host, j->input,
            b->outdir, j->name);
    struct sigaction sa = {.sa_handler = on_signal}, old_term, old_int, old_hup, old_quit;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGTERM, &sa, &old_term);
    sigaction(SIGINT, &sa, &old_int);
    sigaction(SIGHUP, &sa, &old_hup);
    sigaction(SIGQUIT, &sa, &old_quit);
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) {
        perror("scicap batch: pipe");
        return 1;
    }
    batch_job_clean_staging(b, j);
    slot s = {.job = (int)(j - b->jobs), .t0_ns = sci_clock_mono_ns()};
    int pid = batch_job_spawn(b, j, -1, fds[1], 0);
    close(fds[1]);
    if (pid < 0) {
        fprintf(stderr, "scicap batch: cannot start scicap recon: %s\n", strerror(-pid));
        return 1;
    }
    s.pid = pid, s.errfd = fds[0];
    int forwarded = 0, status = 0;
    while (s.errfd >= 0) {
        if (stop_signal && !forwarded) {
            kill(pid, SIGTERM); /* scancel: the recon removes what it had begun and publishes nothing */
            forwarded = 1;
        }
        struct pollfd pf = {.fd = s.errfd, .events = POLLIN};
        if (poll(&pf, 1, 500) > 0 && !slot_read(&s, b, 0)) { /* the lines go on to the Slurm log */
            close(s.errfd);
            s.errfd = -1;
        }
    }
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
        ;
    j->seconds = sci_clock_s(s.t0_ns, sci_clock_mono_ns());
    const int ok = WIFEXITED(status) && WEXITSTATUS(status) == 0 && batch_job_finished(b, j);
    if (!ok && WIFSIGNALED(status))
        snprintf(j->error, sizeof j->error, "killed by signal %d", WTERMSIG(status));
    else if (!ok)
        snprintf(j->error, sizeof j->error, "%s", s.last[0] ? s.last : "failed without a message");
    json_t *rec = json_pack("{s:s, s:s, s:s, s:f, s:i, s:s, s:s}", "name", j->name, "state", ok ? "done" : "failed",
                            "slurm_task", task, "seconds", j->seconds, "exit",
                            WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), "host", host, "error",
                            ok ? "" : j->error);
    if (rec)
        json_object_set_new(rec, "psnr_db", ok && !isnan(j->psnr) ? json_real(j->psnr) : json_null());
    char path[PATH_MAX + 300], rel[300];
    sci_error err = {0};
    snprintf(rel, sizeof rel, "tasks/%s.json", j->name);
    if (rec && batch_path(b, path, sizeof path, rel, &err) == 0)
        sci_json_write_atomic(path, rec, JSON_INDENT(1), 0644, 0, &err); /* the state file still says it ran */
    json_decref(rec);
    fprintf(stderr, "scicap batch: task %s: %s in %.1f s%s%s\n", task, ok ? "done" : "FAILED", j->seconds,
            ok ? "" : ": ", ok ? "" : j->error);
    sigaction(SIGTERM, &old_term, NULL);
    sigaction(SIGINT, &old_int, NULL);
    sigaction(SIGHUP, &old_hup, NULL);
    sigaction(SIGQUIT, &old_quit, NULL);
    return ok ? 0 : 1;
}

/* Options common to `scicap batch` and `scicap recon` with several inputs: after the inputs are known. */
static int batch_main_run(batch *b, char *const *inputs, int ninputs, const char *store, int parallel, int quiet,
                          int slurm, const batch_slurm_opts *so)
{
    sci_error err = {0};
    if (mkdir(b->outdir, 0755) != 0 && errno != EEXIST) {
        fprintf(stderr, "scicap batch: %s: %s\n", b->outdir, strerror(errno));
        return 1;
    }
    if (batch_add_inputs(b, inputs, ninputs, store, &err) < 0) {
        fprintf(stderr, "scicap batch: %s\n", err.msg);
        return 2;
    }
    if (b->njobs == 0) {
        fprintf(stderr, "scicap batch: no inputs, and %s holds no batch to go on with\n", b->outdir);
        return 2;
    }
    if (batch_state_save(b, &err) < 0) {
        fprintf(stderr, "scicap batch: %s\n", err.msg);
        return 1;
    }
    if (slurm) {
        batch_state_merge_tasks(b);
        int rc = batch_slurm_submit(b, so, &err);
        if (rc < 0)
            fprintf(stderr, "scicap batch: %s\n", err.msg);
        return rc < 0 ? 1 : 0;
    }
    int rc = batch_run_local(b, parallel, quiet);
    if (rc > 128) { /* interrupted: die of the signal, as the shell expects */
        batch_free(b);
        fflush(NULL);
        signal(rc - 128, SIG_DFL);
        raise(rc - 128);
    }
    return rc;
}

static int parse_long(const char *s, const char *opt, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || *end || end == s || v < lo || v > hi) {
        fprintf(stderr, "scicap batch: %s wants an integer in [%ld, %ld], got '%s'\n", opt, lo, hi, s);
        return -1;
    }
    *out = v;
    return 0;
}

/* The inputs, checked before OUTDIR is made: a bad input leaves no folder behind, and its error comes before
 * any about OUTDIR. 0, or 2 (usage) after saying why. */
static int batch_check_inputs(char *const *inputs, int n, const char *store, const char *who)
{
    if (n == 0)
        return 0;
    batch t;
    memset(&t, 0, sizeof t);
    sci_error err = {0};
    int rc = batch_add_inputs(&t, inputs, n, store, &err);
    if (rc < 0)
        fprintf(stderr, "%s: %s\n", who, err.msg);
    batch_free(&t);
    return rc < 0 ? 2 : 0;
}

/* b->outdir and b->bin from `out` and /proc/self/exe. */
static int batch_init(batch *b, const char *out)
{
    memset(b, 0, sizeof *b);
    char abs[PATH_MAX];
    if (mkdir(out, 0755) != 0 && errno != EEXIST) {
        fprintf(stderr, "scicap batch: %s: %s\n", out, strerror(errno));
        return -1;
    }
    if (!realpath(out, abs)) {
        fprintf(stderr, "scicap batch: %s: %s\n", out, strerror(errno));
        return -1;
    }
    snprintf(b->outdir, sizeof b->outdir, "%s", abs);
    ssize_t n = readlink("/proc/self/exe", b->bin, sizeof b->bin - 1);
    if (n <= 0) {
        fprintf(stderr, "scicap batch: cannot find the scicap executable: %s\n", strerror(errno));
        return -1;
    }
    b->bin[n] = 0;
    return 0;
}

/* scicap batch's command line, as parsed. The recon options are argv after dashdash. */
typedef struct batch_cli {
    int dashdash;  /* index of "--" in argv, argc without one */
    const char *out, *method, *preset, *store, *task;
    int quiet, slurm, status;
    long parallel;
    batch_slurm_opts so;
} batch_cli;

/* Parses argv up to "--" into o. Returns -1 to go on, else the exit code (0 after --help, 2 on a bad option). */
static int batch_cli_parse(batch_cli *o, int argc, char **argv)
{
    enum { O_PRESET = 256, O_STORE, O_SLURM, O_STATUS, O_CPUS, O_MEM, O_TIME, O_PARTITION, O_LIMIT, O_RESULTS,
           O_DRY, O_TASK };
    static const struct option longopts[] = {
        {"output", required_argument, 0, 'o'},      {"method", required_argument, 0, 'm'},
        {"preset", required_argument, 0, O_PRESET}, {"parallel", required_argument, 0, 'P'},
        {"store", required_argument, 0, O_STORE},   {"quiet", no_argument, 0, 'q'},
        {"slurm", no_argument, 0, O_SLURM},         {"status", no_argument, 0, O_STATUS},
        {"cpus", required_argument, 0, O_CPUS},     {"mem", required_argument, 0, O_MEM},
        {"time", required_argument, 0, O_TIME},     {"partition", required_argument, 0, O_PARTITION},
        {"array-limit", required_argument, 0, O_LIMIT}, {"results", required_argument, 0, O_RESULTS},
        {"dry-run", no_argument, 0, O_DRY},         {"task", required_argument, 0, O_TASK},
        {"help", no_argument, 0, 'h'},              {0, 0, 0, 0},
    };
    o->dashdash = argc;
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "--") == 0) {
            o->dashdash = i;
            break;
        }
    o->parallel = 1;
    int c;
    long v;
    optind = 1;
    while ((c = getopt_long(o->dashdash, argv, "o:m:P:qh", longopts, NULL)) != -1) {
        switch (c) {
        case 'o': o->out = optarg; break;
        case 'm': o->method = optarg; break;
        case O_PRESET: o->preset = optarg; break;
        case 'P':
            if (parse_long(optarg, "--parallel", 1, 256, &o->parallel) < 0)
                return 2;
            break;
        case O_STORE: o->store = optarg; break;
        case 'q': o->quiet = 1; break;
        case O_SLURM: o->slurm = 1; break;
        case O_STATUS: o->status = 1; break;
        case O_CPUS:
            if (parse_long(optarg, "--cpus", 1, 1024, &v) < 0)
                return 2;
            o->so.cpus = (int)v;
            break;
        case O_MEM:
            if (parse_long(optarg, "--mem", 16, 1L << 30, &o->so.mem_mib) < 0)
                return 2;
            break;
        case O_TIME:
            if (parse_long(optarg, "--time", 1, 1L << 24, &o->so.time_min) < 0)
                return 2;
            break;
        case O_PARTITION: o->so.partition = optarg; break;
        case O_LIMIT:
            if (parse_long(optarg, "--array-limit", 1, 1L << 20, &v) < 0)
                return 2;
            o->so.max_parallel = (int)v;
            break;
        case O_RESULTS: o->so.results = optarg; break;
        case O_DRY: o->so.dry_run = 1; break;
        case O_TASK: o->task = optarg; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    return -1;
}

/* The recon options: the ones given (method and preset first), else the ones the batch was started with.
 * loaded: batch_state_load's result (0: a batch was there). Returns 0, or 1 after a message. */
static int batch_cli_set_recon_args(const batch_cli *o, batch *b, int loaded, int argc, char **argv, sci_error *err)
{
    int nrargs = argc - o->dashdash - (o->dashdash < argc);
    if (!o->method && !o->preset && nrargs <= 0)
        return 0;
    char **a = calloc((size_t)nrargs + 5, sizeof *a);
    int n = 0;
    if (!a)
        return 1;
    if (o->method)
        a[n++] = (char *)"--method", a[n++] = (char *)o->method;
    if (o->preset)
        a[n++] = (char *)"--preset", a[n++] = (char *)o->preset;
    for (int i = 0; i < nrargs; i++)
        a[n++] = argv[o->dashdash + 1 + i];
    if (loaded == 0 && b->nrecon_args)
        fprintf(stderr, "scicap batch: the options differ from the batch's first run? the jobs still to run "
                        "use the ones given now\n");
    int rc = batch_set_recon_args(b, a, n, err);
    free(a);
    if (rc < 0) {
        fprintf(stderr, "scicap batch: %s\n", err->msg);
        return 1;
    }
    return 0;
}

/* --status and --task on a loaded batch. loaded: batch_state_load's result (1: none there). */
static int batch_cli_status_or_task(const batch_cli *o, batch *b, int loaded)
{
    if (loaded == 1) {
        fprintf(stderr, "scicap batch: %s holds no batch (%s/state.json)\n", b->outdir, BATCH_STATE_DIR);
        return 2;
    }
    batch_state_merge_tasks(b);
    return o->task ? batch_task_run(b, o->task) : batch_slurm_status(b);
}

int cli_batch_main(int argc, char **argv)
{
    batch_cli o = {0};
    int rc = batch_cli_parse(&o, argc, argv);
    if (rc >= 0)
        return rc;
    char **inputs = argv + optind;
    int ninputs = o.dashdash - optind;
    if ((o.status || o.task) && !o.out && ninputs == 1) /* --status OUTDIR, --task NAME OUTDIR */
        o.out = inputs[0], ninputs = 0;
    if (!o.out) {
        fprintf(stderr, "scicap batch: -o OUTDIR is required\n");
        usage(stderr);
        return 2;
    }
    batch b;
    if ((o.status || o.task) && access(o.out, F_OK) != 0) {
        fprintf(stderr, "scicap batch: %s: no such batch folder\n", o.out);
        return 2;
    }
    if (!o.status && !o.task && batch_check_inputs(inputs, ninputs, o.store, "scicap batch") != 0)
        return 2;
    if (batch_init(&b, o.out) < 0)
        return 1;
    sci_error err = {0};
    rc = batch_state_load(&b, &err);
    if (rc < 0) {
        fprintf(stderr, "scicap batch: %s\n", err.msg);
        batch_free(&b);
        return 1;
    }
    if (o.status || o.task)
        rc = batch_cli_status_or_task(&o, &b, rc);
    else if (batch_cli_set_recon_args(&o, &b, rc, argc, argv, &err) != 0)
        rc = 1;
    else
        rc = batch_main_run(&b, inputs, ninputs, o.store, (int)o.parallel, o.quiet, o.slurm, &o.so);
    batch_free(&b);
    return rc;
}

int cli_batch_is_many(const char *input)
{
    struct stat st;
    char pj[PATH_MAX + 16];
    if (stat(input, &st) != 0)
        return strpbrk(input, "*?[") != NULL; /* a glob the shell did not expand (quoted) */
    snprintf(pj, sizeof pj, "%s/problem.json", input);
    return S_ISDIR(st.st_mode) && access(pj, F_OK) != 0; /* a folder of inputs, not a problem folder */
}

int cli_batch_recon(int nopts, char **opts, int ninputs, char **inputs)
{
    /* scicap recon's options minus -o OUT (the batch's folder); the rest goes to every job's scicap recon. */
    const char *out = NULL;
    char **a = calloc((size_t)nopts + 1, sizeof *a);
    int n = 0;
    if (!a)
        return 1;
    for (int i = 0; i < nopts; i++) {
        const char *o = opts[i];
        if ((strcmp(o, "-o") == 0 || strcmp(o, "--output") == 0) && i + 1 < nopts)
            out = opts[++i];
        else if (strncmp(o, "--output=", 9) == 0)
            out = o + 9;
        else if (strncmp(o, "-o", 2) == 0 && o[2])
            out = o + 2;
        else
            a[n++] = opts[i];
    }
    if (!out) {
        free(a);
        fprintf(stderr, "scicap recon: -o OUTDIR is required\n");
        return 2;
    }
    if (batch_check_inputs(inputs, ninputs, NULL, "scicap recon") != 0) {
        free(a);
        return 2;
    }
    batch b;
    sci_error err = {0};
    int rc = batch_init(&b, out) < 0 ? -1 : batch_state_load(&b, &err);
    if (rc >= 0)
        rc = batch_set_recon_args(&b, a, n, &err);
    free(a);
    if (rc < 0) {
        if (err.msg[0])
            fprintf(stderr, "scicap recon: %s\n", err.msg);
        batch_free(&b);
        return 1;
    }
    fprintf(stderr, "scicap recon: several inputs (%d argument(s)): a batch in %s as scicap batch (OUTDIR/NAME)\n",
            ninputs, b.outdir);
    rc = batch_main_run(&b, inputs, ninputs, NULL, 1, 0, 0, NULL);
    batch_free(&b);
    return rc;
}
