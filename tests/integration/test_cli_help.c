/* Help, man page and tool agree (issue 18): every subcommand's --help names each long option its getopt table
 * accepts (the tables are read from the sources in cli/, so a new option without help fails here), each command
 * prints its own help, the top-level help lists every command and every reconstruction method, the man page
 * (docs/man/scicap.1) has a section for every command naming each of its options, and `scicap capture --recon
 * gap-tv` works as its help says, against a real scicapd on the simulated bench. Runs the real binaries from the
 * source tree (BUILD, default build). */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "recon/solver.h"

static char build[1024];

/* Which command each getopt table in cli/ belongs to. Every table found must be listed here. */
static const struct { const char *file, *table, *cmds[8]; } tables[] = {
    {"cli/recon.c", "longopts", {"recon"}},
    {"cli/client.c", "reconstruct_opts", {"recon"}},
    {"cli/sim.c", "longopts", {"sim"}},
    {"cli/bench.c", "longopts", {"bench"}},
    {"cli/dmd.c", "dmd_opts", {"dmd"}},
    {"cli/client.c", "plain_opts", {"status", "devices", "jobs", "cancel", "watch", "reload", "shutdown"}},
    {"cli/client.c", "capture_opts", {"capture"}},
    {"cli/client.c", "calibrate_opts", {"calibrate"}},
};
static const char *const commands[] = {"sim", "recon", "status", "devices", "capture", "calibrate", "jobs",
                                       "cancel", "watch", "reload", "shutdown", "bench", "dmd"};
#define NCMD (sizeof commands / sizeof commands[0])
/* Man page section of each command. */
static const char *man_section(const char *cmd)
{
    if (!strcmp(cmd, "sim"))
        return "SCICAP SIM";
    if (!strcmp(cmd, "recon"))
        return "SCICAP RECON";
    if (!strcmp(cmd, "bench"))
        return "SCICAP BENCH";
    if (!strcmp(cmd, "dmd"))
        return "SCICAP DMD";
    return "DAEMON COMMANDS";
}

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        fail_msg("%s: %s (run from the source tree)", path, strerror(errno));
    char *b = malloc(1 << 20); /* kept for the process's life: a test binary */
    assert_non_null(b);
    size_t n = fread(b, 1, (1 << 20) - 1, f);
    b[n] = 0;
    fclose(f);
    return b;
}

/* The long option names of table `table` in source `file` (names[] receives pointers into a static buffer). */
static int table_names(const char *file, const char *table, char names[][48], int max)
{
    const char *src = slurp(file);
    char key[128];
    snprintf(key, sizeof key, "struct option %s[]", table);
    const char *p = strstr(src, key);
    if (!p)
        fail_msg("%s: no table %s", file, table);
    const char *end = strstr(p, "};");
    int n = 0;
    for (const char *q = strstr(p, "{\""); q && q < end && n < max; q = strstr(q + 2, "{\"")) {
        const char *e = strchr(q + 2, '"');
        snprintf(names[n], 48, "%.*s", (int)(e - q - 2), q + 2);
        n++;
    }
    return n;
}

/* Every `struct option NAME[]` in cli/ is one of ours. */
static void test_every_table_is_mapped(void **state)
{
    const char *files[] = {"cli/recon.c", "cli/client.c", "cli/sim.c", "cli/bench.c", "cli/dmd.c", "cli/main.c"};
    for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
        const char *src = slurp(files[f]);
        for (const char *p = strstr(src, "struct option "); p; p = strstr(p + 1, "struct option ")) {
            char name[64];
            if (sscanf(p, "struct option %63[A-Za-z0-9_][]", name) != 1)
                continue;
            if (!strchr(p, '[') || strchr(p, '[') > strchr(p, ';'))
                continue; /* a pointer, not a table */
            int found = 0;
            for (size_t t = 0; t < sizeof tables / sizeof tables[0]; t++)
                found |= !strcmp(tables[t].file, files[f]) && !strcmp(tables[t].table, name);
            if (!found)
                fail_msg("%s: option table %s belongs to no command in this test", files[f], name);
        }
    }
}

/* Run a command, its stdout into buf; returns the exit status. */
static int capture(char *buf, size_t n, const char *fmt, ...)
{
    char cmd[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t got = fread(buf, 1, n - 1, p);
    buf[got] = 0;
    int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void test_help_names_every_option(void **state)
{
    static char help[65536];
    char first_lines[NCMD][160];
    for (size_t c = 0; c < NCMD; c++) {
        assert_int_equal(capture(help, sizeof help, "%s/scicap %s --help", build, commands[c]), 0);
        char want[64];
        snprintf(want, sizeof want, "scicap %s", commands[c]);
        if (!strstr(help, want))
            fail_msg("'%s --help' does not name the command:\n%s", commands[c], help);
        snprintf(first_lines[c], sizeof first_lines[c], "%.*s", (int)strcspn(help, "\n"), help);
        int checked = 0;
        for (size_t t = 0; t < sizeof tables / sizeof tables[0]; t++) {
            int mine = 0;
            for (int k = 0; k < 8 && tables[t].cmds[k]; k++)
                mine |= !strcmp(tables[t].cmds[k], commands[c]);
            if (!mine)
                continue;
            char names[96][48];
            int nn = table_names(tables[t].file, tables[t].table, names, 96);
            for (int i = 0; i < nn; i++) {
                char opt[64];
                snprintf(opt, sizeof opt, "--%s", names[i]);
                if (!strstr(help, opt))
                    fail_msg("scicap %s accepts %s (%s:%s) but its --help does not name it", commands[c], opt,
                             tables[t].file, tables[t].table);
                checked++;
            }
        }
        printf("scicap %-9s --help names all %d options\n", commands[c], checked);
        assert_true(checked >= 2);
    }
    /* Each prints its own help, not one generic text. */
    for (size_t a = 0; a < NCMD; a++)
        for (size_t b = a + 1; b < NCMD; b++)
            if (!strcmp(first_lines[a], first_lines[b]))
                fail_msg("%s and %s print the same help: %s", commands[a], commands[b], first_lines[a]);
}

static void test_top_level_help(void **state)
{
    static char help[16384];
    assert_int_equal(capture(help, sizeof help, "%s/scicap --help", build), 0);
    size_t nm = 0;
    const solver_ops *const *methods = solver_list(&nm);
    for (size_t i = 0; i < nm; i++) {
        char want[160];
        snprintf(want, sizeof want, "  %-11s %s\n", methods[i]->name, methods[i]->summary);
        if (!strstr(help, want))
            fail_msg("scicap --help does not list the method %s with its summary", methods[i]->name);
    }
    for (size_t c = 0; c < NCMD; c++) {
        char want[64];
        snprintf(want, sizeof want, "\n  %s ", commands[c]);
        if (!strstr(help, want))
            fail_msg("scicap --help does not list the command %s", commands[c]);
    }
}

/* The man page: a section per command naming each of its long options (as \-\- in roff). */
static void test_man_page_complete(void **state)
{
    const char *man = slurp("docs/man/scicap.1");
    for (size_t c = 0; c < NCMD; c++) {
        char head[64];
        snprintf(head, sizeof head, ".SH %s\n", man_section(commands[c]));
        const char *sec = strstr(man, head);
        if (!sec)
            fail_msg("docs/man/scicap.1 has no section %s", head);
        const char *end = strstr(sec + 4, "\n.SH ");
        size_t len = end ? (size_t)(end - sec) : strlen(sec);
        char *text = strndup(sec, len);
        if (strcmp(man_section(commands[c]), "DAEMON COMMANDS") == 0) {
            char want[64];
            snprintf(want, sizeof want, ".B %s", commands[c]);
            if (!strstr(text, want) && !(snprintf(want, sizeof want, ".BI %s", commands[c]) && strstr(text, want)))
                fail_msg("docs/man/scicap.1: %s is not described under DAEMON COMMANDS", commands[c]);
        }
        for (size_t t = 0; t < sizeof tables / sizeof tables[0]; t++) {
            int mine = 0;
            for (int k = 0; k < 8 && tables[t].cmds[k]; k++)
                mine |= !strcmp(tables[t].cmds[k], commands[c]);
            if (!mine)
                continue;
            char names[96][48];
            int nn = table_names(tables[t].file, tables[t].table, names, 96);
            for (int i = 0; i < nn; i++) {
                char opt[64];
                snprintf(opt, sizeof opt, "\\-\\-%s", names[i]);
                if (!strstr(text, opt))
                    fail_msg("docs/man/scicap.1, section %s: no %s (scicap %s accepts it)", man_section(commands[c]),
                             opt, commands[c]);
            }
        }
        free(text);
    }
}

/* `scicap capture --recon gap-tv` (and --recon=admm-tv) against scicapd on the simulated bench. */
static void test_capture_recon_method(void **state)
{
    char dir[] = "/tmp/scicap-test-help-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char sock[256], store[256], run[256];
    snprintf(sock, sizeof sock, "%s/control.sock", dir);
    snprintf(store, sizeof store, "%s/store", dir);
    snprintf(run, sizeof run, "%s/run", dir);
    char daemon[1100];
    snprintf(daemon, sizeof daemon, "%s/scicapd", build);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        freopen("/dev/null", "w", stderr);
        execl(daemon, "scicapd", "--no-config", "--socket", sock, "--storage", store, "--runtime-dir", run,
              geteuid() == 0 ? "--allow-root" : NULL, (char *)NULL);
        _exit(127);
    }
    struct stat st;
    for (int i = 0; i < 100 && stat(sock, &st) != 0; i++)
        nanosleep(&(struct timespec){0, 100000000}, NULL);
    static char out[65536];
    int rc = capture(out, sizeof out, "SCICAP_SOCKET=%s %s/scicap capture --recon gap-tv --wait", sock, build);
    printf("%s", out);
    int ok_gap = rc == 0 && strstr(out, "gap-tv of c") && strstr(out, "PSNR");
    rc = capture(out, sizeof out, "SCICAP_SOCKET=%s %s/scicap capture --recon=admm-tv --wait", sock, build);
    int ok_admm = rc == 0 && strstr(out, "admm-tv of c");
    int bad = capture(out, sizeof out, "SCICAP_SOCKET=%s %s/scicap capture --recon=fista 2>/dev/null", sock, build);
    capture(out, sizeof out, "SCICAP_SOCKET=%s %s/scicap shutdown 2>/dev/null", sock, build);
    int status = 0;
    for (int i = 0; i < 50 && waitpid(pid, &status, WNOHANG) == 0; i++)
        nanosleep(&(struct timespec){0, 100000000}, NULL);
    if (waitpid(pid, &status, WNOHANG) == 0) {
        kill(pid, SIGTERM);
        waitpid(pid, &status, 0);
    }
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
    assert_true(ok_gap);
    assert_true(ok_admm);
    assert_int_equal(bad, 2);
}

static int setup(void **state)
{
    const char *b = getenv("BUILD");
    snprintf(build, sizeof build, "%s", b ? b : "build");
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_table_is_mapped), cmocka_unit_test(test_help_names_every_option),
        cmocka_unit_test(test_top_level_help),        cmocka_unit_test(test_man_page_complete),
        cmocka_unit_test(test_capture_recon_method),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
