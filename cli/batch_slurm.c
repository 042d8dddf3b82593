/* cli/batch_slurm.c — a batch as a Slurm array job: the sbatch script (one task per unfinished job, resources
 * estimated from bench/results.csv), its submission, and the jobs' states from their outputs, the tasks' records
 * and squeue (batch.h). Slurm is driven through its commands (sbatch, squeue), as a user would. */
#include "cli/batch.h"

#include <errno.h>
#include <libgen.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "io/source.h"
#include "recon/solver.h"

/* The value after --method/-m and --preset in the recon options, or dflt. */
static const char *recon_opt(const batch *b, const char *longname, const char *shortname, const char *dflt)
{
    const char *v = dflt;
    size_t l = strlen(longname);
    for (int i = 0; i < b->nrecon_args; i++) {
        const char *a = b->recon_args[i];
        if ((strcmp(a, longname) == 0 || (shortname && strcmp(a, shortname) == 0)) && i + 1 < b->nrecon_args)
            v = b->recon_args[++i];
        else if (strncmp(a, longname, l) == 0 && a[l] == '=')
            v = a + l + 1;
    }
    return v;
}

/* The first readable results.csv: --results, $SCICAP_RESULTS, beside the program (the build tree's
 * bench/results.csv), the installed copy, ./bench/results.csv. */
static FILE *results_open(const batch *b, const char *given, char *used, size_t n)
{
    char beside[PATH_MAX];
    snprintf(beside, sizeof beside, "%s", b->bin);
    const char *cands[] = {given, getenv("SCICAP_RESULTS"), NULL, SCICAP_DATADIR "/results.csv",
                           "bench/results.csv"};
    char c2[PATH_MAX + 32];
    snprintf(c2, sizeof c2, "%s/../bench/results.csv", dirname(beside));
    cands[2] = c2;
    for (size_t i = 0; i < sizeof cands / sizeof cands[0]; i++) {
        if (!cands[i] || !cands[i][0])
            continue;
        FILE *f = fopen(cands[i], "r");
        if (f) {
            snprintf(used, n, "%s", cands[i]);
            return f;
        }
        if (i == 0)
            break; /* given and unreadable: say so rather than use another */
    }
    return NULL;
}

typedef struct estimate {
    double rss_mib;        /* largest peak RSS measured */
    double rss_voxels;     /* the size it was measured at */
    double s_per_voxel;    /* slowest wall time per voxel */
    int rows;
    char from[PATH_MAX];
} estimate;

/* Rows of `method` (those of `preset` when the file has some): the largest RSS and the slowest time per voxel. */
static void estimate_read(const batch *b, const char *given, const char *method, const char *preset, estimate *e)
{
    memset(e, 0, sizeof *e);
    FILE *f = results_open(b, given, e->from, sizeof e->from);
    if (!f)
        return;
    char line[4096], want[64];
    int col_m = -1, col_s = -1, col_w = -1, col_r = -1, col_v = -1;
    snprintf(want, sizeof want, "preset=%s", preset ? preset : "");
    for (int pass = 0; pass < 2 && e->rows == 0; pass++) {
        rewind(f);
        for (int ln = 0; fgets(line, sizeof line, f); ln++) {
            char *fld[32];
            int nf = 0;
            for (char *save, *t = strtok_r(line, ",\n", &save); t && nf < 32; t = strtok_r(NULL, ",\n", &save))
                fld[nf++] = t;
            if (ln == 0) {
                for (int i = 0; i < nf; i++) {
                    col_m = strcmp(fld[i], "method") == 0 ? i : col_m;
                    col_s = strcmp(fld[i], "setting") == 0 ? i : col_s;
                    col_w = strcmp(fld[i], "wall_s") == 0 ? i : col_w;
                    col_r = strcmp(fld[i], "peak_rss_mib") == 0 ? i : col_r;
                    col_v = strcmp(fld[i], "voxels") == 0 ? i : col_v;
                }
                if (col_m < 0 || col_s < 0 || col_w < 0 || col_r < 0 || col_v < 0)
                    break;
                continue;
            }
            if (nf <= col_m || nf <= col_s || nf <= col_w || nf <= col_r || nf <= col_v ||
                strcmp(fld[col_m], method) != 0 || (pass == 0 && (!preset || !strstr(fld[col_s], want))))
                continue;
            const double w = atof(fld[col_w]), r = atof(fld[col_r]), v = atof(fld[col_v]);
            if (!(v > 0))
                continue;
            if (r > e->rss_mib)
                e->rss_mib = r, e->rss_voxels = v;
            if (w / v > e->s_per_voxel)
                e->s_per_voxel = w / v;
            e->rows++;
        }
    }
    fclose(f);
}

/* 'text' for sh, with ' as '\'' */
static void sh_quote(FILE *f, const char *s)
{
    fputc('\'', f);
    for (; *s; s++)
        if (*s == '\'')
            fputs("'\\''", f);
        else
            fputc(*s, f);
    fputc('\'', f);
}

/* squeue's view of our array tasks: for each job, the state of its recorded task ("" if squeue does not list
 * it). Returns how many are listed, or -1 when squeue could not be asked. */
static int squeue_states(const batch *b, char (*states)[24])
{
    for (int i = 0; i < b->njobs; i++)
        states[i][0] = 0;
    FILE *p = popen("squeue --me -h -r -o '%i %T' 2>/dev/null", "r");
    if (!p)
        return -1;
    char line[256];
    int listed = 0;
    while (fgets(line, sizeof line, p)) {
        char id[64], st[32];
        if (sscanf(line, "%63s %31s", id, st) != 2)
            continue;
        for (int i = 0; i < b->njobs; i++)
            if (b->jobs[i].slurm_task[0] && strcmp(b->jobs[i].slurm_task, id) == 0) {
                snprintf(states[i], sizeof states[i], "%s", st);
                listed++;
            }
    }
    int rc = pclose(p);
    return rc == 0 ? listed : -1;
}

/* One submission's plan: the jobs to submit and the resources each task asks for. todo is owned. */
typedef struct slurm_plan {
    int *todo, ntodo;           /* indexes of the jobs neither finished nor queued */
    int done, inq;              /* finished; queued or running */
    int cpus;
    long mem, tmin;             /* MiB, minutes */
    char how[PATH_MAX + 256];   /* where mem and tmin came from, for the script and the message */
    char path[PATH_MAX + 100];  /* the script */
} slurm_plan;

/* The jobs neither finished nor queued (squeue) into p->todo. Returns 0 or -ENOMEM. */
static int batch_slurm_plan_jobs(const batch *b, slurm_plan *p, sci_error *err)
{
    char (*queued)[24] = calloc((size_t)(b->njobs ? b->njobs : 1), sizeof *queued);
    p->todo = calloc((size_t)(b->njobs ? b->njobs : 1), sizeof *p->todo);
    if (!queued || !p->todo) {
        free(queued), free(p->todo);
        p->todo = NULL;
        return sci_error_set(err, -ENOMEM, "out of memory");
    }
    squeue_states(b, queued);
    for (int i = 0; i < b->njobs; i++) {
        if (batch_job_finished(b, &b->jobs[i]))
            p->done++;
        else if (queued[i][0])
            p->inq++;
        else
            p->todo[p->ntodo++] = i;
    }
    free(queued);
    return 0;
}

/* Resources: the options given, else the method's measurements scaled to the largest input of this submission,
 * else defaults. */
static void batch_slurm_plan_resources(const batch *b, const batch_slurm_opts *o, slurm_plan *p)
{
    /* no --method: scicap recon's default, the table's first row */
    const char *method = recon_opt(b, "--method", "-m", solver_list(NULL)[0]->name), *preset = recon_opt(b, "--preset", NULL, NULL);
    estimate e;
    estimate_read(b, o ? o->results : NULL, method, preset, &e);
    double voxels = 0;
    for (int t = 0; t < p->ntodo; t++) {
        long long w, h, n, k;
        sci_error perr = {0};
        if (sci_source_probe(b->jobs[p->todo[t]].input, NULL, &w, &h, &n, &k, &perr) == 0 && w > 0 && h > 0)
            voxels = fmax(voxels, (double)w * (double)h * (double)(n > 0 ? n : 1) * (double)(k > 0 ? k : 1));
    }
    p->cpus = o && o->cpus ? o->cpus : 2;
    p->mem = o && o->mem_mib ? o->mem_mib : 0, p->tmin = o && o->time_min ? o->time_min : 0;
    if (e.rows) {
        if (!p->mem)
            p->mem = (long)ceil(fmax(512, 1.5 * e.rss_mib * fmax(1, voxels / e.rss_voxels)));
        if (!p->tmin)
            p->tmin = (long)ceil(fmax(5, 4 * e.s_per_voxel * voxels / 60));
        snprintf(p->how, sizeof p->how, "from %d row(s) of %s%s%s in %s: peak RSS %.0f MiB, %.3g s per voxel; inputs "
                 "up to %.0f voxels", e.rows, method, preset ? " preset " : "", preset ? preset : "", e.from, e.rss_mib,
                 e.s_per_voxel, voxels);
    } else {
        p->mem = p->mem ? p->mem : 2048;
        p->tmin = p->tmin ? p->tmin : 120;
        snprintf(p->how, sizeof p->how, "no measurement of %s found (bench/results.csv): defaults", method);
    }
}

/* The script, as the first free .batch/slurm-N.sh: one task per job, named in a case so a task never depends on
 * another's index. Returns 0 or -errno with err filled. */
static int batch_slurm_script_write(const batch *b, const batch_slurm_opts *o, slurm_plan *p, sci_error *err)
{
    char rel[64];
    for (int seq = 1;; seq++) {
        snprintf(rel, sizeof rel, "slurm-%d.sh", seq);
        int rc = batch_path(b, p->path, sizeof p->path, rel, err);
        if (rc < 0)
            return rc;
        if (access(p->path, F_OK) != 0)
            break;
    }
    FILE *f = fopen(p->path, "w");
    if (!f)
        return sci_error_set(err, -errno, "%s: %s", p->path, strerror(errno));
    fprintf(f, "#!/bin/sh\n# scicap batch --slurm: %d task(s) of %s\n# resources: %s\n", p->ntodo, b->outdir, p->how);
    fprintf(f, "#SBATCH --job-name=scicap-batch\n#SBATCH --array=0-%d", p->ntodo - 1);
    if (o && o->max_parallel)
        fprintf(f, "%%%d", o->max_parallel);
    fprintf(f, "\n#SBATCH --cpus-per-task=%d\n#SBATCH --mem=%ld\n#SBATCH --time=%ld\n", p->cpus, p->mem, p->tmin);
    fprintf(f, "#SBATCH --output=%s/%s/logs/slurm-%%A_%%a.log\n", b->outdir, BATCH_STATE_DIR);
    if (o && o->partition)
        fprintf(f, "#SBATCH --partition=%s\n", o->partition);
    fprintf(f, "export OMP_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-1}\"\ncase \"$SLURM_ARRAY_TASK_ID\" in\n");
    for (int t = 0; t < p->ntodo; t++) {
        fprintf(f, "%d) name=", t);
        sh_quote(f, b->jobs[p->todo[t]].name);
        fprintf(f, " ;;\n");
    }
    fprintf(f, "*) echo \"scicap batch: no job for task $SLURM_ARRAY_TASK_ID\" >&2; exit 2 ;;\nesac\nexec ");
    sh_quote(f, b->bin);
    fprintf(f, " batch --task \"$name\" ");
    sh_quote(f, b->outdir);
    fprintf(f, "\n");
    if (fclose(f) != 0)
        return sci_error_set(err, -EIO, "%s: write failed", p->path);
    return 0;
}

/* sbatch the script; id gets the array job's id. Returns 0 or -EIO with err filled. */
static int batch_slurm_sbatch(const slurm_plan *p, char *id, size_t idn, sci_error *err)
{
    char cmd[PATH_MAX + 64];
    snprintf(cmd, sizeof cmd, "sbatch --parsable '%s'", p->path);
    FILE *pp = popen(cmd, "r");
    id[0] = 0;
    if (!pp || !fgets(id, (int)idn, pp)) {
        if (pp)
            pclose(pp);
        return sci_error_set(err, -EIO, "sbatch %s failed (is Slurm there? its message is above)", p->path);
    }
    int prc = pclose(pp);
    id[strcspn(id, ";\n")] = 0; /* "123" or "123;cluster" */
    if (prc != 0 || !id[0])
        return sci_error_set(err, -EIO, "sbatch %s failed (exit %d)", p->path, WEXITSTATUS(prc));
    return 0;
}

int batch_slurm_submit(batch *b, const batch_slurm_opts *o, sci_error *err)
{
    slurm_plan p = {0};
    int rc = batch_slurm_plan_jobs(b, &p, err);
    if (rc < 0)
        return rc;
    if (p.ntodo == 0) {
        printf("slurm: nothing to submit: %d job(s) done, %d queued or running (scicap batch --status %s)\n", p.done,
               p.inq, b->outdir);
        free(p.todo);
        return 0;
    }
    batch_slurm_plan_resources(b, o, &p);
    char id[128] = "";
    if ((rc = batch_slurm_script_write(b, o, &p, err)) < 0) {
        free(p.todo);
        return rc;
    }
    if (o && o->dry_run) {
        printf("slurm: wrote %s (%d task(s); not submitted: --dry-run)\n", p.path, p.ntodo);
        free(p.todo);
        return 0;
    }
    if ((rc = batch_slurm_sbatch(&p, id, sizeof id, err)) < 0) {
        free(p.todo);
        return rc;
    }
    snprintf(b->slurm_job, sizeof b->slurm_job, "%s", id);
    for (int t = 0; t < p.ntodo; t++) {
        batch_job *j = &b->jobs[p.todo[t]];
        snprintf(j->slurm_task, sizeof j->slurm_task, "%s_%d", id, t);
        j->state = BATCH_SUBMITTED;
        j->error[0] = 0;
        j->attempts++;
    }
    free(p.todo);
    rc = batch_state_save(b, err);
    printf("slurm: submitted array job %s: %d task(s) (%d done, %d already queued or running); each %d CPU(s), "
           "%ld MiB, %ld min (%s)\nslurm: script %s; follow with: scicap batch --status %s\n", id, p.ntodo, p.done,
           p.inq, p.cpus, p.mem, p.tmin, p.how, p.path, b->outdir);
    return rc;
}

int batch_slurm_status(batch *b)
{
    char (*q)[24] = calloc((size_t)(b->njobs ? b->njobs : 1), sizeof *q);
    if (!q)
        return 1;
    const int asked = squeue_states(b, q);
    int done = 0, queued = 0, failed = 0, other = 0, w = 4;
    for (int i = 0; i < b->njobs; i++)
        if ((int)strlen(b->jobs[i].name) > w)
            w = (int)strlen(b->jobs[i].name) > 40 ? 40 : (int)strlen(b->jobs[i].name);
    printf("%-*s  %-12s  %8s  %8s  %s\n", w, "job", "state", "time s", "PSNR dB", "task / output / error");
    for (int i = 0; i < b->njobs; i++) {
        batch_job *j = &b->jobs[i];
        const char *st;
        char extra[PATH_MAX + 300], ps[16] = "-", t[16] = "-";
        if (batch_job_finished(b, j)) {
            st = "done", done++;
            snprintf(extra, sizeof extra, "%s/%s", b->outdir, j->name);
        } else if (q[i][0]) {
            st = q[i], queued++;
            snprintf(extra, sizeof extra, "%s", j->slurm_task);
        } else if (j->state == BATCH_FAILED) {
            st = "FAILED", failed++;
            snprintf(extra, sizeof extra, "%s%s%s", j->slurm_task, j->slurm_task[0] ? ": " : "", j->error);
        } else {
            st = "not finished", other++;
            snprintf(extra, sizeof extra, "%s%s", j->slurm_task,
                     j->slurm_task[0] ? ": ended without output (cancelled or killed)" : "never run");
        }
        if (!isnan(j->psnr) && j->state == BATCH_DONE)
            snprintf(ps, sizeof ps, "%.2f", j->psnr);
        if (j->seconds > 0)
            snprintf(t, sizeof t, "%.1f", j->seconds);
        printf("%-*s  %-12s  %8s  %8s  %s\n", w, j->name, st, t, ps, extra);
    }
    free(q);
    printf("%d job(s): %d done, %d queued or running, %d failed, %d not finished%s%s\n", b->njobs, done, queued,
           failed, other, b->slurm_job[0] ? "; last array job " : "", b->slurm_job);
    if (asked < 0)
        printf("(squeue could not be asked: queued or running tasks show as not finished)\n");
    sci_error err = {0};
    batch_state_save(b, &err);
    return done == b->njobs ? 0 : queued ? 3 : 1;
}
