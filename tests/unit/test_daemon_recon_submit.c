/* tests/unit/test_daemon_recon_submit.c — the job flow into the reconstruction queue (daemon/reconsubmit.h), run
 * in this process on a store in a temporary folder, without scicapd: a stored capture's reconstruction is made,
 * persisted under ROOT/recon-queue/, announced and queued; a full queue refuses, waits or leaves the job to the
 * caller by mode; a closed one keeps the entry of a job that waited; an import's reconstructions are announced
 * before they are queued. Also the acquisition thread's table from job kind to run function (daemon/acquire.h). */
#include <dirent.h>
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "daemon/acquire.h"
#include "daemon/calibrate.h"
#include "daemon/capture.h"
#include "daemon/reconq.h"
#include "daemon/reconsubmit.h"

typedef struct fixture {
    char dir[64];
    scicapd_store *store;
    scicapd_jobs *jobs;
    scicapd_mailbox *mailbox;
    scicapd_queue *queue;
    scicapd_recon_submit_env env;
    scicapd_recon_spec spec;
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    assert_non_null(f);
    snprintf(f->dir, sizeof f->dir, "/tmp/scicap-submit-XXXXXX");
    assert_non_null(mkdtemp(f->dir));
    sci_error err = {0};
    scicapd_store_recovery rec;
    if (scicapd_store_open(&f->store, f->dir, 0, NULL, &rec, &err) < 0)
        fail_msg("store: %s", err.msg);
    assert_int_equal(scicapd_jobs_new(&f->jobs), 0);
    assert_int_equal(scicapd_mailbox_new(&f->mailbox), 0);
    assert_int_equal(scicapd_queue_new(&f->queue, 2), 0);
    if (scicapd_recon_spec_resolve("gap-tv", "fast", NULL, NULL, "", &f->spec, &err) < 0)
        fail_msg("spec: %s", err.msg);
    f->env = (scicapd_recon_submit_env){.jobs = f->jobs, .store = f->store, .mailbox = f->mailbox,
                                        .queue = f->queue, .log = NULL};
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    scicapd_job *j;
    while ((j = scicapd_queue_take(f->queue)))
        scicapd_job_unref(f->jobs, j);
    scicapd_queue_free(f->queue);
    scicapd_mailbox_free(f->mailbox);
    scicapd_jobs_free(f->jobs);
    scicapd_store_close(f->store);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", f->dir);
    assert_int_equal(system(cmd), 0);
    free(f);
    return 0;
}

/* Files under ROOT/recon-queue/ whose name starts with "r-" (the saved entries). */
static int entries(const fixture *f)
{
    char path[128];
    snprintf(path, sizeof path, "%s/recon-queue", f->dir);
    DIR *d = opendir(path);
    if (!d)
        return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        n += strncmp(e->d_name, "r-", 2) == 0;
    closedir(d);
    return n;
}

/* Every letter posted so far, concatenated (caller frees). */
static char *letters(fixture *f, int *count)
{
    scicapd_letter *l = scicapd_mailbox_take(f->mailbox);
    size_t n = 1;
    for (scicapd_letter *p = l; p; p = p->next)
        n += strlen(p->line);
    char *s = calloc(1, n);
    assert_non_null(s);
    *count = 0;
    for (scicapd_letter *p = l; p; p = p->next, ++*count)
        strcat(s, p->line);
    scicapd_letters_free(l);
    return s;
}

static int jobs_in_table(fixture *f)
{
    json_t *a = scicapd_jobs_json(f->jobs, 0, 1);
    int n = (int)json_array_size(a);
    json_decref(a);
    return n;
}

static scicapd_recon_request request(const fixture *f, const char *capture, scicapd_enqueue_mode mode)
{
    return (scicapd_recon_request){.client = 7, .owner = 1000, .capture_id = capture, .spec = f->spec,
                                   .origin = "capture_job", .origin_job = 3, .mode = mode};
}

/* A capture stored with reconstruct on: its job is in the queue, persisted, announced naming the capture job. */
static void test_capture_done_queues_a_persisted_job(void **state)
{
    fixture *f = *state;
    scicapd_recon_request q = request(f, "c000001", SCICAPD_ENQUEUE_WAIT);
    const char *why = "unset";
    sci_error err = {0};
    assert_int_equal(scicapd_recon_submit(&f->env, &q, NULL, &why, &err), 0);
    assert_null(why);
    assert_int_equal(scicapd_queue_len(f->queue), 1);
    assert_int_equal(entries(f), 1);
    scicapd_job *j = scicapd_queue_take(f->queue);
    assert_int_equal(j->kind, SCICAPD_JOB_RECONSTRUCT);
    assert_string_equal(j->recon.capture_id, "c000001");
    assert_int_equal(j->owner, 1000);
    assert_int_equal(j->client, 7);
    assert_true(j->persisted[0] != 0);
    int n;
    char *s = letters(f, &n);
    assert_int_equal(n, 1);
    json_t *ev = json_loads(s, 0, NULL);
    free(s);
    json_t *data = json_object_get(ev, "data");
    assert_string_equal(json_string_value(json_object_get(ev, "event")), "recon.queued");
    assert_int_equal(json_integer_value(json_object_get(data, "capture_job")), 3);
    assert_string_equal(json_string_value(json_object_get(data, "capture")), "c000001");
    assert_string_equal(json_string_value(json_object_get(data, "method")), "gap-tv");
    json_decref(ev);
    /* the entry reads back as the job that was queued (a stop would resume it) */
    scicapd_reconq_item *items = NULL;
    int k = 0;
    assert_int_equal(scicapd_reconq_load(f->store, NULL, &items, &k, &err), 0);
    assert_int_equal(k, 1);
    assert_string_equal(items[0].capture_id, "c000001");
    assert_int_equal(items[0].owner, 1000);
    assert_string_equal(items[0].file, j->persisted);
    free(items);
    scicapd_job_unref(f->jobs, j);
}

/* The explicit request: a reply instead of an event; a full queue refuses and leaves nothing behind. */
static void test_request_refused_when_full(void **state)
{
    fixture *f = *state;
    scicapd_recon_request q = request(f, "c000002", SCICAPD_ENQUEUE_REFUSE);
    q.origin = NULL;
    sci_error err = {0};
    json_t *reply = NULL;
    for (int i = 0; i < 2; i++) {
        assert_int_equal(scicapd_recon_submit(&f->env, &q, &reply, NULL, &err), 0);
        assert_string_equal(json_string_value(json_object_get(reply, "state")), "queued");
        assert_string_equal(json_string_value(json_object_get(reply, "capture")), "c000002");
        assert_string_equal(json_string_value(json_object_get(reply, "method")), "gap-tv");
        json_decref(reply);
    }
    int before = jobs_in_table(f);
    const char *why = NULL;
    reply = NULL;
    assert_int_equal(scicapd_recon_submit(&f->env, &q, &reply, &why, &err), SCI_EBUSY);
    assert_null(reply);
    assert_string_equal(why, "reconstruction queue full");
    assert_non_null(strstr(err.msg, "(2 jobs)"));
    assert_int_equal(entries(f), 2);               /* the refused one's entry removed */
    assert_int_equal(jobs_in_table(f), before);    /* and its job forgotten */
    int n;
    free(letters(f, &n));
    assert_int_equal(n, 0);                        /* no origin: the caller replies, nothing is posted */
}

/* TRY leaves a job the queue has no room for to its caller, entry and all (an import runs it itself). */
static void test_try_leaves_the_job_to_the_caller(void **state)
{
    fixture *f = *state;
    scicapd_recon_request q = request(f, "c000003", SCICAPD_ENQUEUE_TRY);
    q.origin = "import_job";
    sci_error err = {0};
    scicapd_job *j[3];
    for (int i = 0; i < 3; i++)
        assert_int_equal(scicapd_recon_prepare(&f->env, &q, &j[i], NULL, &err), 0);
    /* announced before any is queued: recon.queued comes before import.done */
    int n;
    char *s = letters(f, &n);
    assert_int_equal(n, 3);
    assert_non_null(strstr(s, "import_job"));
    free(s);
    assert_int_equal(scicapd_queue_len(f->queue), 0);
    assert_int_equal(scicapd_recon_enqueue(&f->env, j[0], SCICAPD_ENQUEUE_TRY, NULL, &err), 0);
    assert_int_equal(scicapd_recon_enqueue(&f->env, j[1], SCICAPD_ENQUEUE_TRY, NULL, &err), 0);
    assert_int_equal(scicapd_recon_enqueue(&f->env, j[2], SCICAPD_ENQUEUE_TRY, NULL, &err), SCI_EBUSY);
    assert_int_equal(entries(f), 3);
    assert_int_equal(scicapd_job_state_get(f->jobs, j[2]), SCICAPD_JOB_QUEUED); /* still the caller's */
    scicapd_reconq_drop(f->store, j[2]);
    scicapd_jobs_forget(f->jobs, j[2]);
    scicapd_job_unref(f->jobs, j[2]);
    assert_int_equal(entries(f), 2);
}

/* A capture's reconstruction meeting a stopping daemon: rejected, its entry kept for the next start. */
static void test_wait_on_a_closed_queue_keeps_the_entry(void **state)
{
    fixture *f = *state;
    scicapd_queue_close(f->queue);
    scicapd_recon_request q = request(f, "c000004", SCICAPD_ENQUEUE_WAIT);
    const char *why = NULL;
    sci_error err = {0};
    int before = jobs_in_table(f);
    assert_int_equal(scicapd_recon_submit(&f->env, &q, NULL, &why, &err), -EPIPE);
    assert_string_equal(why, "daemon stopping; resumed at the next start");
    assert_int_equal(entries(f), 1);
    assert_int_equal(jobs_in_table(f), before);
}

/* The acquisition thread's table: capture and calibrate jobs to their run functions, nothing else. */
static void test_job_kind_table(void **state)
{
    (void)state;
    const scicapd_acquire_kind *k = scicapd_acquire_kind_get(SCICAPD_JOB_CAPTURE);
    assert_non_null(k);
    assert_ptr_equal(k->run, scicapd_capture_run);
    assert_string_equal(k->canceled_event, "capture.canceled");
    assert_non_null(k = scicapd_acquire_kind_get(SCICAPD_JOB_CALIBRATE));
    assert_ptr_equal(k->run, scicapd_calibrate_run);
    assert_string_equal(k->canceled_event, "calibrate.canceled");
    assert_null(scicapd_acquire_kind_get(SCICAPD_JOB_RECONSTRUCT));
    assert_null(scicapd_acquire_kind_get(SCICAPD_JOB_IMPORT));
    assert_null(scicapd_acquire_kind_get((scicapd_job_kind)99));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_capture_done_queues_a_persisted_job, setup, teardown),
        cmocka_unit_test_setup_teardown(test_request_refused_when_full, setup, teardown),
        cmocka_unit_test_setup_teardown(test_try_leaves_the_job_to_the_caller, setup, teardown),
        cmocka_unit_test_setup_teardown(test_wait_on_a_closed_queue_keeps_the_entry, setup, teardown),
        cmocka_unit_test(test_job_kind_table),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
