/* io/sandbox.h and the v7.3 reader behind it (io/matfile_sandbox.h):
 *  - a child's bytes come back whole; a child that crashes (SIGSEGV, as a libhdf5 heap overflow ends) is
 *    SCI_EFORMAT naming the signal; one that hangs is killed at the time limit (-ETIMEDOUT); the caller lives on;
 *  - byte-flipped copies of the fuzz corpus's valid v7.3 file (seeded; the seed printed) read in this process:
 *    every one a problem or an error with a message, the process never killed — a crash inside libhdf5 would
 *    end this test program, so its passing is the claim. */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "io/matfile.h"
#include "io/matfile_sandbox.h"
#include "io/sandbox.h"
#include "recon/problem.h"

#define FLIPS 60

static int writes_hello(void *arg, int fd)
{
    (void)arg;
    return write(fd, "hello", 5) == 5 ? 0 : -EIO;
}

static int crashes(void *arg, int fd)
{
    (void)arg;
    (void)write(fd, "par", 3);
    raise(SIGSEGV);
    return 0;
}

static int hangs(void *arg, int fd)
{
    (void)arg;
    (void)fd;
    for (;;)
        pause();
    return 0;
}

static void test_bytes_back(void **state)
{
    void *b;
    size_t n;
    sci_error err = {0};
    assert_int_equal(sci_sandbox_run(writes_hello, NULL, 30000, &b, &n, "x", &err), 0);
    assert_int_equal(n, 5);
    assert_memory_equal(b, "hello", 5);
    free(b);
}

static void test_crash_is_an_error(void **state)
{
    void *b;
    size_t n;
    sci_error err = {0};
    assert_int_equal(sci_sandbox_run(crashes, NULL, 30000, &b, &n, "bad.mat", &err), SCI_EFORMAT);
    print_message("  %s\n", err.msg);
    assert_non_null(strstr(err.msg, "bad.mat"));
    assert_non_null(strstr(err.msg, "crashed"));
    assert_null(b);
}

static void test_hang_is_killed(void **state)
{
    void *b;
    size_t n;
    sci_error err = {0};
    assert_int_equal(sci_sandbox_run(hangs, NULL, 300, &b, &n, "slow.mat", &err), -ETIMEDOUT);
    print_message("  %s\n", err.msg);
    assert_null(b);
}

static void test_flipped_v73_never_kills_the_reader(void **state)
{
    const char *src = "tests/fuzz/corpus/matfile/v73_valid.mat";
    FILE *f = fopen(src, "rb");
    assert_non_null(f);
    static unsigned char data[1 << 20];
    size_t len = fread(data, 1, sizeof data, f);
    fclose(f);
    assert_true(len > 512);
    assert_int_equal(sci_mat_is_v73(src, NULL), 1);
    sci_problem **pp;
    int k;
    sci_error err = {0};
    assert_int_equal(sci_mat_read_opts(src, NULL, &pp, &k, NULL, &err), 0); /* the original reads */
    assert_true(k >= 1);
    sci_problem_array_free(pp, k);
    unsigned seed = (unsigned)time(NULL);
    print_message("  seed %u\n", seed);
    srand(seed);
    char path[] = "/tmp/scicap-v73-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    int ok = 0, refused = 0;
    for (int i = 0; i < FLIPS; i++) {
        static unsigned char copy[1 << 20];
        memcpy(copy, data, len);
        for (int j = 0; j < 4; j++) /* past the 128-byte MATLAB header: into HDF5's structures and data */
            copy[128 + (size_t)rand() % (len - 128)] ^= (unsigned char)(1 + rand() % 255);
        f = fopen(path, "wb");
        assert_non_null(f);
        assert_int_equal(fwrite(copy, 1, len, f), len);
        fclose(f);
        memset(&err, 0, sizeof err);
        int rc = sci_mat_read_opts(path, NULL, &pp, &k, NULL, &err);
        if (rc == 0) {
            ok++;
            sci_problem_array_free(pp, k);
        } else {
            refused++;
            assert_true(err.msg[0] != '\0');
        }
    }
    unlink(path);
    print_message("  %d flipped files: %d read, %d refused with a message, none killed the reader\n", FLIPS, ok,
                  refused);
    assert_int_equal(ok + refused, FLIPS);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bytes_back),
        cmocka_unit_test(test_crash_is_an_error),
        cmocka_unit_test(test_hang_is_killed),
        cmocka_unit_test(test_flipped_v73_never_kills_the_reader),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
