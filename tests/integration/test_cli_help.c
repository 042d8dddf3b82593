/* Help, man page and tool agree: every subcommand's --help names each long option its getopt table accepts (the
 * tables are read from the sources in cli/ and daemon/main.c, so a new option without help fails here), each
 * command prints its own help, the top-level help lists every command and every reconstruction method, the man
 * pages (docs/man/scicap.1, docs/man/scicapd.8) have a section for every command naming each of its options and
 * no option it does not accept, and `scicap capture --recon gap-tv` works as its help says, against a real
 * scicapd on the simulated bench. Runs the real binaries from the source tree (BUILD, default build). The
 * method and preset tables of the man pages are checked by test_docs_methods.c. */
#include <errno.h>
#include <glob.h>
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
#include "tests/helpers/cli_child.h"

static char build[1024];

/* Which command each getopt table in cli/ belongs to. Every table found must be listed here. */
static const struct { const char *file, *table, *cmds[8]; } tables[] = {
    {"cli/recon.c", "longopts", {"recon"}},
    {"cli/client.c", "reconstruct_opts", {"recon"}},
    {"cli/sim.c", "longopts", {"sim"}},
    {"cli/bench.c", "longopts", {"bench"}},
    {"cli/batch.c", "longopts", {"batch"}},
    {"cli/dmd.c", "dmd_opts", {"dmd"}},
    {"cli/client.c", "plain_opts", {"status", "devices", "cancel", "watch", "reload", "shutdown"}},
    {"cli/client.c", "list_opts", {"jobs", "captures"}},
    {"cli/client.c", "capture_opts", {"capture"}},
    {"cli/client.c", "calibrate_opts", {"calibrate"}},
};
static const char *const commands[] = {"sim",   "recon",  "batch",  "status", "devices",  "capture", "calibrate",
                                       "jobs",  "captures", "cancel", "watch", "reload", "shutdown", "bench", "dmd"};
#define NCMD (sizeof commands / sizeof commands[0])
/* Man page section of each command. */
static const char *man_section(const char *cmd)
{
    if (!strcmp(cmd, "sim"))
        return "SCICAP SIM";
    if (!strcmp(cmd, "recon"))
        return "SCICAP RECON";
    if (!strcmp(cmd, "batch"))
        return "SCICAP BATCH";
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

/* The long options of scicap `cmd`: the names in every getopt table that serves it. */
static int command_options(const char *cmd, char names[][48], int max)
{
    int n = 0;
    for (size_t t = 0; t < sizeof tables / sizeof tables[0]; t++)
        for (int k = 0; k < 8 && tables[t].cmds[k]; k++)
            if (!strcmp(tables[t].cmds[k], cmd))
                n += table_names(tables[t].file, tables[t].table, names + n, max - n);
    return n;
}

/* Every `struct option NAME[]` in cli/ is one of ours. */
static void test_every_table_is_mapped(void **state)
{
    glob_t g;
    assert_int_equal(glob("cli/*.c", 0, NULL, &g), 0);
    char **files = g.gl_pathv;
    assert_true(g.gl_pathc >= 6);
    for (size_t f = 0; f < g.gl_pathc; f++) {
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
    globfree(&g);
}

/* Options a command accepts without naming them in its --help, each with why; printed on every run. The man
 * page names them all the same. */
static const struct { const char *cmd, *opt, *why; } unlisted[] = {
    {"batch", "task", "internal: what each Slurm array task runs (the sbatch script writes it)"},
};

static const char *unlisted_why(const char *cmd, const char *opt)
{
    for (size_t i = 0; i < sizeof unlisted / sizeof unlisted[0]; i++)
        if (!strcmp(unlisted[i].cmd, cmd) && !strcmp(unlisted[i].opt, opt))
            return unlisted[i].why;
    return NULL;
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
        char names[192][48];
        int checked = command_options(commands[c], names, 192);
        for (int i = 0; i < checked; i++) {
            char opt[64];
            snprintf(opt, sizeof opt, "--%s", names[i]);
            const char *why = unlisted_why(commands[c], names[i]);
            if (why && !strstr(help, opt))
                printf("scicap %s %s: not in --help (%s)\n", commands[c], opt, why);
            else if (!strstr(help, opt))
                fail_msg("scicap %s accepts %s (cli/ getopt table) but its --help does not name it", commands[c], opt);
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

/* A man page section's text with roff's font escapes removed and \- read as '-' (malloc'd). */
static char *roff_plain(const char *sec, size_t len)
{
    char *out = malloc(len + 1), *o = out;
    assert_non_null(out);
    for (size_t i = 0; i < len; i++) {
        if (sec[i] == '\\' && i + 1 < len && sec[i + 1] == '-')
            *o++ = '-', i++;
        else if (sec[i] == '\\' && i + 2 < len && sec[i + 1] == 'f')
            i += 2; /* \fB, \fI, \fP, \fR */
        else if (sec[i] == '\\' && i + 1 < len && sec[i + 1] == '&')
            i++;
        else
            *o++ = sec[i];
    }
    *o = 0;
    return out;
}

/* Long options a section names that belong to another program or command: mentioned there, not accepted. */
static const struct { const char *section, *opt; } mentions[] = {
    {"SCICAP RECON", "from"},  /* scicap capture --from */
    {"SCICAP BATCH", "array"}, /* sbatch --array */
};

/* Each --name in the plain section text is in names[] (or a mention above); fails naming the first that is not.
 * Returns how many it found. */
static int check_named_options(const char *page, const char *section, const char *text, char names[][48], int nn)
{
    int found = 0;
    for (const char *p = strstr(text, "--"); p; p = strstr(p + 2, "--")) {
        if (p[2] < 'a' || p[2] > 'z')
            continue; /* the "--" before a command's own options */
        char name[48];
        int k = 0;
        while (k < 47 && ((p[2 + k] >= 'a' && p[2 + k] <= 'z') || (p[2 + k] >= '0' && p[2 + k] <= '9') ||
                          p[2 + k] == '-'))
            name[k] = p[2 + k], k++;
        while (k > 0 && name[k - 1] == '-')
            k--;
        name[k] = 0;
        int ok = 0;
        for (int i = 0; i < nn && !ok; i++)
            ok = !strcmp(names[i], name);
        for (size_t i = 0; i < sizeof mentions / sizeof mentions[0] && !ok; i++)
            ok = !strcmp(mentions[i].section, section) && !strcmp(mentions[i].opt, name);
        if (!ok)
            fail_msg("%s, section %s: names --%s, which the command does not accept", page, section, name);
        found++;
    }
    return found;
}

/* The man page: a section per command naming each of its long options (as \-\- in roff), and no other. */
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
        char names[192][48];
        int nn = command_options(commands[c], names, 192);
        for (int i = 0; i < nn; i++) {
            char opt[64];
            snprintf(opt, sizeof opt, "\\-\\-%s", names[i]);
            if (!strstr(text, opt))
                fail_msg("docs/man/scicap.1, section %s: no %s (scicap %s accepts it)", man_section(commands[c]), opt,
                         commands[c]);
        }
        free(text);
    }
    /* The other way: every option a section names is one its commands accept. */
    for (size_t c = 0; c < NCMD; c++) {
        int first = 1;
        for (size_t b = 0; b < c; b++)
            first &= strcmp(man_section(commands[b]), man_section(commands[c])) != 0;
        if (!first)
            continue; /* a section shared by several commands: checked once, with all of theirs */
        static char names[512][48];
        int nn = 0;
        for (size_t d = 0; d < NCMD; d++) {
            if (strcmp(man_section(commands[d]), man_section(commands[c])) != 0)
                continue;
            nn += command_options(commands[d], names + nn, 512 - nn);
        }
        char head[64];
        snprintf(head, sizeof head, ".SH %s\n", man_section(commands[c]));
        const char *sec = strstr(man, head);
        assert_non_null(sec);
        const char *end = strstr(sec + 4, "\n.SH ");
        char *text = roff_plain(sec, end ? (size_t)(end - sec) : strlen(sec));
        int found = check_named_options("docs/man/scicap.1", man_section(commands[c]), text, names, nn);
        printf("docs/man/scicap.1, %-15s names %3d options, each one its commands accept\n", man_section(commands[c]),
               found);
        free(text);
    }
}

/* scicapd: its getopt table (daemon/main.c), its --help and scicapd(8)'s OPTIONS name the same options. */
static void test_scicapd_help_and_man(void **state)
{
    char names[64][48];
    int nn = table_names("daemon/main.c", "opts", names, 64);
    assert_true(nn >= 8);
    static char help[16384];
    assert_int_equal(capture(help, sizeof help, "%s/scicapd --help", build), 0);
    const char *man = slurp("docs/man/scicapd.8");
    const char *sec = strstr(man, ".SH OPTIONS\n");
    if (!sec)
        fail_msg("docs/man/scicapd.8 has no OPTIONS section");
    const char *end = strstr(sec + 4, "\n.SH ");
    char *text = roff_plain(sec, end ? (size_t)(end - sec) : strlen(sec));
    for (int i = 0; i < nn; i++) {
        char opt[64];
        snprintf(opt, sizeof opt, "--%s", names[i]);
        if (!strstr(help, opt))
            fail_msg("scicapd accepts %s (daemon/main.c) but its --help does not name it", opt);
        if (!strstr(text, opt))
            fail_msg("docs/man/scicapd.8, OPTIONS: no %s (scicapd accepts it)", opt);
    }
    int found = check_named_options("docs/man/scicapd.8", "OPTIONS", text, names, nn);
    printf("scicapd: its %d options in --help and scicapd(8); the page names %d, each one it accepts\n", nn, found);
    free(text);
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
    pid_t pid = cli_child_spawn_logged("/dev/null", daemon,
                                       (const char *const[]){"scicapd", "--no-config", "--socket", sock, "--storage",
                                                             store, "--runtime-dir", run,
                                                             geteuid() == 0 ? "--allow-root" : NULL, NULL});
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
        cmocka_unit_test(test_scicapd_help_and_man),
        cmocka_unit_test(test_capture_recon_method),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
