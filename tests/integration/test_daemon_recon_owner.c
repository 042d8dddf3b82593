/* Two users reconstruct the same capture with the same method: the second's result goes beside the first's
 * (recon/gap-tv, then recon/gap-tv.2), the first's files are left as they were, and each result names the uid
 * that asked — in result.json ("job": {"owner": uid}) and in recon.done ("owner"). Users are taken with
 * seteuid/setegid around connect() (SO_PEERCRED records them), which needs root. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "tests/helpers/daemon_child.h"

static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

/* reconstruct cap with gap-tv as this connection's user; recon.done's data (new ref) */
static json_t *reconstruct(hconn *c, const char *cap)
{
    json_decref(hconn_request(c, "watch", NULL));
    return daemon_child_reconstruct(c, cap, 5);
}

static json_t *result_of(const char *cap, const char *folder)
{
    char p[1200];
    snprintf(p, sizeof p, "%s/captures/%s/recon/%s/result.json", H.store, cap, folder);
    json_t *j = json_load_file(p, 0, NULL);
    if (!j)
        fail_msg("no %s", p);
    return j;
}

static void test_second_user_never_replaces_first(void **state)
{
    harness_require_root("connect as other uids (seteuid)");
    harness_start_open(&H, "{\"control\": {\"mode\": \"0666\"}}\n");
    hconn root;
    hconn_open(&root, &H);
    char cap[32];
    daemon_child_capture(&root, cap, sizeof cap, 30000);
    hconn a, b;
    hconn_open_as(&a, &H, HARNESS_UID_A, HARNESS_UID_A);
    json_t *da = reconstruct(&a, cap);
    json_t *ra = result_of(cap, "gap-tv");
    char *ra_text = json_dumps(ra, JSON_SORT_KEYS);
    hconn_open_as(&b, &H, HARNESS_UID_B, HARNESS_UID_B);
    json_t *db = reconstruct(&b, cap);
    print_message("  uid %d: %s (owner %lld); uid %d: %s (owner %lld)\n", HARNESS_UID_A,
                  json_string_value(json_object_get(da, "dir")),
                  (long long)json_integer_value(json_object_get(da, "owner")), HARNESS_UID_B,
                  json_string_value(json_object_get(db, "dir")),
                  (long long)json_integer_value(json_object_get(db, "owner")));
    assert_int_equal(json_integer_value(json_object_get(da, "owner")), HARNESS_UID_A);
    assert_int_equal(json_integer_value(json_object_get(db, "owner")), HARNESS_UID_B);
    /* A's result as it was; B's beside it */
    json_t *ra2 = result_of(cap, "gap-tv");
    char *ra2_text = json_dumps(ra2, JSON_SORT_KEYS);
    assert_string_equal(ra_text, ra2_text);
    json_t *rb = result_of(cap, "gap-tv.2");
    assert_int_equal(json_integer_value(json_object_get(json_object_get(ra2, "job"), "owner")), HARNESS_UID_A);
    assert_int_equal(json_integer_value(json_object_get(json_object_get(rb, "job"), "owner")), HARNESS_UID_B);
    free(ra_text);
    free(ra2_text);
    json_decref(ra);
    json_decref(ra2);
    json_decref(rb);
    json_decref(da);
    json_decref(db);
    hconn_close(&a);
    hconn_close(&b);
    hconn_close(&root);
    harness_stop(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_second_user_never_replaces_first, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
