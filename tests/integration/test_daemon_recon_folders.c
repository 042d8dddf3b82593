/* A capture's reconstructions are kept side by side (docs/capture-folder.md): the first by a method in
 * recon/METHOD, the next in recon/METHOD.2, .3, ...; nothing is replaced, whoever asks, and recon.done names the
 * folder. Two reconstructions that finish at once get different folders (two workers). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "daemon/reconout.h"
#include "tests/helpers/daemon_child.h"

static harness H;
static char scicap[1024];

static json_int_t iterations_of(const char *cap, const char *folder)
{
    json_t *r = daemon_child_result(&H, cap, folder);
    json_int_t n = json_integer_value(json_object_get(r, "iterations"));
    json_decref(r);
    return n;
}

static void second_goes_beside_the_first(void **state)
{
    hconn c;
    hconn_open(&c, &H);
    char cap[32];
    daemon_child_capture(&c, cap, sizeof cap, 30000);
    json_t *a = daemon_child_reconstruct(&c, cap, 4), *b = daemon_child_reconstruct(&c, cap, 6);
    print_message("  %s: first -> %s, second -> %s\n", cap, json_string_value(json_object_get(a, "folder")),
                  json_string_value(json_object_get(b, "folder")));
    assert_string_equal(json_string_value(json_object_get(a, "folder")), "gap-tv");
    assert_string_equal(json_string_value(json_object_get(b, "folder")), "gap-tv.2");
    char want[700];
    snprintf(want, sizeof want, "%s/captures/%s/recon/gap-tv.2", H.store, cap);
    assert_string_equal(json_string_value(json_object_get(b, "dir")), want);
    /* both kept, each its own run */
    assert_int_equal(iterations_of(cap, "gap-tv"), 4);
    assert_int_equal(iterations_of(cap, "gap-tv.2"), 6);
    /* another method starts its own numbering */
    json_t *r = hconn_request(&c, "reconstruct", json_pack("{s:s, s:s, s:{s:i}}", "capture", cap, "method", "admm-tv",
                                                          "params", "iters", 3));
    json_decref(r);
    json_t *e = hconn_wait_event(&c, "recon.done", 60000);
    assert_string_equal(json_string_value(json_object_get(json_object_get(e, "data"), "folder")), "admm-tv");
    json_decref(e);
    json_decref(a);
    json_decref(b);
    hconn_close(&c);
}

/* Two workers finishing the same capture's reconstructions together: two folders, numbered on. */
static void concurrent_ones_get_their_own(void **state)
{
    hconn c;
    hconn_open(&c, &H);
    char cap[32];
    daemon_child_capture(&c, cap, sizeof cap, 30000);
    for (int round = 0; round < 3; round++) {
        json_int_t jobs[2];
        for (int i = 0; i < 2; i++) {
            json_t *r = hconn_request(&c, "reconstruct", json_pack("{s:s, s:s, s:{s:i}}", "capture", cap, "method",
                                                                  "gap-tv", "params", "iters", 5));
            jobs[i] = json_integer_value(json_object_get(r, "job"));
            json_decref(r);
        }
        char seen[2][32] = {"", ""};
        for (int done = 0; done < 2;) {
            json_t *e = hconn_wait_event(&c, "recon.done", 60000);
            json_int_t j = json_integer_value(json_object_get(e, "job"));
            for (int i = 0; i < 2; i++)
                if (j == jobs[i]) {
                    snprintf(seen[i], sizeof seen[i], "%s",
                             json_string_value(json_object_get(json_object_get(e, "data"), "folder")));
                    done++;
                }
            json_decref(e);
        }
        print_message("  round %d: %s and %s\n", round, seen[0], seen[1]);
        assert_string_not_equal(seen[0], seen[1]);
    }
    /* six runs, six folders: gap-tv, gap-tv.2 ... gap-tv.6 */
    for (int k = 1; k <= 6; k++) {
        char f[32];
        snprintf(f, sizeof f, k == 1 ? "gap-tv" : "gap-tv.%d", k);
        if (!daemon_child_recon_exists(&H, cap, f))
            fail_msg("no recon/%s of %s", f, cap);
    }
    assert_false(daemon_child_recon_exists(&H, cap, "gap-tv.7"));
    hconn_close(&c);
}

/* The folder names: what is one of a method's, and the next one with folders deleted in between. */
static void names_follow_the_largest(void **state)
{
    assert_int_equal(scicapd_reconout_ordinal("gap-tv", "gap-tv"), 1);
    assert_int_equal(scicapd_reconout_ordinal("gap-tv.2", "gap-tv"), 2);
    assert_int_equal(scicapd_reconout_ordinal("gap-tv.12", "gap-tv"), 12);
    const char *not_ours[] = {"gap-tv.", "gap-tv.1", "gap-tv.02", "gap-tv.x", "gap-tv.2.tmp-12", "admm-tv", "gap-t",
                              "gap-tvx", ".gap-tv.3"};
    for (size_t i = 0; i < sizeof not_ours / sizeof not_ours[0]; i++)
        assert_int_equal(scicapd_reconout_ordinal(not_ours[i], "gap-tv"), 0);
    char dir[400], path[600], name[96];
    snprintf(dir, sizeof dir, "%s/names", H.dir);
    const char *made[] = {"", "/recon", "/recon/gap-tv", "/recon/gap-tv.3", "/recon/gap-tv.5.tmp-1",
                          "/recon/admm-tv.9"};
    for (size_t i = 0; i < sizeof made / sizeof made[0]; i++) {
        snprintf(path, sizeof path, "%s%s", dir, made[i]);
        assert_int_equal(mkdir(path, 0750), 0);
    }
    scicapd_reconout *ro;
    sci_error err = {0};
    assert_int_equal(scicapd_reconout_new(&ro), 0);
    assert_int_equal(scicapd_reconout_reserve(ro, dir, "gap-tv", name, sizeof name, &err), 0);
    assert_string_equal(name, "gap-tv.4"); /* after the largest, not in the hole at .2 */
    char second[96];
    assert_int_equal(scicapd_reconout_reserve(ro, dir, "gap-tv", second, sizeof second, &err), 0);
    assert_string_equal(second, "gap-tv.5"); /* .4 is held; a temporary is not a folder */
    scicapd_reconout_release(ro, dir, name);
    scicapd_reconout_release(ro, dir, second);
    assert_int_equal(scicapd_reconout_reserve(ro, dir, "admm-tv", name, sizeof name, &err), 0);
    assert_string_equal(name, "admm-tv.10");
    assert_int_equal(scicapd_reconout_reserve(ro, dir, "scinerf", name, sizeof name, &err), 0);
    assert_string_equal(name, "scinerf");
    scicapd_reconout_free(ro);
}

static int setup(void **state)
{
    return daemon_child_setup(&H, scicap, sizeof scicap, "{\"reconstruction\": {\"workers\": 2}}\n");
}
static int teardown(void **state) { return daemon_child_teardown(&H); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(second_goes_beside_the_first),
        cmocka_unit_test(concurrent_ones_get_their_own),
        cmocka_unit_test(names_follow_the_largest),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
