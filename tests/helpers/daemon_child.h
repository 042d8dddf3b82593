/* tests/helpers/daemon_child.h — what the daemon's integration tests repeat around tests/integration/
 * daemon_harness.h: a test group that starts one scicapd and runs the scicap client against it, a capture taken
 * to storage, and the reconstruction folders it leads to.
 *
 *     static harness H;
 *     static char scicap[1024];
 *     static int setup(void **s) { return daemon_child_setup(&H, scicap, sizeof scicap, NULL); }
 *     static int teardown(void **s) { return daemon_child_teardown(&H); }
 *     ...
 *     char cap[32];
 *     daemon_child_capture(&c, cap, sizeof cap, 30000);          // stored, not reconstructed
 *     if (daemon_child_wait_recon(&H, cap, "gap-tv", 30000)) { json_t *r = daemon_child_result(&H, cap, "gap-tv"); }
 *
 * For use inside cmocka tests: what cannot go on fails the test. Paths: ROOT/captures/<id>/recon/<method>/
 * (docs/capture-folder.md).
 */
#ifndef SCICAP_TESTS_DAEMON_CHILD_H
#define SCICAP_TESTS_DAEMON_CHILD_H

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "recon/problem.h"
#include "tests/integration/daemon_harness.h"

/* A group's setup: BUILD/scicap into scicap (n bytes), then scicapd started in a new folder with config text
 * (NULL: none). 0, or -1 when scicap is not built (said on stderr). */
int daemon_child_setup(harness *h, char *scicap, size_t n, const char *config);
/* A group's teardown: SIGTERM (the test fails unless scicapd exits 0), then its folder removed. 0. */
int daemon_child_teardown(harness *h);

/* Ask for one capture of the default mask set, not reconstructed, and wait up to timeout_ms until it is stored;
 * its id into id (n bytes). Returns id. */
const char *daemon_child_capture(hconn *c, char *id, size_t n, int timeout_ms);

/* The reconstructions the daemon resumed at its start (status: recovered.reconstructions_resumed); -1 when the
 * status does not say. */
int daemon_child_resumed(hconn *c);

/* 1 when the reconstruction of capture `cap` by `method` has its result.json. */
int daemon_child_recon_exists(const harness *h, const char *cap, const char *method);
/* Wait up to timeout_ms for it: 1 when it came, 0 when not. */
int daemon_child_wait_recon(const harness *h, const char *cap, const char *method, int timeout_ms);
/* That result.json (new reference); fails the test when it is missing or unreadable. */
json_t *daemon_child_result(const harness *h, const char *cap, const char *method);

/* Reconstruct capture `cap` with gap-tv at `iters` iterations and wait (60 s at most) for that job's recon.done:
 * its data (new reference). A refusal, a recon.failed or no event in time fails the test. */
json_t *daemon_child_reconstruct(hconn *c, const char *cap, int iters);
/* Capture `id` as stored (ROOT/captures/<id>, one problem): the caller frees it (sci_problem_free). A capture that
 * cannot be read fails the test. */
sci_problem *daemon_child_read_capture(const harness *h, const char *id);

#endif
