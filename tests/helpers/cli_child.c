/* tests/helpers/cli_child.c — a built program in a child process (see the header). */
#include "tests/helpers/cli_child.h"

#include <fcntl.h>
#include <ftw.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

int cli_child_program(char *buf, size_t n, const char *name)
{
    const char *build = getenv("BUILD");
    snprintf(buf, n, "%s/%s", build && build[0] ? build : "build", name);
    if (access(buf, X_OK) != 0) {
        fprintf(stderr, "%s: not built\n", buf);
        return -1;
    }
    return 0;
}

static void stream_path(const cli_child *c, const char *which, char *buf, size_t n)
{
    snprintf(buf, n, "%s/%s-%d.txt", c->dir, which, (int)c->pid);
}

void cli_child_start(cli_child *c, const char *prog, const char *const *args, const char *dir)
{
    char *argv[64];
    int n = 0;
    argv[n++] = (char *)prog;
    for (; *args && n < 63; args++)
        argv[n++] = (char *)*args;
    argv[n] = NULL;
    memset(c, 0, sizeof *c);
    snprintf(c->dir, sizeof c->dir, "%s", dir);
    fflush(NULL); /* nothing buffered twice */
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        c->pid = getpid();
        char errp[600], outp[600];
        stream_path(c, "stderr", errp, sizeof errp);
        stream_path(c, "stdout", outp, sizeof outp);
        int e = open(errp, O_WRONLY | O_CREAT | O_TRUNC, 0644), o = open(outp, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (e < 0 || o < 0)
            _exit(126);
        dup2(e, 2);
        dup2(o, 1);
        execv(prog, argv);
        _exit(127);
    }
    c->pid = pid;
}

/* The file at path as written so far, into buf (n bytes, NUL-terminated; empty if there is none yet). */
static void read_stream(const char *path, char *buf, size_t n)
{
    FILE *f = fopen(path, "r");
    size_t len = f ? fread(buf, 1, n - 1, f) : 0;
    buf[len] = '\0';
    if (f)
        fclose(f);
}

/* The whole stream once the child has ended; its file goes with it. */
static void slurp(const cli_child *c, const char *which, char *buf, size_t n)
{
    char path[600];
    stream_path(c, which, path, sizeof path);
    read_stream(path, buf, n);
    unlink(path);
}

int cli_child_wait_stdout(const cli_child *c, const char *needle, int timeout_ms)
{
    char path[600], buf[8192];
    stream_path(c, "stdout", path, sizeof path);
    for (int waited = 0; waited <= timeout_ms; waited += 20) {
        read_stream(path, buf, sizeof buf);
        if (strstr(buf, needle))
            return 0;
        usleep(20000);
    }
    return -1;
}

void cli_child_finish(cli_child *c)
{
    struct rusage ru;
    assert_int_equal(wait4(c->pid, &c->status, 0, &ru), c->pid);
    c->maxrss_kb = ru.ru_maxrss;
    slurp(c, "stderr", c->err, sizeof c->err);
    slurp(c, "stdout", c->out, sizeof c->out);
}

void cli_child_run(cli_child *c, const char *prog, const char *const *args, const char *dir)
{
    cli_child_start(c, prog, args, dir);
    cli_child_finish(c);
}

int cli_child_exit_code(const cli_child *c) { return WIFEXITED(c->status) ? WEXITSTATUS(c->status) : -1; }

int cli_child_setup(char *prog, size_t n, const char *name, char *dir)
{
    if (cli_child_program(prog, n, name) < 0)
        return -1;
    return mkdtemp(dir) ? 0 : -1;
}

static int remove_entry(const char *path, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb, (void)flag, (void)ftw;
    return remove(path);
}

int cli_child_remove_dir(const char *dir) { return nftw(dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS) == 0 ? 0 : -1; }

int cli_child_shell(const char *fmt, ...)
{
    char cmd[8192];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    int rc = system(cmd);
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

int cli_child_sim(const char *scicap, const char *dir, const char *scene_name, const char *scene_json)
{
    char path[2048];
    snprintf(path, sizeof path, "%s/%s", dir, scene_name);
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    int bad = fputs(scene_json, f) < 0;
    bad |= fclose(f) != 0;
    if (bad)
        return -1;
    return cli_child_shell("%s sim %s -o %s/prob -q >/dev/null 2>&1", scicap, path, dir) == 0 ? 0 : -1;
}

json_t *cli_child_load_json(const char *dir, const char *name)
{
    char path[2048];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    json_error_t je;
    json_t *j = json_load_file(path, 0, &je);
    if (!j)
        fail_msg("%s: %s", path, je.text);
    return j;
}

int cli_child_checkpoint_step(const char *log)
{
    static const char tag[] = "checkpoint of step ";
    int step = 0;
    FILE *f = fopen(log, "r");
    char line[1024];
    while (f && fgets(line, sizeof line, f)) {
        const char *s = strstr(line, tag);
        if (s)
            step = atoi(s + strlen(tag));
    }
    if (f)
        fclose(f);
    return step;
}

pid_t cli_child_spawn_logged(const char *log, const char *prog, const char *const *args)
{
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        FILE *f = freopen(log, "w", stderr);
        (void)f;
        execv(prog, (char *const *)args);
        _exit(127);
    }
    return pid;
}
