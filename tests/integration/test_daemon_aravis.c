/* scicapd with a GenICam camera through the aravis backend: Aravis's in-process fake camera ("Fake_1") with the
 * simulated trigger and DMD, captured through the daemon's socket. Each stored frame must be the fake's own
 * diagonal ramp, bit for bit (the simulated camera could not produce it: its image is a noisy scene at ~6000
 * counts, this one 8-bit); frame timestamps increase and follow each snapshot's start; the frames the daemon
 * lost between snapshots are counted in meta.json (the camera's drop counter) and add up exactly with the frames
 * it drained; the software trigger is sent once per snapshot; each capture is reconstructed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "io/image.h"
#include "tests/helpers/cli_child.h"
#include "tests/integration/daemon_harness.h"

#define W 64
#define H 48
#define SNAPSHOTS 5

/* fps 100 and 2 buffers: a snapshot every ~150 ms (the acquire-delay fault below) leaves the fake ~15 frames
 * with nowhere to go, which Aravis counts as underruns and the backend as lost frames. gain 0 and the capture's
 * exposure of 10 ms make the fake's ramp scale exactly 1 (1 + gain + log10(exposure / 10 ms)). */
static const char CONFIG[] =
    "{\"devices\": {\"camera\": {\"backend\": \"aravis\", \"device\": \"Fake_1\", \"width\": 64, \"height\": 48,"
    " \"format\": \"GREY\", \"fps\": 100, \"gain\": 0, \"buffers\": 2, \"trigger\": \"software\"},"
    " \"trigger\": {\"backend\": \"sim\"}},"
    " \"storage\": {\"previews\": false},"
    " \"reconstruction\": {\"preset\": \"fast\"}}";

/* File-static, so that a failed test's daemon is stopped and its folder removed by the teardown. */
static harness daemon_h;

static int cleanup(void **state)
{
    (void)state;
    harness_cleanup(&daemon_h);
    memset(&daemon_h, 0, sizeof daemon_h);
    return 0;
}

static json_int_t jint(const json_t *o, const char *a, const char *b)
{
    const json_t *v = json_object_get(o, a);
    if (b)
        v = json_object_get(v, b);
    if (!json_is_integer(v))
        fail_msg("meta.json: %s%s%s is not an integer", a, b ? "." : "", b ? b : "");
    return json_integer_value(v);
}

/* The fake's Mono8 diagonal ramp at scale 1: (x + y + frame id) % 255 (arvfakecamera.c). The frame id is not in
 * the metadata, so the offset is read from pixel (0, 0) and every other pixel must follow. */
static void expect_fake_ramp(const char *dir)
{
    char path[800];
    snprintf(path, sizeof path, "%s/raw.tif", dir);
    sci_cube *raw;
    int bits = 0;
    sci_error err = {0};
    if (sci_image_read(path, &raw, &bits, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(raw->w, W);
    assert_int_equal(raw->h, H);
    unsigned base = (unsigned)raw->data[0];
    assert_true(base < 255);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            unsigned want = (base + (unsigned)x + (unsigned)y) % 255, got = (unsigned)raw->data[(size_t)y * W + x];
            if (got != want)
                fail_msg("%s: pixel (%d,%d) = %u, the fake camera's ramp says %u", path, x, y, got, want);
        }
    sci_cube_free(raw);
}

static void fake_camera_captured_by_daemon(void **state)
{
    (void)state;
    harness *h = &daemon_h;
    harness_start(h, CONFIG, NULL);
    hconn c;
    hconn_open(&c, h);

    json_t *r = hconn_request(&c, "devices", NULL);
    json_t *cam = json_object_get(r, "camera");
    assert_string_equal(json_string_value(json_object_get(cam, "backend")), "aravis");
    assert_true(json_is_true(json_object_get(cam, "connected")));
    assert_string_equal(json_string_value(json_object_get(json_object_get(cam, "identity"), "backend")), "aravis");
    assert_int_equal(json_integer_value(json_object_get(cam, "width")), W);
    assert_int_equal(json_integer_value(json_object_get(cam, "bits")), 8);
    /* the emulated DMD took the camera's size: one mirror per pixel */
    assert_int_equal(json_integer_value(json_object_get(json_object_get(r, "dmd"), "width")), W);
    json_decref(r);

    json_decref(hconn_request(&c, "simulate", json_pack("{s:s, s:i}", "fault", "acquire-delay", "n", 150)));
    r = hconn_request(&c, "capture", json_pack("{s:i, s:i, s:b}", "count", SNAPSHOTS, "exposure_us", 10000,
                                                "reconstruct", 1));
    json_decref(r);
    /* stored and reconstructed snapshots interleave (the first is reconstructed while the next is taken) */
    char dirs[SNAPSHOTS][512] = {{0}};
    int stored = 0, done = 0;
    int64_t t0 = h_now_ms();
    while (stored < SNAPSHOTS || done < SNAPSHOTS) {
        int left = 60000 - (int)(h_now_ms() - t0);
        json_t *e = left > 0 ? hconn_read(&c, left) : NULL;
        if (!e)
            fail_msg("after 60 s: %d of %d snapshots stored, %d reconstructed", stored, SNAPSHOTS, done);
        const char *ev = json_string_value(json_object_get(e, "event"));
        if (ev && strstr(ev, ".failed")) {
            char *txt = json_dumps(e, JSON_COMPACT);
            fail_msg("%s", txt);
        }
        if (ev && strcmp(ev, "capture.stored") == 0) {
            /* by the event's index: with several storage writers the events may come out of index order
             * (docs/protocol.md); under ASan on a loaded machine the second one was snapshot 2's */
            const json_t *data = json_object_get(e, "data");
            json_int_t idx = json_integer_value(json_object_get(data, "index"));
            assert_in_range(idx, 0, SNAPSHOTS - 1);
            snprintf(dirs[idx], sizeof dirs[0], "%s", json_string_value(json_object_get(data, "dir")));
            stored++;
        }
        if (ev && strcmp(ev, "recon.done") == 0)
            done++;
        json_decref(e);
    }
    printf("  %d snapshots stored and reconstructed in %.1f s\n", SNAPSHOTS, (double)(h_now_ms() - t0) * 1e-3);

    json_int_t prev_ts = 0, prev_seq = -1, prev_lost = 0, prev_sent = 0, lost_sum = 0, stale_sum = 0;
    for (int i = 0; i < SNAPSHOTS; i++) {
        expect_fake_ramp(dirs[i]);
        json_t *m = cli_child_load_json(dirs[i], "meta.json");
        assert_int_equal(jint(m, "snapshot_index", NULL), i);
        assert_null(json_object_get(m, "simulated")); /* not the simulated bench */
        assert_string_equal(json_string_value(json_object_get(json_object_get(m, "camera"), "backend")), "aravis");
        assert_string_equal(json_string_value(json_object_get(json_object_get(m, "frame"), "pixel_format")), "GREY");
        json_int_t ts = jint(m, "frame", "timestamp_ns"), start = jint(m, "start_ns", NULL);
        json_int_t seq = jint(m, "frame", "sequence"), lost = jint(m, "frame", "lost_total");
        json_int_t stale = jint(m, "stale_frames", NULL), sent = jint(m, "camera_trigger", "sent");
        const json_t *sync = json_object_get(m, "sync");
        char *flags = json_dumps(json_object_get(sync, "flags"), JSON_COMPACT | JSON_ENCODE_ANY);
        printf("  snapshot %d: sequence %lld, lost_total %lld, stale %lld, frame %.2f ms after the start, "
               "software triggers %lld, sync broken %d %s\n", i, (long long)seq, (long long)lost, (long long)stale,
               (double)(ts - start) * 1e-6, (long long)sent, json_is_true(json_object_get(sync, "broken")),
               flags ? flags : "");
        free(flags);
        assert_true(ts > start);     /* the kept frame follows the snapshot's start */
        assert_true(ts > prev_ts);   /* timestamps increase */
        assert_true(lost >= prev_lost);
        assert_int_equal(sent, prev_sent + 1); /* one TriggerSoftware per snapshot, at its start */
        assert_string_equal(json_string_value(json_object_get(json_object_get(m, "camera_trigger"), "mode")),
                            "software");
        if (prev_seq >= 0) {
            /* every frame the camera produced between two kept frames was drained (stale) or lost: exact */
            assert_int_equal(seq - prev_seq - 1, stale + (lost - prev_lost));
            lost_sum += lost - prev_lost;
            stale_sum += stale;
        }
        prev_ts = ts;
        prev_seq = seq;
        prev_lost = lost;
        prev_sent = sent;
        json_decref(m);
        assert_true(h_exists("%s/%s", dirs[i], "recon/gap-tv/result.json"));
    }
    printf("  between the snapshots: %lld frames lost, %lld drained\n", (long long)lost_sum, (long long)stale_sum);
    assert_true(lost_sum > 0); /* 150 ms between snapshots at 100 fps with 2 buffers */

    /* software trigger: only the host can start the exposure */
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s, s:i}", "fault", "acquire-delay", "n", 0)));
    json_decref(hconn_request(&c, "capture", json_pack("{s:s}", "sync_mode", "dmd-master")));
    json_t *e = hconn_wait_event(&c, "capture.failed", 20000);
    const char *why = json_string_value(json_object_get(json_object_get(e, "data"), "error"));
    printf("  dmd-master: %s\n", why);
    assert_non_null(strstr(why, "host-master"));
    json_decref(e);
    hconn_close(&c);
    harness_stop(h);
}

/* The pairing rule: only the fake camera may run with the simulated trigger; an aravis camera needs a name. */
static void aravis_config_rules(void **state)
{
    (void)state;
    static const struct {
        const char *text, *words; /* words NULL: valid */
    } cases[] = {
        {"{\"devices\": {\"camera\": {\"backend\": \"aravis\", \"device\": \"Fake_1\"}}}", NULL},
        {"{\"devices\": {\"camera\": {\"backend\": \"aravis\", \"device\": \"Basler-21234567\"}}}", "both real"},
        {"{\"devices\": {\"camera\": {\"backend\": \"aravis\", \"format\": \"GREY\"}, \"trigger\": {\"backend\":"
         " \"gpiod\", \"chip\": \"gpiochip0\", \"output\": 17}}}", "the aravis camera needs \"device\""},
        {"{\"devices\": {\"camera\": {\"backend\": \"aravis\", \"device\": \"Fake_1\", \"trigger\": \"edge\"}}}",
         "devices.camera.trigger"},
        {"{\"devices\": {\"camera\": {\"backend\": \"aravis\", \"card\": \"acA1440-220um\", \"bus_info\": \"2123\","
         " \"trigger\": \"line\", \"trigger_line\": \"Line1\", \"packet_size\": 8192}, \"trigger\": {\"backend\":"
         " \"gpiod\", \"chip\": \"gpiochip0\", \"output\": 17}}}", NULL},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        harness h;
        harness_init(&h, cases[i].text);
        char cmd[2048], out[2048];
        snprintf(cmd, sizeof cmd, "%s --check-config -c %s 2>&1", h.bin, h.config);
        FILE *p = popen(cmd, "r");
        assert_non_null(p);
        size_t n = fread(out, 1, sizeof out - 1, p);
        out[n] = '\0';
        int st = pclose(p);
        harness_cleanup(&h);
        printf("  %s", out);
        if (!cases[i].words && (!WIFEXITED(st) || WEXITSTATUS(st) != 0))
            fail_msg("expected valid: %s\ngot: %s", cases[i].text, out);
        if (cases[i].words && (!WIFEXITED(st) || WEXITSTATUS(st) != 1 || !strstr(out, cases[i].words)))
            fail_msg("expected refused naming '%s': %s\ngot: %s", cases[i].words, cases[i].text, out);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(aravis_config_rules),
        cmocka_unit_test_teardown(fake_camera_captured_by_daemon, cleanup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
