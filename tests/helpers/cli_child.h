/* tests/helpers/cli_child.h — run one of the built programs (scicap, scicapd) in a child process and look at
 * what it did: exit status, peak RSS, stderr and stdout.
 *
 *     char scicap[1024];
 *     cli_child_program(scicap, sizeof scicap, "scicap");        // $BUILD/scicap (BUILD defaults to "build")
 *     cli_child c;
 *     cli_child_run(&c, scicap, (const char *const[]){"recon", "-q", in, "-o", out, NULL}, dir);
 *     if (cli_child_exit_code(&c) != 0) fail_msg("%s", c.err);
 *
 * stdout and stderr go to files in `dir` (named after the child's pid: several children may run at once) that
 * cli_child_finish reads back (the first 8 KB of each) and removes. For use inside cmocka tests: a failed fork
 * or wait fails the test.
 */
#ifndef SCICAP_TESTS_CLI_CHILD_H
#define SCICAP_TESTS_CLI_CHILD_H

#include <jansson.h>
#include <stddef.h>
#include <sys/types.h>

typedef struct cli_child {
    pid_t pid;
    int status;         /* as from wait4 */
    long maxrss_kb;     /* the child's peak resident set */
    char err[8192];     /* its stderr */
    char out[8192];     /* its stdout */
    char dir[512];
} cli_child;

/* BUILD/name into buf ($BUILD, default "build"). 0 when it is an executable, else -1 after printing why. */
int cli_child_program(char *buf, size_t n, const char *name);
/* Start `prog args...` (args NULL-terminated; prog is also argv[0]). The child's working folder is ours. */
void cli_child_start(cli_child *c, const char *prog, const char *const *args, const char *dir);
/* Wait until the running child's stdout so far holds `needle` (the child must flush it): 0, or -1 after timeout_ms
 * (a bound for a stuck child, not a timing: the test fails on -1). */
int cli_child_wait_stdout(const cli_child *c, const char *needle, int timeout_ms);
/* Wait for it (status, peak RSS) and read its stdout and stderr back. */
void cli_child_finish(cli_child *c);
/* Start and finish. */
void cli_child_run(cli_child *c, const char *prog, const char *const *args, const char *dir);
/* The exit status, or -1 when it died of a signal. */
int cli_child_exit_code(const cli_child *c);

/* A test group's setup and teardown: BUILD/name into prog and a new folder from the mkdtemp template in dir
 * (0 or -1); then the folder removed with everything in it (0 or -1). */
int cli_child_setup(char *prog, size_t n, const char *name, char *dir);
int cli_child_remove_dir(const char *dir);

/* The command line fmt, ... run by /bin/sh (system(3)): its exit status, -1 when it did not exit. For tests that
 * redirect, pipe or grep; the child's output goes where the command line says. */
int cli_child_shell(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* A scene: scene_json written to dir/scene_name, then `scicap sim dir/scene_name -o dir/prob -q` (its output
 * discarded), so the group's tests reconstruct dir/prob. 0, or -1 (the file or the simulation failed). */
int cli_child_sim(const char *scicap, const char *dir, const char *scene_name, const char *scene_json);
/* The JSON file dir/name (a result.json, a problem.json), a new reference the caller decrefs; a file that is
 * missing or not JSON fails the test, naming it. */
json_t *cli_child_load_json(const char *dir, const char *name);
/* Start `prog args...` (args NULL-terminated, args[0] is argv[0]) with its stderr to the file log (stdout left as
 * ours), without waiting: for a test that signals it mid-run and reaps it itself. The pid; a failed fork fails the
 * test. */
pid_t cli_child_spawn_logged(const char *log, const char *prog, const char *const *args);
/* N of the last "checkpoint of step N" line in the log file (scicap recon's, with --checkpoint); 0 when none. */
int cli_child_checkpoint_step(const char *log);

#endif
