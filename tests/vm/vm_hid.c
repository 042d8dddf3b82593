/* Kernel-level test of the DLPC900 DMD backend over hidapi/hidraw (runs inside the check-vm guest, tests/vm/run).
 *
 * The test makes a USB-bus HID device through /dev/uhid (VID 0x0451, PID 0xC900, 64-byte vendor IN/OUT reports,
 * no report IDs, serial in `uniq`) and puts the byte-exact emulator behind it: a pump thread takes each
 * UHID_OUTPUT (what hid_write sent through /dev/hidrawN), feeds it to dlpc900_emu_write, and answers every reply
 * report with UHID_INPUT2 (what hid_read returns). The backend under test is the real one — hidapi enumerates
 * with libudev, opens /dev/hidrawN, writes 65-byte reports and reads with a timeout — so the kernel's HID core,
 * hidraw and uhid carry every byte. Covered: discovery by VID/PID and serial, identity, a mask upload that the
 * emulator must decode to the same masks, timing, start/stop, status, a device error (NACK) and a lost reply
 * (-ETIMEDOUT) through hidraw, and an unplug (UHID_DESTROY) seen as -ENODEV with DISCONNECTED, then a replug
 * re-opened on demand with CONNECTED.
 *
 * uhid has no flow control: it queues at most 32 output events and drops the rest ("Output queue is full"), where
 * USB would make hid_write wait. The pump therefore runs SCHED_FIFO on the same CPU as the writer (both pinned
 * to CPU 0): each hid_write wakes it, and it preempts the writer on the way out of that write() and takes the
 * report before the next one is written. The guest's init fails the run if the kernel logs a dropped report.
 *
 * Needs root and uhid (+ hid-generic); exits 77 (skip) when /dev/uhid is missing. */
#include <errno.h>
#include <fcntl.h>
#include <linux/uhid.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "base/clock.h"
#include "base/cube.h"
#include "base/rng.h"
#include "drivers/dlpc900_emu.h"
#include "drivers/dlpc900_hid.h"
#include "drivers/dmd.h"

#define SERIAL "VMDMD01"
enum { W = 1920, H = 1080 };

/* A 64-byte vendor-defined input and output report, no report IDs: what a DLPC900 describes. */
static const uint8_t k_rdesc[] = {
    0x06, 0x00, 0xFF, /* Usage Page (Vendor 0xFF00) */
    0x09, 0x01,       /* Usage (1) */
    0xA1, 0x01,       /* Collection (Application) */
    0x15, 0x00,       /*   Logical Minimum (0) */
    0x26, 0xFF, 0x00, /*   Logical Maximum (255) */
    0x75, 0x08,       /*   Report Size (8) */
    0x95, 0x40,       /*   Report Count (64) */
    0x09, 0x01,       /*   Usage (1) */
    0x81, 0x02,       /*   Input (Data, Var, Abs) */
    0x95, 0x40,       /*   Report Count (64) */
    0x09, 0x01,       /*   Usage (1) */
    0x91, 0x02,       /*   Output (Data, Var, Abs) */
    0xC0,             /* End Collection */
};

/* The simulated device: a uhid fd, the emulator behind it, and the pump thread that joins them. */
typedef struct vdev {
    int fd;
    dlpc900_emu *emu;
    pthread_mutex_t lock;  /* guards emu and the counters */
    pthread_t pump;
    volatile int stop;
    int pump_running;
    long outputs, inputs, odd_sizes, opens;
    int fifo;              /* the pump got SCHED_FIFO */
} vdev;

static vdev g;
static uint64_t g_seed;

static int uhid_send(int fd, const struct uhid_event *ev)
{
    ssize_t n = write(fd, ev, sizeof *ev);
    return n == (ssize_t)sizeof *ev ? 0 : -errno;
}

static int uhid_create(vdev *d)
{
    struct uhid_event ev;
    memset(&ev, 0, sizeof ev);
    ev.type = UHID_CREATE2;
    snprintf((char *)ev.u.create2.name, sizeof ev.u.create2.name, "Texas Instruments DLPC900");
    snprintf((char *)ev.u.create2.phys, sizeof ev.u.create2.phys, "scicap-vm/uhid0");
    snprintf((char *)ev.u.create2.uniq, sizeof ev.u.create2.uniq, "%s", SERIAL);
    memcpy(ev.u.create2.rd_data, k_rdesc, sizeof k_rdesc);
    ev.u.create2.rd_size = sizeof k_rdesc;
    ev.u.create2.bus = 0x03; /* BUS_USB */
    ev.u.create2.vendor = DLPC900_VID;
    ev.u.create2.product = DLPC900_PID;
    ev.u.create2.version = 0x0100;
    return uhid_send(d->fd, &ev);
}

/* One event from the kernel. */
static void pump_one(vdev *d, const struct uhid_event *in)
{
    struct uhid_event out;
    switch (in->type) {
    case UHID_OUTPUT: {
        const uint8_t *p = in->u.output.data;
        size_t n = in->u.output.size;
        if (n == DLPC900_REPORT_SIZE + 1) { /* hid_write's leading report ID 0 comes through */
            p++;
            n--;
        }
        pthread_mutex_lock(&d->lock);
        d->outputs++;
        if (n != DLPC900_REPORT_SIZE)
            d->odd_sizes++;
        dlpc900_emu_write(d->emu, p, n);
        uint8_t rep[DLPC900_REPORT_SIZE];
        int r;
        while ((r = dlpc900_emu_read(d->emu, rep)) >= 0) {
            memset(&out, 0, sizeof out);
            out.type = UHID_INPUT2;
            out.u.input2.size = (uint16_t)r;
            memcpy(out.u.input2.data, rep, (size_t)r);
            if (uhid_send(d->fd, &out) == 0)
                d->inputs++;
        }
        pthread_mutex_unlock(&d->lock);
        break;
    }
    case UHID_GET_REPORT:
        memset(&out, 0, sizeof out);
        out.type = UHID_GET_REPORT_REPLY;
        out.u.get_report_reply.id = in->u.get_report.id;
        out.u.get_report_reply.err = EIO;
        uhid_send(d->fd, &out);
        break;
    case UHID_SET_REPORT:
        memset(&out, 0, sizeof out);
        out.type = UHID_SET_REPORT_REPLY;
        out.u.set_report_reply.id = in->u.set_report.id;
        out.u.set_report_reply.err = EIO;
        uhid_send(d->fd, &out);
        break;
    case UHID_OPEN:
        pthread_mutex_lock(&d->lock);
        d->opens++;
        pthread_mutex_unlock(&d->lock);
        break;
    default: /* START, STOP, CLOSE */
        break;
    }
}

static void *pump_main(void *arg)
{
    vdev *d = arg;
    struct uhid_event ev;
    while (!d->stop) {
        struct pollfd p = {.fd = d->fd, .events = POLLIN};
        int r = poll(&p, 1, 50);
        if (r <= 0)
            continue;
        ssize_t n = read(d->fd, &ev, sizeof ev);
        if (n <= 0)
            continue;
        pump_one(d, &ev);
    }
    return NULL;
}

static int pump_start(vdev *d)
{
    pthread_attr_t a;
    pthread_attr_init(&a);
    struct sched_param sp = {.sched_priority = 10};
    pthread_attr_setinheritsched(&a, PTHREAD_EXPLICIT_SCHED);
    pthread_attr_setschedpolicy(&a, SCHED_FIFO);
    pthread_attr_setschedparam(&a, &sp);
    cpu_set_t cpu0;
    CPU_ZERO(&cpu0);
    CPU_SET(0, &cpu0);
    pthread_attr_setaffinity_np(&a, sizeof cpu0, &cpu0); /* beside the writer: see the top of the file */
    d->stop = 0;
    d->fifo = 1;
    int rc = pthread_create(&d->pump, &a, pump_main, d);
    if (rc == EPERM) { /* not allowed real-time: run anyway; drops show as decode errors and in dmesg */
        d->fifo = 0;
        rc = pthread_create(&d->pump, NULL, pump_main, d);
    }
    pthread_attr_destroy(&a);
    d->pump_running = rc == 0;
    return -rc;
}

static void pump_stop(vdev *d)
{
    if (!d->pump_running)
        return;
    d->stop = 1;
    pthread_join(d->pump, NULL);
    d->pump_running = 0;
}

/* Plug: a new uhid device and pump. The hidraw node appears asynchronously: wait for hidapi to list it. */
static int vdev_plug(vdev *d)
{
    d->fd = open("/dev/uhid", O_RDWR | O_CLOEXEC);
    if (d->fd < 0)
        return -errno;
    int rc = uhid_create(d);
    if (rc == 0)
        rc = pump_start(d);
    if (rc < 0)
        return rc;
    for (int i = 0; i < 500; i++) {
        dlpc900_hid_info info[4];
        int n = 0;
        if (dlpc900_hid_list(info, 4, &n, NULL) == 0 && n > 0)
            return 0;
        struct timespec ts = {0, 10000000};
        nanosleep(&ts, NULL);
    }
    return -ETIMEDOUT;
}

/* Unplug: closing the uhid fd destroys the device (hidraw node goes away). */
static void vdev_unplug(vdev *d)
{
    pump_stop(d);
    if (d->fd >= 0) {
        struct uhid_event ev = {.type = UHID_DESTROY};
        uhid_send(d->fd, &ev);
        close(d->fd);
    }
    d->fd = -1;
}

/* ---- DMD under test ---- */

typedef struct events {
    int n;
    dmd_event ev[8];
} events;

static events g_events;

static void on_event(void *user, dmd_event ev, const char *serial)
{
    events *e = user;
    if (e->n < 8)
        e->ev[e->n++] = ev;
    (void)serial;
}

static dmd *g_dmd;

/* Blocky random masks (blocks of `block` mirrors, a few isolated mirrors flipped per mask so that pixel
 * exactness is checked at full resolution too). */
static sci_cube *masks_new(int n, int block, uint64_t stream)
{
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, W, H, n, NULL), 0);
    sci_rng rng;
    sci_rng_seed(&rng, g_seed, stream);
    int bw = (W + block - 1) / block, bh = (H + block - 1) / block;
    uint8_t *cells = malloc((size_t)bw * bh);
    for (int k = 0; k < n; k++) {
        for (int i = 0; i < bw * bh; i++)
            cells[i] = (uint8_t)(sci_rng_u64(&rng) & 1);
        float *f = sci_cube_frame(c, k);
        for (int y = 0; y < H; y++) {
            if (y % block) { /* rows inside a block row repeat (the guest runs under TCG: keep this cheap) */
                memcpy(f + (size_t)y * W, f + (size_t)(y - 1) * W, W * sizeof *f);
                continue;
            }
            for (int x = 0; x < W; x++)
                f[(size_t)y * W + x] = cells[(y / block) * bw + x / block];
        }
        for (int j = 0; j < 16; j++) {
            size_t i = (size_t)(sci_rng_u64(&rng) % ((uint64_t)W * H));
            f[i] = 1.0f - f[i];
        }
    }
    free(cells);
    return c;
}

static void check_device_masks(const sci_cube *c)
{
    uint8_t *m = malloc((size_t)W * H);
    pthread_mutex_lock(&g.lock);
    int nl;
    uint32_t np;
    dlpc900_emu_lut(g.emu, &nl, &np);
    int bad_k = -1;
    size_t bad_i = 0;
    for (int k = 0; k < c->n && bad_k < 0; k++) {
        if (dlpc900_emu_mask(g.emu, k, m) < 0) {
            bad_k = k;
            break;
        }
        const float *src = sci_cube_frame(c, k);
        for (size_t i = 0; i < (size_t)W * H; i++)
            if (m[i] != (src[i] >= 0.5f)) {
                bad_k = k;
                bad_i = i;
                break;
            }
    }
    pthread_mutex_unlock(&g.lock);
    free(m);
    assert_int_equal(nl, c->n);
    if (bad_k >= 0)
        fail_msg("mask %d differs on the device at pixel (%zu, %zu) (seed %llu)", bad_k, bad_i % W, bad_i / W,
                 (unsigned long long)g_seed);
}

/* ---- tests ---- */

static void enumerate(void **state)
{
    (void)state;
    dlpc900_hid_info info[4];
    int n = 0;
    sci_error err = {0};
    assert_int_equal(dlpc900_hid_list(info, 4, &n, &err), 0);
    assert_int_equal(n, 1);
    printf("# hidapi: %s serial \"%s\" product \"%s\" interface %d\n", info[0].path, info[0].serial,
           info[0].product, info[0].interface_number);
    assert_non_null(strstr(info[0].path, "/dev/hidraw"));
    assert_string_equal(info[0].serial, SERIAL);
    assert_string_equal(info[0].product, "Texas Instruments DLPC900");
}

static void open_and_identify(void **state)
{
    (void)state;
    sci_error err = {0};
    dmd_config cfg = dmd_config_default();
    cfg.serial = "NOT-THIS-ONE";
    dmd *other;
    assert_int_equal(dmd_open(&other, &dmd_dlpc900_ops, &cfg, &err), -ENODEV);
    assert_non_null(strstr(err.msg, "NOT-THIS-ONE"));
    cfg.serial = SERIAL;
    cfg.on_event = on_event;
    cfg.event_user = &g_events;
    if (dmd_open(&g_dmd, &dmd_dlpc900_ops, &cfg, &err) < 0)
        fail_msg("open: %s", err.msg);
    dmd_identity id;
    assert_int_equal(dmd_identify(g_dmd, &id, &err), 0);
    assert_string_equal(id.backend, "dlpc900");
    assert_string_equal(id.model, "DLP6500");
    assert_string_equal(id.serial, SERIAL);
    assert_int_equal(id.width, W);
    assert_int_equal(id.height, H);
    assert_true(id.firmware[0] != 0);
    printf("# %s %s firmware %s, %dx%d\n", id.model, id.serial, id.firmware, id.width, id.height);
}

static void upload_start_stop(void **state)
{
    (void)state;
    if (!g_dmd)
        skip();
    sci_error err = {0};
    sci_cube *c = masks_new(26, 40, 1); /* 2 images: 24 + 2 masks */
    assert_int_equal(dmd_set_timing(g_dmd, &(dmd_timing){.exposure_us = 250, .dark_us = 20, .passes = 2}, &err), 0);
    long out0 = g.outputs;
    int64_t t0 = sci_clock_mono_ns();
    if (dmd_upload(g_dmd, c, &err) < 0)
        fail_msg("upload: %s", err.msg);
    double s = sci_clock_s(t0, sci_clock_mono_ns());
    printf("# 26 masks (2 images) uploaded in %.2f s, %ld reports through hidraw/uhid\n", s, g.outputs - out0);
    check_device_masks(c);
    pthread_mutex_lock(&g.lock);
    int nl;
    uint32_t np;
    dlpc900_emu_lut(g.emu, &nl, &np);
    dlpc900_lut_entry e;
    int rc = dlpc900_emu_lut_entry(g.emu, 25, &e);
    long refused = dlpc900_emu_refused(g.emu);
    pthread_mutex_unlock(&g.lock);
    assert_int_equal(nl, 26);
    assert_int_equal(np, 52);
    assert_int_equal(rc, 0);
    assert_int_equal(e.exposure_us, 250);
    assert_int_equal(refused, 0);

    assert_int_equal(dmd_start(g_dmd, &err), 0);
    pthread_mutex_lock(&g.lock);
    int running = dlpc900_emu_running(g.emu);
    pthread_mutex_unlock(&g.lock);
    assert_int_equal(running, 1);
    dmd_status st;
    assert_int_equal(dmd_status_get(g_dmd, &st, &err), 0);
    assert_true(st.connected);
    assert_true(st.running);
    assert_int_equal(st.loaded_masks, 26);
    assert_int_equal(st.error_code, 0);
    assert_string_equal(st.error_text, "");
    assert_int_equal(dmd_stop(g_dmd, &err), 0);
    pthread_mutex_lock(&g.lock);
    running = dlpc900_emu_running(g.emu);
    pthread_mutex_unlock(&g.lock);
    assert_int_equal(running, 0);
    assert_int_equal(dmd_status_get(g_dmd, &st, &err), 0);
    assert_false(st.running);
    assert_int_equal(g.odd_sizes, 0);
    sci_cube_free(c);
}

/* A larger upload (4-mirror blocks, so ERLE cannot shrink it much): the long stream of image chunks without
 * replies is what uhid's 32-event queue would drop if the pump fell behind. (Masks are float cubes of 8 MB
 * each at 1920x1080: counts stay small for the guest's memory.) */
static void larger_upload(void **state)
{
    (void)state;
    if (!g_dmd)
        skip();
    sci_error err = {0};
    sci_cube *c = masks_new(8, 4, 2);
    long out0 = g.outputs;
    int64_t t0 = sci_clock_mono_ns();
    if (dmd_upload(g_dmd, c, &err) < 0)
        fail_msg("upload: %s", err.msg);
    double s = sci_clock_s(t0, sci_clock_mono_ns());
    long reports = g.outputs - out0;
    printf("# 8 masks, 4-mirror blocks: %ld reports in %.2f s (%.0f reports/s)\n", reports, s, reports / s);
    check_device_masks(c);
    assert_int_equal(dmd_start(g_dmd, &err), 0);
    assert_int_equal(dmd_stop(g_dmd, &err), 0);
    sci_cube_free(c);
}

/* The device refuses a command (NACK): the backend reads its error code and text back through hidraw. A reply
 * that never comes is -ETIMEDOUT after the configured timeout. The device is usable afterwards. */
static void device_errors(void **state)
{
    (void)state;
    if (!g_dmd)
        skip();
    sci_error err = {0};
    pthread_mutex_lock(&g.lock);
    dlpc900_emu_inject(g.emu, DLPC900_CMD_PATTERN_START, 1, DLPC900_EMU_FAULT_NACK, 7);
    pthread_mutex_unlock(&g.lock);
    int rc = dmd_start(g_dmd, &err); /* start sends stop (0x1A24 #0), then start (#1) */
    printf("# NACK: %s\n", err.msg);
    assert_int_equal(rc, SCI_EDEVICE);
    assert_non_null(strstr(err.msg, "0x1A24"));
    assert_non_null(strstr(err.msg, "error 7"));
    dmd_status st;
    assert_int_equal(dmd_status_get(g_dmd, &st, &err), 0);
    assert_true(st.connected);
    assert_false(st.running);

    pthread_mutex_lock(&g.lock);
    dlpc900_emu_inject(g.emu, DLPC900_CMD_MAIN_STATUS, 0, DLPC900_EMU_FAULT_SILENT, 0);
    pthread_mutex_unlock(&g.lock);
    int64_t t0 = sci_clock_mono_ns();
    rc = dmd_status_get(g_dmd, &st, &err);
    double s = sci_clock_s(t0, sci_clock_mono_ns());
    printf("# silent: %d after %.2f s: %s\n", rc, s, err.msg);
    assert_int_equal(rc, -ETIMEDOUT);
    assert_non_null(strstr(err.msg, "0x1A0C"));
    assert_true(s >= 0.2);

    assert_int_equal(dmd_start(g_dmd, &err), 0);
    assert_int_equal(dmd_status_get(g_dmd, &st, &err), 0);
    assert_true(st.running);
    assert_int_equal(dmd_stop(g_dmd, &err), 0);
}

/* Unplug: the hidraw node disappears; the next call fails with -ENODEV and DISCONNECTED. Replug (the controller
 * powers up blank): the next call re-opens by serial, CONNECTED, masks must be uploaded again. */
static void unplug_replug(void **state)
{
    (void)state;
    if (!g_dmd)
        skip();
    sci_error err = {0};
    int ev0 = g_events.n;
    vdev_unplug(&g);
    pthread_mutex_lock(&g.lock);
    dlpc900_emu_unplug_after(g.emu, 0);
    pthread_mutex_unlock(&g.lock);
    int rc = dmd_start(g_dmd, &err);
    printf("# unplugged: %d %s\n", rc, err.msg);
    assert_int_equal(rc, -ENODEV);
    assert_int_equal(g_events.n, ev0 + 1);
    assert_int_equal(g_events.ev[ev0], DMD_EVENT_DISCONNECTED);
    dmd_status st;
    assert_int_equal(dmd_status_get(g_dmd, &st, &err), 0);
    assert_false(st.connected);

    pthread_mutex_lock(&g.lock);
    dlpc900_emu_replug(g.emu);
    pthread_mutex_unlock(&g.lock);
    rc = vdev_plug(&g);
    if (rc < 0)
        fail_msg("replug: %s", strerror(-rc));
    assert_int_equal(dmd_start(g_dmd, &err), -EINVAL); /* re-opened, but blank */
    assert_int_equal(g_events.n, ev0 + 2);
    assert_int_equal(g_events.ev[ev0 + 1], DMD_EVENT_CONNECTED);
    assert_non_null(strstr(err.msg, "upload first"));
    sci_cube *c = masks_new(4, 60, 3);
    if (dmd_upload(g_dmd, c, &err) < 0)
        fail_msg("upload after replug: %s", err.msg);
    check_device_masks(c);
    assert_int_equal(dmd_start(g_dmd, &err), 0);
    assert_int_equal(dmd_status_get(g_dmd, &st, &err), 0);
    assert_true(st.connected && st.running);
    assert_int_equal(dmd_stop(g_dmd, &err), 0);
    sci_cube_free(c);
}

int main(void)
{
    g_seed = getenv("SEED") ? strtoull(getenv("SEED"), NULL, 0) : (uint64_t)time(NULL);
    printf("# vm_hid: seed %llu (set SEED to repeat)\n", (unsigned long long)g_seed);
    sci_error err = {0};
    pthread_mutex_init(&g.lock, NULL);
    cpu_set_t cpu0;
    CPU_ZERO(&cpu0);
    CPU_SET(0, &cpu0);
    sched_setaffinity(0, sizeof cpu0, &cpu0);
    g.fd = -1;
    if (dlpc900_emu_new(&g.emu, &(dlpc900_emu_config){.serial = SERIAL}, &err) < 0) {
        printf("vm_hid: emulator: %s\n", err.msg);
        return 1;
    }
    int rc = vdev_plug(&g);
    if (rc == -ENOENT) {
        printf("vm_hid: no /dev/uhid (modprobe uhid); skipped\n");
        return 77;
    }
    if (rc < 0) {
        printf("vm_hid: cannot create the uhid device: %s\n", strerror(-rc));
        return 1;
    }
    printf("# uhid device up, pump %s\n", g.fifo ? "SCHED_FIFO" : "SCHED_OTHER (no real-time priority)");
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(enumerate),
        cmocka_unit_test(open_and_identify),
        cmocka_unit_test(upload_start_stop),
        cmocka_unit_test(larger_upload),
        cmocka_unit_test(device_errors),
        cmocka_unit_test(unplug_replug),
    };
    rc = cmocka_run_group_tests(tests, NULL, NULL);
    dmd_close(g_dmd);
    g_dmd = NULL;
    vdev_unplug(&g);
    printf("# uhid: %ld output reports, %ld input reports, %ld hidraw opens, emulator: %ld messages, %ld refused\n",
           g.outputs, g.inputs, g.opens, dlpc900_emu_messages(g.emu), dlpc900_emu_refused(g.emu));
    dlpc900_emu_free(g.emu);
    return rc;
}
