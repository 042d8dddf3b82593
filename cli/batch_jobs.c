/* cli/batch_jobs.c — the jobs of a batch: inputs to jobs, the state file, each job's command line (batch.h). */
#include "cli/batch.h"

#include <dirent.h>
#include <errno.h>
#include <glob.h>
#include <limits.h>
#include <signal.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <jansson.h>

#include "base/json.h"
#include "io/staging.h"

static const char *const state_names[] = {"pending", "running", "done", "failed", "submitted"};

static const char *str_or(const char *s)
{
    return s ? s : "";
}

static int is_dir(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0 && S_ISDIR(st.st_mode);
}

static int has_suffix(const char *s, const char *suf)
{
    size_t a = strlen(s), b = strlen(suf);
    return a >= b && strcasecmp(s + a - b, suf) == 0;
}

static int is_problem_dir(const char *p)
{
    char f[PATH_MAX + 32];
    snprintf(f, sizeof f, "%s/problem.json", p);
    return access(f, R_OK) == 0;
}

/* A capture id as scicapd names them: c and six digits or more. */
static int is_capture_id(const char *s)
{
    if (s[0] != 'c' || strlen(s) < 7)
        return 0;
    for (const char *p = s + 1; *p; p++)
        if (*p < '0' || *p > '9')
            return 0;
    return 1;
}

static int add_job(batch *b, const char *path, const char *name_hint, sci_error *err)
{
    char abs[PATH_MAX];
    if (!realpath(path, abs))
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    for (int i = 0; i < b->njobs; i++)
        if (strcmp(b->jobs[i].input, abs) == 0)
            return 0; /* the same input twice (or again on a re-run): one job */
    char base[256];
    if (name_hint) {
        snprintf(base, sizeof base, "%s", name_hint);
    } else {
        const char *slash = strrchr(abs, '/');
        snprintf(base, sizeof base, "%s", slash ? slash + 1 : abs);
        if (has_suffix(base, ".mat"))
            base[strlen(base) - 4] = 0;
    }
    char name[256];
    snprintf(name, sizeof name, "%s", base);
    for (int k = 2;; k++) {
        int clash = strcmp(name, BATCH_STATE_DIR) == 0;
        for (int i = 0; i < b->njobs && !clash; i++)
            clash = strcmp(b->jobs[i].name, name) == 0;
        if (!clash)
            break;
        snprintf(name, sizeof name, "%.240s_%d", base, k);
    }
    if (b->njobs == b->capjobs) {
        int cap = b->capjobs ? 2 * b->capjobs : 16;
        batch_job *nj = realloc(b->jobs, (size_t)cap * sizeof *nj);
        if (!nj)
            return sci_error_set(err, -ENOMEM, "out of memory for %d jobs", cap);
        b->jobs = nj, b->capjobs = cap;
    }
    batch_job *j = &b->jobs[b->njobs++];
    memset(j, 0, sizeof *j);
    snprintf(j->name, sizeof j->name, "%s", name);
    snprintf(j->input, sizeof j->input, "%s", abs);
    j->psnr = NAN;
    return 0;
}

/* A path that exists: a .mat, a problem folder, or a folder of those. */
static int add_path(batch *b, const char *p, const char *name_hint, sci_error *err)
{
    if (!is_dir(p)) {
        if (has_suffix(p, "/problem.json")) {
            char dir[PATH_MAX];
            snprintf(dir, sizeof dir, "%.*s", (int)(strlen(p) - 13), p);
            return add_job(b, dir, name_hint, err);
        }
        return add_job(b, p, name_hint, err); /* scicap recon says what it is not */
    }
    if (is_problem_dir(p))
        return add_job(b, p, name_hint, err);
    struct dirent **ents;
    int n = scandir(p, &ents, NULL, alphasort), added = 0, rc = 0;
    if (n < 0)
        return sci_error_set(err, -errno, "%s: %s", p, strerror(errno));
    for (int i = 0; i < n; i++) {
        char sub[PATH_MAX];
        const char *e = ents[i]->d_name;
        if (e[0] != '.' && rc == 0 && snprintf(sub, sizeof sub, "%s/%s", p, e) < (int)sizeof sub &&
            ((has_suffix(e, ".mat") && !is_dir(sub)) || (is_dir(sub) && is_problem_dir(sub)))) {
            rc = add_job(b, sub, NULL, err);
            added++;
        }
        free(ents[i]);
    }
    free(ents);
    if (rc == 0 && added == 0)
        rc = sci_error_set(err, -ENOENT, "%s: no .mat file or problem folder in it", p);
    return rc;
}

int batch_add_inputs(batch *b, char *const *inputs, int n, const char *store, sci_error *err)
{
    if (!store || !store[0])
        store = getenv("SCICAP_STORE");
    if (!store || !store[0])
        store = "/var/lib/scicapd";
    for (int i = 0; i < n; i++) {
        const char *in = inputs[i];
        int rc;
        if (access(in, F_OK) == 0) {
            rc = add_path(b, in, NULL, err);
        } else if (is_capture_id(in)) {
            char p[PATH_MAX];
            snprintf(p, sizeof p, "%s/captures/%s", store, in);
            if (!is_dir(p))
                return sci_error_set(err, -ENOENT, "%s: no capture %s in %s/captures (--store DIR)", in, in, store);
            rc = add_path(b, p, in, err);
        } else if (strpbrk(in, "*?[")) {
            glob_t g;
            int grc = glob(in, 0, NULL, &g);
            if (grc != 0) {
                if (grc == GLOB_NOMATCH)
                    return sci_error_set(err, -ENOENT, "%s: matches nothing", in);
                return sci_error_set(err, -EIO, "%s: glob failed", in);
            }
            rc = 0;
            for (size_t k = 0; k < g.gl_pathc && rc == 0; k++)
                rc = add_path(b, g.gl_pathv[k], NULL, err);
            globfree(&g);
        } else {
            return sci_error_set(err, -ENOENT, "%s: no such file, folder or capture", in);
        }
        if (rc < 0)
            return rc;
    }
    return 0;
}

int batch_path(const batch *b, char *buf, size_t n, const char *rel, sci_error *err)
{
    static const char *const sub[] = {"", "/logs", "/tasks"};
    for (size_t i = 0; i < sizeof sub / sizeof sub[0]; i++) {
        char d[PATH_MAX];
        snprintf(d, sizeof d, "%s/%s%s", b->outdir, BATCH_STATE_DIR, sub[i]);
        if (mkdir(d, 0755) != 0 && errno != EEXIST)
            return sci_error_set(err, -errno, "%s: %s", d, strerror(errno));
    }
    if ((size_t)snprintf(buf, n, "%s/%s/%s", b->outdir, BATCH_STATE_DIR, rel) >= n)
        return sci_error_set(err, -ENAMETOOLONG, "%s: path too long", b->outdir);
    return 0;
}

/* The PSNR in a result folder: result.json, or the first snapshot's when the input had several. */
static double result_psnr(const char *dir)
{
    char p[PATH_MAX + 64];
    json_t *j = NULL;
    snprintf(p, sizeof p, "%s/result.json", dir);
    if (!(j = json_load_file(p, 0, NULL))) {
        snprintf(p, sizeof p, "%s/snap_001/result.json", dir);
        j = json_load_file(p, 0, NULL);
    }
    double v = NAN;
    json_t *m = j ? json_object_get(json_object_get(j, "psnr_frame_max_db"), "mean") : NULL;
    if (json_is_number(m))
        v = json_number_value(m);
    json_decref(j);
    return v;
}

int batch_job_finished(const batch *b, batch_job *j)
{
    char p[PATH_MAX + 300];
    snprintf(p, sizeof p, "%s/%s", b->outdir, j->name);
    if (!is_dir(p))
        return 0;
    if (j->state != BATCH_DONE || isnan(j->psnr))
        j->psnr = result_psnr(p);
    j->state = BATCH_DONE;
    j->error[0] = 0;
    return 1;
}

void batch_job_clean_staging(const batch *b, const batch_job *j)
{
    DIR *d = opendir(b->outdir);
    if (!d)
        return;
    const size_t l = strlen(j->name);
    struct dirent *e;
    while ((e = readdir(d))) {
        char *end;
        if (strncmp(e->d_name, j->name, l) != 0 || strncmp(e->d_name + l, ".tmp-", 5) != 0)
            continue;
        long pid = strtol(e->d_name + l + 5, &end, 10);
        if (*end || pid <= 0 || (kill((pid_t)pid, 0) == 0 || errno != ESRCH))
            continue; /* not a staging name, or its writer is still alive */
        char p[PATH_MAX + 300];
        snprintf(p, sizeof p, "%s/%s", b->outdir, e->d_name);
        sci_staging_remove(p);
    }
    closedir(d);
}

int batch_set_recon_args(batch *b, char *const *args, int n, sci_error *err)
{
    char **a = calloc((size_t)n + 1, sizeof *a);
    if (!a)
        return sci_error_set(err, -ENOMEM, "out of memory");
    for (int i = 0; i < n; i++)
        if (!(a[i] = strdup(args[i]))) {
            for (int k = 0; k < i; k++)
                free(a[k]);
            free(a);
            return sci_error_set(err, -ENOMEM, "out of memory");
        }
    for (int i = 0; i < b->nrecon_args; i++)
        free(b->recon_args[i]);
    free(b->recon_args);
    b->recon_args = a, b->nrecon_args = n;
    return 0;
}

void batch_free(batch *b)
{
    for (int i = 0; i < b->nrecon_args; i++)
        free(b->recon_args[i]);
    free(b->recon_args);
    free(b->jobs);
    memset(b, 0, sizeof *b);
}

char **batch_job_argv(const batch *b, const batch_job *j)
{
    char **argv = calloc((size_t)b->nrecon_args + 8, sizeof *argv);
    char *out = malloc(strlen(b->outdir) + strlen(j->name) + 2);
    if (!argv || !out) {
        free(argv);
        free(out);
        return NULL;
    }
    sprintf(out, "%s/%s", b->outdir, j->name);
    int k = 0;
    argv[k++] = (char *)b->bin;
    argv[k++] = (char *)"recon";
    for (int i = 0; i < b->nrecon_args; i++)
        argv[k++] = b->recon_args[i];
    argv[k++] = (char *)j->input;
    argv[k++] = (char *)"-o";
    argv[k++] = out; /* the one malloc'd string: batch_argv_free frees it */
    argv[k] = NULL;
    return argv;
}

void batch_argv_free(char **argv)
{
    if (!argv)
        return;
    int k = 0;
    while (argv[k])
        k++;
    free(argv[k - 1]);
    free(argv);
}

static json_t *job_to_json(const batch_job *j)
{
    json_t *o = json_pack("{s:s, s:s, s:s, s:f, s:i, s:s, s:s}", "name", j->name, "input", j->input, "state",
                          state_names[j->state], "seconds", j->seconds, "attempts", j->attempts, "error", j->error,
                          "slurm_task", j->slurm_task);
    if (o)
        json_object_set_new(o, "psnr_db", isnan(j->psnr) ? json_null() : json_real(j->psnr));
    return o;
}

int batch_state_save(const batch *b, sci_error *err)
{
    char path[PATH_MAX];
    int rc = batch_path(b, path, sizeof path, "state.json", err);
    if (rc < 0)
        return rc;
    json_t *jobs = json_array(), *args = json_array();
    for (int i = 0; i < b->njobs; i++)
        json_array_append_new(jobs, job_to_json(&b->jobs[i]));
    for (int i = 0; i < b->nrecon_args; i++)
        json_array_append_new(args, json_string(b->recon_args[i]));
    json_t *root = json_pack("{s:s, s:i, s:s, s:o, s:s, s:o}", "format", "scicap-batch", "version", 1, "scicap",
                             b->bin, "recon_args", args, "slurm_job", b->slurm_job, "jobs", jobs);
    rc = root ? sci_json_write_atomic(path, root, JSON_INDENT(1), 0644, 0, NULL) : -ENOMEM;
    json_decref(root);
    if (rc < 0)
        return sci_error_set(err, rc, "%s: cannot write the batch state", path);
    return 0;
}

static batch_state state_parse(const char *s)
{
    for (int i = 0; i < 5; i++)
        if (s && strcmp(s, state_names[i]) == 0)
            return (batch_state)i;
    return BATCH_PENDING;
}

int batch_state_load(batch *b, sci_error *err)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/%s/state.json", b->outdir, BATCH_STATE_DIR);
    if (access(path, F_OK) != 0)
        return 1;
    json_error_t je;
    json_t *root = json_load_file(path, 0, &je);
    json_t *jobs = root ? json_object_get(root, "jobs") : NULL;
    if (!json_is_array(jobs)) {
        json_decref(root);
        return sci_error_set(err, SCI_EFORMAT, "%s: not a batch state file (%s)", path, root ? "no jobs" : je.text);
    }
    json_t *args = json_object_get(root, "recon_args"), *v;
    size_t i;
    int rc = 0;
    if (json_is_array(args)) {
        char **a = calloc(json_array_size(args) + 1, sizeof *a);
        int n = 0;
        json_array_foreach(args, i, v) if (a && json_is_string(v)) a[n++] = (char *)json_string_value(v);
        rc = a ? batch_set_recon_args(b, a, n, err) : sci_error_set(err, -ENOMEM, "out of memory");
        free(a);
    }
    snprintf(b->slurm_job, sizeof b->slurm_job, "%s", str_or(json_string_value(json_object_get(root, "slurm_job"))));
    json_array_foreach(jobs, i, v) {
        const char *in = json_string_value(json_object_get(v, "input")),
                   *name = json_string_value(json_object_get(v, "name"));
        if (rc < 0 || !in || !name)
            continue;
        if (access(in, F_OK) != 0) { /* the input went away: keep the job, it will fail and say so */
            if (b->njobs == b->capjobs) {
                int cap = b->capjobs ? 2 * b->capjobs : 16;
                batch_job *nj = realloc(b->jobs, (size_t)cap * sizeof *nj);
                if (!nj) {
                    rc = sci_error_set(err, -ENOMEM, "out of memory");
                    continue;
                }
                b->jobs = nj, b->capjobs = cap;
            }
            batch_job *j = &b->jobs[b->njobs++];
            memset(j, 0, sizeof *j);
            snprintf(j->name, sizeof j->name, "%s", name);
            snprintf(j->input, sizeof j->input, "%s", in);
        } else if ((rc = add_job(b, in, name, err)) < 0) {
            continue;
        }
        batch_job *j = &b->jobs[b->njobs - 1];
        j->state = state_parse(json_string_value(json_object_get(v, "state")));
        if (j->state == BATCH_RUNNING)
            j->state = BATCH_PENDING; /* a run that was killed with us */
        j->seconds = json_number_value(json_object_get(v, "seconds"));
        json_t *ps = json_object_get(v, "psnr_db");
        j->psnr = json_is_number(ps) ? json_number_value(ps) : NAN;
        j->attempts = (int)json_integer_value(json_object_get(v, "attempts"));
        snprintf(j->error, sizeof j->error, "%s", str_or(json_string_value(json_object_get(v, "error"))));
        snprintf(j->slurm_task, sizeof j->slurm_task, "%s",
                 str_or(json_string_value(json_object_get(v, "slurm_task"))));
    }
    json_decref(root);
    return rc;
}

void batch_state_merge_tasks(batch *b)
{
    for (int i = 0; i < b->njobs; i++) {
        batch_job *j = &b->jobs[i];
        char p[PATH_MAX + 300];
        snprintf(p, sizeof p, "%s/%s/tasks/%s.json", b->outdir, BATCH_STATE_DIR, j->name);
        json_t *t = json_load_file(p, 0, NULL);
        if (!t)
            continue;
        const char *task = json_string_value(json_object_get(t, "slurm_task"));
        /* only the record of the task submitted last counts: an older one may be from a run resubmitted since */
        if (task && (!j->slurm_task[0] || strcmp(task, j->slurm_task) == 0)) {
            j->state = state_parse(json_string_value(json_object_get(t, "state")));
            j->seconds = json_number_value(json_object_get(t, "seconds"));
            json_t *ps = json_object_get(t, "psnr_db");
            j->psnr = json_is_number(ps) ? json_number_value(ps) : NAN;
            snprintf(j->error, sizeof j->error, "%s", str_or(json_string_value(json_object_get(t, "error"))));
        }
        json_decref(t);
    }
}
