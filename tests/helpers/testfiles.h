/* tests/helpers/testfiles.h — small inputs that tests write for scicap and scicapd: a problem folder of a chosen
 * size, and a compressed .mat that declares many snapshots in a few KB (to provoke the size limits of
 * io/limits.h without a large file).
 *
 * For use inside cmocka tests: a write that fails fails the test (fail_msg / assert), nothing is returned. The
 * caller owns the paths and removes them (with its temporary folder). */
#ifndef SCICAP_TESTS_TESTFILES_H
#define SCICAP_TESTS_TESTFILES_H

#include <matio.h>
#include <stddef.h>

/* A problem folder at `path` (io/problem_dir.h): k problems named limits#1..k, each with the same w×h×n binary
 * mask (a fixed hash of the index, no RNG) and a one-frame measurement of (i % 7) * 0.5, peak 1. */
void testfiles_write_problem(const char *path, int w, int h, int n, int k);

/* A MAT 5 file (zlib) with mask 8×8×8 (0/1) and meas 8×8×snapshots, every value 4 (a plausible measurement:
 * without the limits it imports); mode 0644, so another uid can read it. A few KB for 5,000 snapshots. */
void testfiles_write_declared_mat(const char *path, size_t snapshots);

/* One variable `name` (rank dims, data in the class's C type, column-major as MATLAB) written to the open file m
 * with the given compression; a failure fails the test. matio copies nothing: data must live until it returns. */
void testfiles_mat_put(mat_t *m, const char *name, enum matio_classes cls, enum matio_types type, int rank,
                       size_t *dims, void *data, enum matio_compression compression);

/* Fails the test unless nothing named out, out.tmp-* or out.old-* exists: a refused or failed run published
 * nothing and left no staging folder behind. */
void testfiles_assert_nothing_at(const char *out);

/* Fails the test, quoting `text` and the first missing piece, unless text holds every string of `want` (a
 * NULL-terminated list). For reports and usage texts whose lines a test names one by one. */
void testfiles_expect_all(const char *text, const char *const *want);

#endif
