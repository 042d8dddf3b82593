/* scicapd's device backends without hardware: configuration validation for each backend (scicapd
 * --check-config); a start on a DLPC900, a V4L2 node and a GPIO chip that are not there (the daemon serves, says
 * which device is missing and why, refuses captures with that reason, and reconnects after a reload); and a mixed
 * bench where the DMD is the real dlpc900 backend driving the DLPC900 emulator through its transport, with the
 * simulated camera and trigger: captures, a reconstruction, dmd-master sync, and an unplug/replug; camera-master
 * sync on the simulated bench; the storage writer pool's ordering and shared DMD mask files. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "tests/integration/daemon_harness.h"

/* Run `scicapd --check-config -c FILE` on `text`; returns the exit status, the output in out. */
static int check_config(const char *text, char *out, size_t n)
{
    harness h;
    harness_init(&h, text);
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "%s --check-config -c %s 2>&1", h.bin, h.config);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t len = fread(out, 1, n - 1, p);
    out[len] = '\0';
    int st = pclose(p);
    harness_cleanup(&h);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void expect_valid(const char *text)
{
    char out[2048];
    int st = check_config(text, out, sizeof out);
    if (st != 0)
        fail_msg("expected a valid configuration, got: %s", out);
}

static void expect_invalid(const char *text, const char *key, const char *words)
{
    char out[2048];
    int st = check_config(text, out, sizeof out);
    printf("  refused: %s", out);
    if (st != 1 || !strstr(out, "scicapd.json:") || !strstr(out, key) || (words && !strstr(out, words)))
        fail_msg("expected \"%s\" refused naming %s (%s), got status %d: %s", text, key, words ? words : "", st, out);
}

static void config_validation_per_backend(void **state)
{
    (void)state;
    /* valid: every backend */
    expect_valid("{\"devices\": {\"dmd\": {\"backend\": \"dlpc900\", \"serial\": \"A1B2C3\", \"timeout_ms\": 500,"
                 " \"trigger_delay_us\": 120}, \"camera\": {\"backend\": \"v4l2\", \"device\": \"/dev/video0\","
                 " \"width\": 1440, \"height\": 1080, \"format\": \"Y16\", \"exposure_us\": 10000, \"readout_us\": 50,"
                 " \"trigger_profile\": {\"name\": \"imx296-ext\", \"controls\": {\"trigger_mode\": 1}}},"
                 " \"trigger\": {\"backend\": \"gpiod\", \"chip\": \"gpiochip0\", \"output\": 17,"
                 " \"dmd_input\": 22, \"strobe_input\": {\"line\": 27, \"active_low\": true}}}}");
    expect_valid("{\"devices\": {\"dmd\": {\"backend\": \"dlpc900\", \"emulator\": true}}}");
    expect_valid("{\"storage\": {\"writers\": 4, \"previews\": false}}");
    /* refused, with file:line:col and the key */
    expect_invalid("{\"devices\": {\"dmd\": {\"backend\": \"dlpc9000\"}}}", "devices.dmd.backend", NULL);
    expect_invalid("{\"devices\": {\"dmd\": {\"backend\": \"sim\", \"emulator\": true}}}", "devices.dmd.emulator",
                   "dlpc900");
    expect_invalid("{\"devices\": {\"dmd\": {\"backend\": \"dlpc900\", \"trigger_delay_us\": 70000}}}",
                   "devices.dmd.trigger_delay_us", NULL);
    expect_invalid("{\"devices\": {\"camera\": {\"backend\": \"v4l2\", \"device\": \"/dev/video0\"}}}",
                   "devices.camera.backend", "both real");
    expect_invalid("{\"devices\": {\"camera\": {\"backend\": \"v4l2\"}, \"trigger\": {\"backend\": \"gpiod\","
                   " \"chip\": \"gpiochip0\", \"output\": 17}}}", "devices.camera", "device");
    expect_invalid("{\"devices\": {\"camera\": {\"backend\": \"v4l2\", \"device\": \"/dev/video0\", \"widht\": 3},"
                   " \"trigger\": {\"backend\": \"gpiod\", \"chip\": \"gpiochip0\", \"output\": 17}}}",
                   "devices.camera.widht", "unknown key");
    expect_invalid("{\"devices\": {\"camera\": {\"backend\": \"v4l2\", \"device\": \"/dev/video0\"},"
                   " \"trigger\": {\"backend\": \"gpiod\", \"output\": 17}}}", "devices.trigger.chip", NULL);
    expect_invalid("{\"devices\": {\"camera\": {\"backend\": \"v4l2\", \"device\": \"/dev/video0\"},"
                   " \"trigger\": {\"backend\": \"gpiod\", \"chip\": \"gpiochip0\"}}}", "devices.trigger", "output");
    expect_invalid("{\"devices\": {\"trigger\": {\"backend\": \"sim\", \"chip\": \"x\"}}}", "devices.trigger",
                   "no settings");
    expect_invalid("{\"storage\": {\"writers\": 0}}", "storage.writers", NULL);
}

/* The example configurations shipped in etc/ (the simulated bench, DLPC900 + GenICam camera + GPIO, DLPC900 +
 * V4L2 camera + GPIO) pass the daemon's own validation, as `scicapd --check-config -c FILE` runs it. */
static void example_configs_are_valid(void **state)
{
    (void)state;
    static const char *const files[] = {"scicapd.json", "scicapd-aravis.json", "scicapd-v4l2.json"};
    char self[1024];
    ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
    assert_true(len > 0);
    self[len] = '\0';
    char etc[1100];
    snprintf(etc, sizeof etc, "%s/../../../etc", dirname(self)); /* BUILD/tests/integration -> the checkout */
    harness h;
    harness_init(&h, NULL);
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        char cmd[3000], out[2048];
        snprintf(cmd, sizeof cmd, "%s --check-config -c %s/%s 2>&1", h.bin, etc, files[i]);
        FILE *p = popen(cmd, "r");
        assert_non_null(p);
        size_t n = fread(out, 1, sizeof out - 1, p);
        out[n] = '\0';
        int st = pclose(p);
        printf("  %s", out);
        if (!WIFEXITED(st) || WEXITSTATUS(st) != 0 || !strstr(out, "valid"))
            fail_msg("etc/%s: %s", files[i], out);
    }
    harness_cleanup(&h);
}

static const char *const MISSING =
    "{\"devices\": {\"dmd\": {\"backend\": \"dlpc900\", \"serial\": \"NOSUCHDMD\", \"timeout_ms\": 200},"
    " \"camera\": {\"backend\": \"v4l2\", \"device\": \"/dev/video-scicap-missing\"},"
    " \"trigger\": {\"backend\": \"gpiod\", \"chip\": \"/dev/gpiochip-scicap-missing\", \"output\": 17}}}";

static void missing_hardware_then_reload(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, MISSING, NULL); /* the daemon starts and serves */
    hconn c;
    hconn_open(&c, &h);
    json_t *r = hconn_request(&c, "devices", NULL);
    const char *names[3] = {"dmd", "camera", "trigger"}, *want[3] = {"NOSUCHDMD", "/dev/video-scicap-missing",
                                                                      "/dev/gpiochip-scicap-missing"};
    for (int i = 0; i < 3; i++) {
        json_t *d = json_object_get(r, names[i]);
        const char *e = json_string_value(json_object_get(d, "error"));
        printf("  %s: %s\n", names[i], e ? e : "(no error)");
        assert_true(json_is_false(json_object_get(d, "connected")));
        assert_non_null(e);
        assert_non_null(strstr(e, want[i]));
    }
    json_decref(r);
    r = hconn_request(&c, "status", NULL);
    assert_true(json_is_false(json_object_get(r, "dmd_connected")));
    assert_true(json_is_false(json_object_get(json_object_get(json_object_get(r, "devices"), "camera"), "connected")));
    json_decref(r);
    /* a capture is refused with the reason, and the daemon keeps serving */
    json_decref(hconn_request(&c, "capture", NULL));
    json_t *e = hconn_wait_event(&c, "capture.failed", 20000);
    const char *why = json_string_value(json_object_get(json_object_get(e, "data"), "error"));
    printf("  capture: %s\n", why);
    assert_non_null(strstr(why, "not connected"));
    json_decref(e);
    hconn_expect_error(&c, "simulate", json_pack("{s:s}", "fault", "dmd-unplug"), "unsupported");
    /* the start-up error is in the log, naming the node */
    FILE *f = fopen(h.log, "r");
    char logbuf[16384];
    size_t n = f ? fread(logbuf, 1, sizeof logbuf - 1, f) : 0;
    logbuf[n] = '\0';
    if (f)
        fclose(f);
    assert_non_null(strstr(logbuf, "/dev/video-scicap-missing"));
    assert_non_null(strstr(logbuf, "/dev/gpiochip-scicap-missing"));
    /* the devices come back with a reload (here: the simulated bench instead) */
    harness_write_config(&h, "{\"version\": 1}");
    json_decref(hconn_request(&c, "reload", NULL));
    int ok = 0;
    for (int i = 0; i < 50 && !ok; i++) {
        h_sleep_ms(100);
        r = hconn_request(&c, "status", NULL);
        ok = json_is_true(json_object_get(r, "dmd_connected")) &&
             json_is_true(json_object_get(json_object_get(json_object_get(r, "devices"), "camera"), "connected"));
        json_decref(r);
    }
    assert_true(ok);
    json_decref(hconn_request(&c, "capture", NULL));
    json_decref(hconn_wait_event(&c, "capture.done", 20000));
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

static const char *const EMULATED =
    "{\"devices\": {\"dmd\": {\"backend\": \"dlpc900\", \"emulator\": true, \"serial\": \"EMU4242\"},"
    " \"camera\": {\"backend\": \"sim\"}, \"trigger\": {\"backend\": \"sim\"}},"
    " \"storage\": {\"writers\": 2, \"previews\": false}}";

/* The next recon.done: its PSNR printed after `what`, and above 18 dB (GAP-TV fast on the simulated scene). */
static void expect_recon_psnr(hconn *c, const char *what)
{
    json_t *e = hconn_wait_event(c, "recon.done", 60000);
    double psnr = json_number_value(json_object_get(json_object_get(e, "data"), "psnr"));
    printf("  %s: GAP-TV fast PSNR %.2f dB\n", what, psnr);
    assert_true(psnr > 18);
    json_decref(e);
}

/* One capture in sync_mode: its snapshot whole (when broken, the sync and offset are printed first), then done. */
static void expect_whole_capture(hconn *c, const char *sync_mode)
{
    json_decref(hconn_request(c, "capture", json_pack("{s:s}", "sync_mode", sync_mode)));
    json_t *e = hconn_wait_event(c, "capture.snapshot", 20000);
    json_t *sd = json_object_get(e, "data");
    if (!json_is_false(json_object_get(sd, "broken"))) /* say which check failed */
        printf("  %s snapshot broken: sync %s, offset %lld ns\n", sync_mode,
               json_string_value(json_object_get(sd, "sync")),
               (long long)json_integer_value(json_object_get(sd, "offset_ns")));
    assert_true(json_is_false(json_object_get(sd, "broken")));
    json_decref(e);
    json_decref(hconn_wait_event(c, "capture.done", 20000));
}

static void dlpc900_backend_on_the_emulator(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, EMULATED, NULL);
    hconn c;
    hconn_open(&c, &h);
    json_t *r = hconn_request(&c, "devices", NULL);
    json_t *dm = json_object_get(r, "dmd");
    assert_string_equal(json_string_value(json_object_get(dm, "backend")), "dlpc900");
    assert_string_equal(json_string_value(json_object_get(dm, "transport")), "emulator");
    assert_string_equal(json_string_value(json_object_get(dm, "serial")), "EMU4242");
    assert_true(json_is_true(json_object_get(dm, "connected")));
    json_decref(r);
    /* host master, reconstructed */
    json_decref(hconn_request(&c, "capture", json_pack("{s:i, s:b, s:s}", "count", 3, "reconstruct", 1, "preset",
                                                       "fast")));
    json_t *e = hconn_wait_event(&c, "capture.stored", 20000);
    char dir[512];
    snprintf(dir, sizeof dir, "%s", json_string_value(json_object_get(json_object_get(e, "data"), "dir")));
    json_decref(e);
    json_decref(hconn_wait_event(&c, "capture.done", 20000));
    expect_recon_psnr(&c, "dlpc900 backend on the emulator");
    assert_true(h_exists("%s/%s", dir, "dmd_mask_000.png"));
    assert_false(h_exists("%s/%s", dir, "preview_truth.gif")); /* storage.previews false */
    /* dmd master */
    expect_whole_capture(&c, "dmd-master");
    /* unplugged through the emulator: the real backend notices, reconnects, uploads again */
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s}", "fault", "dmd-unplug")));
    json_decref(hconn_request(&c, "capture", NULL));
    json_decref(hconn_wait_event(&c, "capture.failed", 20000));
    json_decref(hconn_request(&c, "simulate", json_pack("{s:s}", "fault", "dmd-replug")));
    int ok = 0;
    for (int i = 0; i < 50 && !ok; i++) {
        h_sleep_ms(100);
        r = hconn_request(&c, "status", NULL);
        ok = json_is_true(json_object_get(r, "dmd_connected"));
        json_decref(r);
    }
    assert_true(ok);
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", 2)));
    e = hconn_wait_event(&c, "capture.done", 20000);
    assert_int_equal(json_integer_value(json_object_get(json_object_get(e, "data"), "done")), 2);
    json_decref(e);
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

/* Camera master on the simulated bench: the camera free-runs, the strobe of the first exposure after the DMD was
 * armed starts the sequence; the snapshot is whole (not broken) and reconstructs; host master works after it. */
static void camera_master_on_the_simulated_bench(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, "{\"capture\": {\"sync_mode\": \"camera-master\"}}", NULL);
    hconn c;
    hconn_open(&c, &h);
    json_decref(hconn_request(&c, "capture", json_pack("{s:i, s:b, s:s}", "count", 2, "reconstruct", 1, "preset",
                                                       "fast")));
    for (int i = 0; i < 2; i++) {
        json_t *e = hconn_wait_event(&c, "capture.snapshot", 20000);
        json_t *d = json_object_get(e, "data");
        printf("  camera master snapshot %d: sync %s, %d patterns inside\n", i,
               json_string_value(json_object_get(d, "sync")), (int)json_integer_value(json_object_get(d, "inside")));
        assert_true(json_is_false(json_object_get(d, "broken")));
        json_decref(e);
    }
    expect_recon_psnr(&c, "camera master");
    expect_whole_capture(&c, "host-master");
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

/* Four writers: ids follow the snapshot index, capture.done comes after every capture.stored, and the DMD mask
 * PNGs of one mask set are one set of files hard-linked into each folder. */
static void writer_pool_keeps_order(void **state)
{
    (void)state;
    harness h;
    harness_start(&h, "{\"storage\": {\"writers\": 4, \"previews\": false}}", NULL);
    hconn c;
    hconn_open(&c, &h);
    enum { N = 8 };
    json_decref(hconn_request(&c, "capture", json_pack("{s:i}", "count", N)));
    char ids[N][32] = {{0}};
    int stored = 0, done = 0;
    while (!done) {
        json_t *m = hconn_read(&c, 30000);
        if (!m)
            fail_msg("no capture.done within 30 s (%d stored)", stored);
        const char *ev = json_string_value(json_object_get(m, "event"));
        json_t *d = json_object_get(m, "data");
        if (ev && !strcmp(ev, "capture.stored")) {
            int i = (int)json_integer_value(json_object_get(d, "index"));
            assert_true(i >= 0 && i < N);
            snprintf(ids[i], sizeof ids[i], "%s", json_string_value(json_object_get(d, "capture")));
            stored++;
        } else if (ev && !strcmp(ev, "capture.done")) {
            assert_int_equal(stored, N); /* the job's last word */
            assert_int_equal(json_integer_value(json_object_get(d, "done")), N);
            done = 1;
        } else if (ev && strstr(ev, ".failed")) {
            fail_msg("capture failed");
        }
        json_decref(m);
    }
    for (int i = 1; i < N; i++)
        assert_true(strcmp(ids[i - 1], ids[i]) < 0);
    char p[1024];
    snprintf(p, sizeof p, "%s/captures/%s/dmd_mask_000.png", h.store, ids[N - 1]);
    struct stat sb;
    assert_int_equal(stat(p, &sb), 0);
    printf("  %d snapshots by 4 writers: %s .. %s in order; dmd_mask_000.png has %d links\n", N, ids[0], ids[N - 1],
           (int)sb.st_nlink);
    assert_true(sb.st_nlink >= N);
    hconn_close(&c);
    harness_stop(&h);
    harness_cleanup(&h);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(config_validation_per_backend),
        cmocka_unit_test(example_configs_are_valid),
        cmocka_unit_test(missing_hardware_then_reload),
        cmocka_unit_test(dlpc900_backend_on_the_emulator),
        cmocka_unit_test(camera_master_on_the_simulated_bench),
        cmocka_unit_test(writer_pool_keeps_order),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
