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

int batch_slurm_submit(batch *b, const batch_slurm_opts *o, sci_error *err)
{
    char (*queued)[24] = calloc((size_t)(b->njobs ? b->njobs : 1), sizeof *queued);
    int *todo = calloc((size_t)(b->njobs ? b->njobs : 1), sizeof *todo), ntodo = 0, done = 0, inq = 0;
    if (!queued || !todo) {
        free(queued), free(todo);
        return sci_error_set(err, -ENOMEM, "out of memory");
    }
    squeue_states(b, queued);
    for (int i = 0; i < b->njobs; i++) {
        if (batch_job_finished(b, &b->jobs[i]))
            done++;
        else if (queued[i][0])
            inq++;
        else
            todo[ntodo++] = i;
    }
    free(queued);
    if (ntodo == 0) {
        printf("slurm: nothing to submit: %d job(s) done, %d queued or running (scicap batch --status %s)\n", done,
               inq, b->outdir);
        free(todo);
        return 0;
    }
    /* Resources: the method's measurements, scaled to the largest input of this submission. */
    /* no --method: scicap recon's default, the table's first row */
    const char *method = recon_opt(b, "--method", "-m", solver_list(NULL)[0]->name), *preset = recon_opt(b, "--preset", NULL, NULL);
    estimate e;
    estimate_read(b, o ? o->results : NULL, method, preset, &e);
    double voxels = 0;
    for (int t = 0; t < ntodo; t++) {
        long long w, h, n, k;
        sci_error perr = {0};
        if (sci_source_probe(b->jobs[todo[t]].input, NULL, &w, &h, &n, &k, &perr) == 0 && w > 0 && h > 0)
            voxels = fmax(voxels, (double)w * (double)h * (double)(n > 0 ? n : 1) * (double)(k > 0 ? k : 1));
    }
    const int cpus = o && o->cpus ? o->cpus : 2;
    long mem = o && o->mem_mib ? o->mem_mib : 0, tmin = o && o->time_min ? o->time_min : 0;
    char how[PATH_MAX + 256];
    if (e.rows) {
        if (!mem)
            mem = (long)ceil(fmax(512, 1.5 * e.rss_mib * fmax(1, voxels / e.rss_voxels)));
        if (!tmin)
            tmin = (long)ceil(fmax(5, 4 * e.s_per_voxel * voxels / 60));
        snprintf(how, sizeof how, "from %d row(s) of %s%s%s in %s: peak RSS %.0f MiB, %.3g s per voxel; inputs up "
                 "to %.0f voxels", e.rows, method, preset ? " preset " : "", preset ? preset : "", e.from, e.rss_mib,
                 e.s_per_voxel, voxels);
    } else {
        mem = mem ? mem : 2048;
        tmin = tmin ? tmin : 120;
        snprintf(how, sizeof how, "no measurement of %s found (bench/results.csv): defaults", method);
    }
    /* The script: one task per job, named in a case so a task never depends on another's index. */
    int seq = 1;
    char rel[64], path[PATH_MAX + 100];
    for (;; seq++) {
        snprintf(rel, sizeof rel, "slurm-%d.sh", seq);
        int rc = batch_path(b, path, sizeof path, rel, err);
        if (rc < 0) {
            free(todo);
            return rc;
        }
        if (access(path, F_OK) != 0)
            break;
    }
    FILE *f = fopen(path, "w");
    if (!f) {
        free(todo);
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    }
    fprintf(f, "#!/bin/sh\n# scicap batch --slurm: %d task(s) of %s\n# resources: %s\n", ntodo, b->outdir, how);
    fprintf(f, "#SBATCH --job-name=scicap-batch\n#SBATCH --array=0-%d", ntodo - 1);
    if (o && o->max_parallel)
        fprintf(f, "%%%d", o->max_parallel);
    fprintf(f, "\n#SBATCH --cpus-per-task=%d\n#SBATCH --mem=%ld\n#SBATCH --time=%ld\n", cpus, mem, tmin);
    fprintf(f, "#SBATCH --output=%s/%s/logs/slurm-%%A_%%a.log\n", b->outdir, BATCH_STATE_DIR);
    if (o && o->partition)
        fprintf(f, "#SBATCH --partition=%s\n", o->partition);
    fprintf(f, "export OMP_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-1}\"\ncase \"$SLURM_ARRAY_TASK_ID\" in\n");
    for (int t = 0; t < ntodo; t++) {
        fprintf(f, "%d) name=", t);
        sh_quote(f, b->jobs[todo[t]].name);
        fprintf(f, " ;;\n");
    }
    fprintf(f, "*) echo \"scicap batch: no job for task $SLURM_ARRAY_TASK_ID\" >&2; exit 2 ;;\nesac\nexec ");
    sh_quote(f, b->bin);
    fprintf(f, " batch --task \"$name\" ");
    sh_quote(f, b->outdir);
    fprintf(f, "\n");
    if (fclose(f) != 0) {
        free(todo);
        return sci_error_set(err, -EIO, "%s: write failed", path);
    }
    if (o && o->dry_run) {
        printf("slurm: wrote %s (%d task(s); not submitted: --dry-run)\n", path, ntodo);
        free(todo);
        return 0;
    }
    char cmd[PATH_MAX + 64];
    snprintf(cmd, sizeof cmd, "sbatch --parsable '%s'", path);
    FILE *p = popen(cmd, "r");
    char id[128] = "";
    if (!p || !fgets(id, sizeof id, p)) {
        if (p)
            pclose(p);
        free(todo);
        return sci_error_set(err, -EIO, "sbatch %s failed (is Slurm there? its message is above)", path);
    }
    int prc = pclose(p);
    id[strcspn(id, ";\n")] = 0; /* "123" or "123;cluster" */
    if (prc != 0 || !id[0]) {
        free(todo);
        return sci_error_set(err, -EIO, "sbatch %s failed (exit %d)", path, WEXITSTATUS(prc));
    }
    snprintf(b->slurm_job, sizeof b->slurm_job, "%s", id);
    for (int t = 0; t < ntodo; t++) {
        batch_job *j = &b->jobs[todo[t]];
        snprintf(j->slurm_task, sizeof j->slurm_task, "%s_%d", id, t);
        j->state = BATCH_SUBMITTED;
        j->error[0] = 0;
        j->attempts++;
    }
    free(todo);
    int rc = batch_state_save(b, err);
    printf("slurm: submitted array job %s: %d task(s) (%d done, %d already queued or running); each %d CPU(s), "
           "%ld MiB, %ld min (%s)\nslurm: script %s; follow with: scicap batch --status %s\n", id, ntodo, done, inq,
           cpus, mem, tmin, how, path, b->outdir);
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
