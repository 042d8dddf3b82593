/* The daemon's import of external data: `scicap capture --from FILE` stores a .mat or a problem folder
 * as captures and reconstructs them, with the options `scicap recon` has for a .mat, and the daemon reads the
 * files through descriptors the client opened (SCM_RIGHTS), never by path:
 *   - drop40 rewritten as a lab ships it ([0, 1] values, y/X in one file, the masks as Phi in another) imports
 *     with --mask/--mask-var/--meas-var/--truth-var/--scale auto (white 1 found) and reconstructs snapshot 1 to
 *     the PSNR of the original file imported with no option (34.63 dB, GAP-TV defaults);
 *   - a daemon running as uid 65534 imports a root-only file (0600 in a 0700 folder) that a root client passes,
 *     and what it reads is what the descriptor holds: the path was replaced after the client opened it;
 *   - refusals: descriptors that do not match the names, something that is not a regular file, a missing
 *     variable (the message lists what the file holds and the option), .mat options on a folder;
 *   - a problem folder's files import with their values unchanged. */
#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>
#include <matio.h>

#include "tests/helpers/daemon_child.h"
#include "io/matfile.h"
#include "io/problem_dir.h"
#include "tests/helpers/cli_child.h"
#include "tests/helpers/testdata.h"

#define NOBODY 65534

static harness H;
static char scicap[1024];

static const char *err_code(const json_t *reply)
{
    return json_string_value(json_object_get(json_object_get(reply, "error"), "code"));
}

/* Copy variable `from` of file `src` into `dst` (created or appended) as `to`: drop40's variables renamed. */
static void copy_var(const char *src, const char *from, mat_t *dst, const char *to)
{
    mat_t *m = Mat_Open(src, MAT_ACC_RDONLY);
    assert_non_null(m);
    matvar_t *v = Mat_VarRead(m, from);
    assert_non_null(v);
    matvar_t *c = Mat_VarCreate(to, v->class_type, v->data_type, v->rank, v->dims, v->data, MAT_F_DONT_COPY_DATA);
    assert_non_null(c);
    assert_int_equal(Mat_VarWrite(dst, c, MAT_COMPRESSION_ZLIB), 0);
    Mat_VarFree(c);
    Mat_VarFree(v);
    Mat_Close(m);
}

/* drop40 on [0, 1] as DIR/data.mat {y, X} and DIR/mask.mat {Phi}. */
static void write_lab_files(const char *drop40)
{
    sci_problem **p;
    int k;
    sci_error err = {0};
    char plain[600], data[600], mask[600];
    if (sci_mat_read(drop40, 255, &p, &k, &err) < 0)
        fail_msg("%s", err.msg);
    snprintf(plain, sizeof plain, "%s/plain01.mat", H.dir);
    snprintf(data, sizeof data, "%s/data.mat", H.dir);
    snprintf(mask, sizeof mask, "%s/mask.mat", H.dir);
    if (sci_mat_write(plain, p, k, 1.0, &err) < 0) /* mask, meas, orig on [0, 1] */
        fail_msg("%s", err.msg);
    sci_problem_array_free(p, k);
    mat_t *d = Mat_CreateVer(data, NULL, MAT_FT_MAT5), *mk = Mat_CreateVer(mask, NULL, MAT_FT_MAT5);
    assert_non_null(d);
    assert_non_null(mk);
    copy_var(plain, "meas", d, "y");
    copy_var(plain, "orig", d, "X");
    copy_var(plain, "mask", mk, "Phi");
    Mat_Close(d);
    Mat_Close(mk);
}

/* The capture id stored for snapshot `n` (1-based) in `scicap capture --from` output. */
static void capture_of_snapshot(const char *out, int n, char *id)
{
    char key[64];
    snprintf(key, sizeof key, "), snapshot %d of", n);
    const char *at = strstr(out, key);
    if (!at)
        fail_msg("no snapshot %d in: %s", n, out);
    const char *st = at;
    while (st > out && strncmp(st, "stored ", 7) != 0)
        st--;
    assert_int_equal(sscanf(st, "stored %31s", id), 1);
}

static double recon_psnr(const harness *h, const char *id)
{
    json_t *j = daemon_child_result(h, id, "gap-tv");
    double v = json_number_value(json_object_get(json_object_get(j, "psnr_frame_max_db"), "mean"));
    json_decref(j);
    return v;
}

static void test_mat_options_reconstruct_as_the_original(void **state)
{
    char drop40[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", drop40);
    write_lab_files(drop40);
    char data[600], mask[600], id_lab[32], id_orig[32];
    snprintf(data, sizeof data, "%s/data.mat", H.dir);
    snprintf(mask, sizeof mask, "%s/mask.mat", H.dir);
    cli_child c;
    cli_child_run(&c, scicap,
                  (const char *const[]){"capture", "--socket", H.sock, "--from", data, "--mask", mask, "--mask-var",
                                        "Phi", "--meas-var", "y", "--truth-var", "X", "--scale", "auto", "--recon",
                                        "--wait", NULL},
                  H.dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d\nstdout: %s\nstderr: %s", cli_child_exit_code(&c), c.out, c.err);
    if (!strstr(c.out, "imported 5 snapshots, values divided by 1:"))
        fail_msg("--scale auto did not report white 1: %s", c.out);
    capture_of_snapshot(c.out, 1, id_lab);
    /* the original, with no option; only its snapshot 1 reconstructed, on request */
    cli_child_run(&c, scicap, (const char *const[]){"capture", "--socket", H.sock, "--from", drop40, "--wait", NULL},
                  H.dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d\nstdout: %s\nstderr: %s", cli_child_exit_code(&c), c.out, c.err);
    assert_non_null(strstr(c.out, "values divided by 255"));
    capture_of_snapshot(c.out, 1, id_orig);
    cli_child_run(&c, scicap, (const char *const[]){"recon", "--socket", H.sock, "--capture", id_orig, "--wait", NULL},
                  H.dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d\nstdout: %s\nstderr: %s", cli_child_exit_code(&c), c.out, c.err);
    double lab = recon_psnr(&H, id_lab), orig = recon_psnr(&H, id_orig);
    print_message("  snapshot 1: %.4f dB from y/X + Phi at [0, 1] (%s), %.4f dB from the original (%s)\n", lab,
                  id_lab, orig, id_orig);
    assert_true(fabs(lab - orig) < 1e-3);
    assert_true(fabs(orig - 34.66) < 0.01); /* GAP-TV balanced (130 iterations) on drop40 snapshot 1, as test_gaptv */
}

/* A daemon of our own, as uid 65534, on a storage it owns. */
static pid_t start_as_nobody(const char *dir, char *sock, size_t n)
{
    char store[600], run[600], logp[600];
    snprintf(sock, n, "%s/c.sock", dir);
    snprintf(store, sizeof store, "%s/store", dir);
    snprintf(run, sizeof run, "%s/run", dir);
    snprintf(logp, sizeof logp, "%s/scicapd.log", dir);
    pid_t parent = getpid(), pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        int fd = open(logp, O_WRONLY | O_CREAT | O_APPEND, 0644);
        dup2(fd, 2);
        if (setgroups(0, NULL) != 0 || setgid(NOBODY) != 0 || setuid(NOBODY) != 0)
            _exit(126);
        harness_child_tie(parent); /* after the change of user, which clears the parent-death signal */
        execl(H.bin, H.bin, "--no-config", "--socket", sock, "--storage", store, "--runtime-dir", run, "--no-fsync",
              (char *)NULL);
        _exit(127);
    }
    for (int i = 0; i < 200; i++) {
        int fd = h_connect_raw(sock);
        if (fd >= 0) {
            close(fd);
            return pid;
        }
        h_sleep_ms(50);
    }
    fail_msg("scicapd as uid %d did not start; log %s", NOBODY, logp);
    return -1;
}

static void test_reads_through_the_clients_descriptor(void **state)
{
    if (geteuid() != 0) {
        print_message("  needs root to run the daemon as uid %d and own a file it cannot read; uid %d here\n",
                      NOBODY, (int)geteuid());
        skip();
    }
    char drop40[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", drop40);
    /* the daemon's folder (its own) and a private one holding the data (root only) */
    char ddir[600], pdir[600], priv[700], sock[700];
    snprintf(ddir, sizeof ddir, "%s/nobody", H.dir);
    snprintf(pdir, sizeof pdir, "%s/private", H.dir);
    snprintf(priv, sizeof priv, "%s/drop40.mat", pdir);
    assert_int_equal(mkdir(ddir, 0700), 0);
    assert_int_equal(chown(ddir, NOBODY, NOBODY), 0);
    assert_int_equal(chmod(H.dir, 0711), 0); /* nobody may pass through to its folder, not list ours */
    assert_int_equal(mkdir(pdir, 0700), 0);
    char cmd[9000];
    snprintf(cmd, sizeof cmd, "cp '%s' '%s' && chmod 600 '%s'", drop40, priv, priv);
    assert_int_equal(system(cmd), 0);
    pid_t pid = start_as_nobody(ddir, sock, sizeof sock);
    /* open, then put something else at the path: only the descriptor holds drop40 now */
    int fd = open(priv, O_RDONLY | O_CLOEXEC);
    assert_true(fd >= 0);
    char junk[700];
    snprintf(junk, sizeof junk, "%s/junk", pdir);
    FILE *f = fopen(junk, "w");
    assert_non_null(f);
    fputs("not a MAT file\n", f);
    fclose(f);
    assert_int_equal(rename(junk, priv), 0);
    hconn c = {.fd = h_connect_raw(sock), .next_id = 1};
    assert_true(c.fd >= 0);
    json_t *r = hconn_import_fds(&c, json_pack("{s:[s]}", "files", "drop40.mat"), &fd, 1);
    close(fd);
    if (!json_is_true(json_object_get(r, "ok")))
        fail_msg("import refused: %s", json_dumps(r, JSON_COMPACT));
    json_decref(r);
    json_t *e = hconn_wait_event(&c, "import.done", 60000);
    json_t *caps = json_object_get(json_object_get(e, "data"), "captures");
    assert_int_equal(json_array_size(caps), 5);
    /* what was stored is drop40's snapshot 1, values /255 */
    char capdir[1200];
    snprintf(capdir, sizeof capdir, "%s/store/captures/%s", ddir, json_string_value(json_array_get(caps, 0)));
    sci_problem **a, **b;
    int ka, kb;
    sci_error err = {0};
    if (sci_problem_dir_read(capdir, &a, &ka, &err) < 0 || sci_mat_read(drop40, 255, &b, &kb, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(ka, 1);
    assert_int_equal(memcmp(a[0]->meas->data, b[0]->meas->data, sci_cube_count(b[0]->meas) * sizeof(float)), 0);
    assert_int_equal(memcmp(a[0]->mask->data, b[0]->mask->data, sci_cube_count(b[0]->mask) * sizeof(float)), 0);
    print_message("  daemon uid %d imported a 0600 root file through the descriptor: %zu captures, meas and mask "
                  "bit-identical\n", NOBODY, json_array_size(caps));
    sci_problem_array_free(a, ka);
    sci_problem_array_free(b, kb);
    json_decref(e);
    hconn_close(&c);
    kill(pid, SIGTERM);
    int st;
    assert_int_equal(waitpid(pid, &st, 0), pid);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
}

static void test_refusals(void **state)
{
    char drop40[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", drop40);
    hconn c;
    hconn_open(&c, &H);
    int fd = open(drop40, O_RDONLY | O_CLOEXEC);
    assert_true(fd >= 0);
    /* a refused request closes the descriptors it brought and nothing of the daemon's own (its stdin here) */
    char fd0[64], before[512] = "", after[512] = "";
    snprintf(fd0, sizeof fd0, "/proc/%d/fd/0", (int)H.pid);
    assert_true(readlink(fd0, before, sizeof before - 1) > 0);
    /* two names, one descriptor */
    json_t *r = hconn_import_fds(&c, json_pack("{s:[s,s], s:s}", "files", "a.mat", "b.mat", "mask", "b.mat"), &fd, 1);
    assert_string_equal(err_code(r), "bad_arguments");
    assert_non_null(strstr(json_string_value(json_object_get(json_object_get(r, "error"), "message")),
                           "descriptors passed"));
    json_decref(r);
    /* no descriptor at all: the daemon opens no path */
    r = hconn_import_fds(&c, json_pack("{s:[s]}", "files", "drop40.mat"), NULL, 0);
    assert_string_equal(err_code(r), "bad_arguments");
    json_decref(r);
    /* .mat options on a folder */
    r = hconn_import_fds(&c, json_pack("{s:[s], s:s, s:s}", "files", "problem.json", "kind", "folder", "meas_var", "y"),
                      &fd, 1);
    assert_string_equal(err_code(r), "bad_arguments");
    json_decref(r);
    /* a pipe: refused by the worker, never read (it could block it) */
    int p[2];
    assert_int_equal(pipe(p), 0);
    r = hconn_import_fds(&c, json_pack("{s:[s]}", "files", "pipe.mat"), &p[0], 1);
    assert_true(json_is_true(json_object_get(r, "ok")));
    json_decref(r);
    json_t *e = hconn_wait_event_ex(&c, "import.failed", 30000, 1);
    assert_non_null(strstr(json_string_value(json_object_get(json_object_get(e, "data"), "error")),
                           "not a regular file"));
    json_decref(e);
    close(p[0]);
    close(p[1]);
    /* a missing variable: what the file holds, and the option */
    r = hconn_import_fds(&c, json_pack("{s:[s], s:s}", "files", "drop40.mat", "meas_var", "y"), &fd, 1);
    assert_true(json_is_true(json_object_get(r, "ok")));
    json_decref(r);
    e = hconn_wait_event_ex(&c, "import.failed", 30000, 1);
    const char *msg = json_string_value(json_object_get(json_object_get(e, "data"), "error"));
    print_message("  missing variable: %s\n", msg);
    if (!strstr(msg, "meas") || !strstr(msg, "--meas-var") || !strstr(msg, "drop40.mat") || strstr(msg, "import-"))
        fail_msg("message: %s", msg);
    json_decref(e);
    close(fd);
    hconn_close(&c);
    if (readlink(fd0, after, sizeof after - 1) <= 0 || strcmp(before, after) != 0)
        fail_msg("the daemon's fd 0 was %s, is now %s", before, after[0] ? after : "closed");
}

static void test_problem_folder(void **state)
{
    char drop40[4096], folder[600];
    TESTDATA_REQUIRE("drop40_cacti.mat", drop40);
    sci_problem **p;
    int k;
    sci_error err = {0};
    if (sci_mat_read(drop40, 255, &p, &k, &err) < 0)
        fail_msg("%s", err.msg);
    snprintf(folder, sizeof folder, "%s/folder", H.dir);
    if (sci_problem_dir_write_opt(folder, p, 2, NULL, 1, 1, &err) < 0)
        fail_msg("%s", err.msg);
    cli_child c;
    cli_child_run(&c, scicap, (const char *const[]){"capture", "--socket", H.sock, "--from", folder, "--wait", NULL},
                  H.dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d\nstdout: %s\nstderr: %s", cli_child_exit_code(&c), c.out, c.err);
    char id[32], capdir[1200];
    capture_of_snapshot(c.out, 2, id);
    snprintf(capdir, sizeof capdir, "%s/captures/%s", H.store, id);
    sci_problem **q;
    int kq;
    if (sci_problem_dir_read(capdir, &q, &kq, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(memcmp(q[0]->meas->data, p[1]->meas->data, sci_cube_count(p[1]->meas) * sizeof(float)), 0);
    assert_int_equal(memcmp(q[0]->truth->data, p[1]->truth->data, sci_cube_count(p[1]->truth) * sizeof(float)), 0);
    sci_problem_array_free(q, kq);
    sci_problem_array_free(p, k);
    /* .mat options with a folder: refused by the client before anything is sent */
    cli_child_run(&c, scicap, (const char *const[]){"capture", "--socket", H.sock, "--from", folder, "--scale", "1",
                                                    NULL},
                  H.dir);
    assert_int_equal(cli_child_exit_code(&c), 2);
    assert_non_null(strstr(c.err, "problem folder"));
}

static int setup(void **state) { return daemon_child_setup(&H, scicap, sizeof scicap, NULL); }
static int teardown(void **state) { return daemon_child_teardown(&H); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mat_options_reconstruct_as_the_original),
        cmocka_unit_test(test_reads_through_the_clients_descriptor),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_problem_folder),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
