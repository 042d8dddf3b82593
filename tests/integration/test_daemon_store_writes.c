/* What scicapd writes per snapshot, over the real socket and storage:
 *  - the reconstruction's masks (mask.json, mask_*.exr, preview_mask_*.png) are written once per mask stack to
 *    ROOT/mask_stacks/<hash>/ and hard-linked into each capture folder, which stays self-contained (read back as
 *    a problem folder, masks equal; deleting one capture leaves the others whole); a shared folder that no longer
 *    holds the masks (damaged between runs) is not linked: the next capture writes its own, correct masks;
 *  - the GIF previews (fixed grey palette) decode to the 8-bit values of the frames they show, for the capture's
 *    truth and the reconstruction;
 *  - a reconstruction whose output was published before the daemon died, with its queue entry still there (a
 *    kill -9 between the two), is not run again at restart, while another entry for the same capture is. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <dirent.h>

#include "io/image.h"
#include "io/problem_dir.h"
#include "io/staging.h"
#include "tests/helpers/daemon_child.h"
#include "tests/integration/daemon_harness.h"

static harness H;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&H);
    memset(&H, 0, sizeof H);
    return 0;
}

/* Capture `count` snapshots; their ids into ids[index]. */
static void capture(hconn *c, int count, char ids[][32])
{
    json_decref(hconn_request(c, "capture", json_pack("{s:i}", "count", count)));
    for (int i = 0; i < count; i++) {
        json_t *e = hconn_wait_event(c, "capture.stored", 30000);
        json_t *d = json_object_get(e, "data");
        snprintf(ids[json_integer_value(json_object_get(d, "index"))], 32, "%s",
                 json_string_value(json_object_get(d, "capture")));
        json_decref(e);
    }
    json_decref(hconn_wait_event(c, "capture.done", 30000));
}

/* scicapd started, one capture taken and reconstructed with GAP-TV (fast): its id into id (32 bytes). */
static void start_capture_reconstruct(hconn *c, char *id)
{
    harness_start(&H, NULL, NULL);
    hconn_open(c, &H);
    char ids[1][32];
    capture(c, 1, ids);
    snprintf(id, 32, "%s", ids[0]);
    json_decref(hconn_request(c, "reconstruct", json_pack("{s:s, s:s, s:s}", "capture", id, "method", "gap-tv",
                                                            "preset", "fast")));
    json_decref(hconn_wait_event(c, "recon.done", 60000));
}

static struct stat stat_of(const char *fmt, const char *a, const char *b)
{
    char p[1024];
    snprintf(p, sizeof p, fmt, a, b);
    struct stat st;
    if (stat(p, &st) != 0)
        fail_msg("%s: %s", p, strerror(errno));
    return st;
}

/* The one folder under ROOT/mask_stacks (there must be exactly one), into buf. */
static void the_mask_stack(const harness *h, char *buf, size_t n)
{
    char d[512];
    snprintf(d, sizeof d, "%s/mask_stacks", h->store);
    DIR *dir = opendir(d);
    assert_non_null(dir);
    int found = 0;
    struct dirent *e;
    while ((e = readdir(dir)))
        if (e->d_name[0] != '.') {
            snprintf(buf, n, "%s/%s", d, e->d_name);
            found++;
        }
    closedir(dir);
    assert_int_equal(found, 1);
}

static void assert_cubes_equal(const sci_cube *a, const sci_cube *b, const char *what)
{
    assert_int_equal(a->w, b->w);
    assert_int_equal(a->h, b->h);
    assert_int_equal(a->n, b->n);
    if (memcmp(a->data, b->data, sci_cube_count(a) * sizeof(float)) != 0)
        fail_msg("%s differ", what);
}

static void mask_stack_linked_once_per_set(void **state)
{
    (void)state;
    harness_start(&H, NULL, NULL);
    hconn c;
    hconn_open(&c, &H);
    char ids[3][32];
    capture(&c, 3, ids);
    char shared[700];
    the_mask_stack(&H, shared, sizeof shared);
    sci_problem *p0 = daemon_child_read_capture(&H, ids[0]);
    const int n = p0->mask->n;
    char name[64];
    for (int f = -1; f < n; f++) {
        for (int pv = 0; pv < 2; pv++) {
            if (f < 0 && pv)
                continue;
            snprintf(name, sizeof name, f < 0 ? "mask.json" : pv ? "preview_mask_%03d.png" : "mask_%03d.exr", f);
            struct stat s0 = stat_of("%s/%s", shared, name);
            for (int i = 0; i < 3; i++) {
                char cap[600];
                snprintf(cap, sizeof cap, "%s/captures/%s", H.store, ids[i]);
                struct stat si = stat_of("%s/%s", cap, name);
                if (si.st_ino != s0.st_ino)
                    fail_msg("%s/%s is not a link to %s/%s", cap, name, shared, name);
            }
            assert_true(s0.st_nlink >= 4); /* the shared folder and the three captures */
        }
    }
    printf("  3 captures of one mask set: %d mask files each, all hard links to %s\n", 2 * n + 1, shared);
    /* self-contained: a deleted capture takes only its links; the others read back whole, masks equal */
    char gone[600];
    snprintf(gone, sizeof gone, "%s/captures/%s", H.store, ids[0]);
    assert_int_equal(sci_staging_remove(gone), 0);
    for (int i = 1; i < 3; i++) {
        sci_problem *p = daemon_child_read_capture(&H, ids[i]);
        assert_cubes_equal(p->mask, p0->mask, "masks of two captures of one mask set");
        sci_problem_free(p);
    }
    /* a shared folder that no longer holds these masks (changed between runs): not linked after a restart */
    hconn_close(&c);
    harness_stop(&H);
    sci_cube *zero = NULL;
    assert_int_equal(sci_cube_new(&zero, p0->mask->w, p0->mask->h, 1, NULL), 0);
    char bad[800];
    snprintf(bad, sizeof bad, "%s/mask_003.exr", shared);
    sci_error err = {0};
    if (sci_image_write(bad, zero, 0, SCI_PIXEL_F32, 1.0, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_cube_free(zero);
    harness_spawn(&H, NULL);
    hconn_open(&c, &H);
    char more[1][32];
    capture(&c, 1, more);
    struct stat sb = stat_of("%s/%s", shared, "mask_003.exr");
    char cap[600];
    snprintf(cap, sizeof cap, "%s/captures/%s", H.store, more[0]);
    struct stat sn = stat_of("%s/%s", cap, "mask_003.exr");
    assert_true(sn.st_ino != sb.st_ino);
    sci_problem *pn = daemon_child_read_capture(&H, more[0]);
    assert_cubes_equal(pn->mask, p0->mask, "masks written beside a damaged shared folder");
    printf("  damaged shared folder after a restart: %s wrote its own masks (equal to the first capture's)\n",
           more[0]);
    sci_problem_free(pn);
    sci_problem_free(p0);
    hconn_close(&c);
    harness_stop(&H);
    harness_cleanup(&H);
}

/* The GIF at `gif` shows `frames` × scale: every pixel within one 8-bit step of round(v × scale) clamped. */
static void assert_gif_shows(const char *gif, const sci_cube *frames, double scale)
{
    sci_cube *g = NULL;
    sci_error err = {0};
    if (sci_image_read(gif, &g, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(g->w, frames->w);
    assert_int_equal(g->h, frames->h);
    assert_int_equal(g->n, frames->n);
    size_t off = 0;
    for (size_t i = 0; i < sci_cube_count(g); i++) {
        double v = isnan(frames->data[i]) ? 0 : nearbyint((double)frames->data[i] * scale);
        v = v < 0 ? 0 : v > 255 ? 255 : v;
        if (fabs(g->data[i] - v) > 1e-3)
            off++;
    }
    if (off)
        fail_msg("%s: %zu of %zu pixels are not the frames' 8-bit values", gif, off, sci_cube_count(g));
    sci_cube_free(g);
}

static void previews_show_the_frames(void **state)
{
    (void)state;
    hconn c;
    char ids[1][32];
    start_capture_reconstruct(&c, ids[0]);
    sci_problem *p = daemon_child_read_capture(&H, ids[0]);
    assert_non_null(p->truth);
    char gif[700], side[700];
    snprintf(gif, sizeof gif, "%s/captures/%s/preview_truth.gif", H.store, ids[0]);
    assert_gif_shows(gif, p->truth, 255.0 / p->peak);
    snprintf(side, sizeof side, "%s/captures/%s/recon/gap-tv/frame.json", H.store, ids[0]);
    sci_cube *frames = NULL;
    sci_error err = {0};
    if (sci_stack_read(side, &frames, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    snprintf(gif, sizeof gif, "%s/captures/%s/recon/gap-tv/preview.gif", H.store, ids[0]);
    assert_gif_shows(gif, frames, 255.0 / p->peak);
    printf("  preview_truth.gif and recon/gap-tv/preview.gif: every pixel the 8-bit value of its frame\n");
    sci_cube_free(frames);
    sci_problem_free(p);
    hconn_close(&c);
    harness_stop(&H);
    harness_cleanup(&H);
}

/* result.json's "job"."queue_entry" of <cap>/recon/<folder>, into buf ("" when none). */
static void written_by(const harness *h, const char *cap, const char *folder, char *buf, size_t n)
{
    char p[700];
    snprintf(p, sizeof p, "%s/captures/%s/recon/%s/result.json", h->store, cap, folder);
    json_t *r = json_load_file(p, 0, NULL);
    const char *e = json_string_value(json_object_get(json_object_get(r, "job"), "queue_entry"));
    snprintf(buf, n, "%s", e ? e : "");
    json_decref(r);
}

static void plant_entry(const harness *h, const char *name, const char *cap)
{
    char p[700];
    snprintf(p, sizeof p, "%s/recon-queue/%s", h->store, name);
    FILE *f = fopen(p, "w");
    assert_non_null(f);
    fprintf(f, "{\"capture\": \"%s\", \"owner\": %d, \"method\": \"gap-tv\", \"preset\": \"fast\", \"params\": {}}\n",
            cap, (int)geteuid());
    fclose(f);
}

/* Restart with `entries` planted in the queue: how many the daemon resumed. */
static int restart_with(hconn *c, const char *const *entries, const char *cap)
{
    harness_stop(&H);
    for (int i = 0; entries[i]; i++)
        plant_entry(&H, entries[i], cap);
    harness_spawn(&H, NULL);
    hconn_open(c, &H);
    return daemon_child_resumed(c);
}

static int entry_left(const char *entry)
{
    char p[700];
    snprintf(p, sizeof p, "%s/recon-queue/%s", H.store, entry);
    struct stat sb;
    return stat(p, &sb) == 0;
}

static void published_job_not_rerun(void **state)
{
    (void)state;
    hconn c;
    char ids[1][32];
    start_capture_reconstruct(&c, ids[0]);
    char entry[256];
    written_by(&H, ids[0], "gap-tv", entry, sizeof entry);
    assert_true(strncmp(entry, "r-", 2) == 0);
    hconn_close(&c);
    /* the state a kill -9 leaves between "output published" and "entry removed": the entry back in the queue;
     * beside it a second, later request for the same reconstruction, which must run, beside the first */
    const char *later = "r-99999999999999999999-999999.json";
    const int resumed = restart_with(&c, (const char *const[]){entry, later, NULL}, ids[0]);
    const int left = entry_left(entry);
    char by[256] = "", first[256] = "";
    int64_t t0 = h_now_ms();
    while (strcmp(by, later) != 0 && h_now_ms() - t0 < 60000) {
        h_sleep_ms(50);
        written_by(&H, ids[0], "gap-tv.2", by, sizeof by);
    }
    written_by(&H, ids[0], "gap-tv", first, sizeof first);
    printf("  restart with the published job's entry and a later one: %d resumed, the published entry %s, the "
           "later one %s, the first result %s\n", resumed, left ? "LEFT" : "removed",
           strcmp(by, later) ? "NOT RUN" : "ran into recon/gap-tv.2", strcmp(first, entry) ? "REPLACED" : "kept");
    assert_int_equal(resumed, 1);
    assert_false(left);
    assert_string_equal(by, later);
    assert_string_equal(first, entry);
    hconn_close(&c);
    /* the later one's entry back too: its output is recon/gap-tv.2, found there, not run a third time */
    const int again = restart_with(&c, (const char *const[]){later, NULL}, ids[0]);
    h_sleep_ms(500);
    printf("  restart with the entry that published recon/gap-tv.2: %d resumed, entry %s, recon/gap-tv.3 %s\n",
           again, entry_left(later) ? "LEFT" : "removed",
           daemon_child_recon_exists(&H, ids[0], "gap-tv.3") ? "WRITTEN" : "absent");
    assert_int_equal(again, 0);
    assert_false(entry_left(later));
    assert_false(daemon_child_recon_exists(&H, ids[0], "gap-tv.3"));
    hconn_close(&c);
    harness_stop(&H);
    harness_cleanup(&H);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(mask_stack_linked_once_per_set, cleanup),
        cmocka_unit_test_teardown(previews_show_the_frames, cleanup),
        cmocka_unit_test_teardown(published_job_not_rerun, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
