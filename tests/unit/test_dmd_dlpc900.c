/* Tests for the "dlpc900" DMD backend (drivers/dmd_dlpc900.c) through drivers/dmd.h, with the emulator as
 * the device: identity, upload of a cube, timing, start/stop, status, mask validation, and unplug/replug
 * handling with events — no restart needed. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>

#include "base/rng.h"
#include "drivers/dlpc900_emu.h"
#include "drivers/dmd.h"

enum { W = 320, H = 200 };
static uint64_t seed;

typedef struct fixture {
    dlpc900_emu *emu;
    dmd *dev;
    int events[8];
    int nevents;
    char last_serial[64];
} fixture;

static void on_event(void *user, dmd_event ev, const char *serial)
{
    fixture *f = user;
    if (f->nevents < 8)
        f->events[f->nevents++] = ev;
    snprintf(f->last_serial, sizeof f->last_serial, "%s", serial);
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    sci_error err = {0};
    assert_int_equal(dlpc900_emu_new(&f->emu, &(dlpc900_emu_config){.serial = "EMU7", .width = W, .height = H}, &err), 0);
    dmd_config cfg = dmd_config_default();
    cfg.emulator = f->emu;
    cfg.on_event = on_event;
    cfg.event_user = f;
    if (dmd_open(&f->dev, &dmd_dlpc900_ops, &cfg, &err) < 0)
        fail_msg("open: %s", err.msg);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    dmd_close(f->dev);
    dlpc900_emu_free(f->emu);
    free(f);
    return 0;
}

static sci_cube *random_masks(int n, uint64_t stream)
{
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, W, H, n, NULL), 0);
    sci_rng rng;
    sci_rng_seed(&rng, seed, stream);
    for (size_t i = 0; i < sci_cube_count(c); i++)
        c->data[i] = (float)(sci_rng_u64(&rng) & 1);
    return c;
}

static void check_loaded(fixture *f, const sci_cube *c)
{
    uint8_t *m = malloc((size_t)W * H);
    for (int k = 0; k < c->n; k++) {
        assert_int_equal(dlpc900_emu_mask(f->emu, k, m), 0);
        const float *src = sci_cube_frame(c, k);
        for (int i = 0; i < W * H; i++)
            if (m[i] != (src[i] >= 0.5f))
                fail_msg("mask %d pixel %d differs (seed %llu)", k, i, (unsigned long long)seed);
    }
    free(m);
}

static void test_identity(void **state)
{
    fixture *f = *state;
    dmd_identity id;
    sci_error err = {0};
    assert_int_equal(dmd_identify(f->dev, &id, &err), 0);
    assert_string_equal(id.backend, "dlpc900");
    assert_string_equal(id.model, "DLP6500");
    assert_string_equal(id.serial, "EMU7");
    assert_string_equal(id.firmware, "6.0.0");
    assert_int_equal(id.width, W);
    assert_int_equal(id.height, H);
    assert_int_equal(id.max_masks, 400);
    assert_int_equal(id.min_exposure_us, 105);
}

static void test_upload_start_stop(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    sci_cube *c = random_masks(40, 1);
    assert_int_equal(dmd_set_timing(f->dev, &(dmd_timing){.exposure_us = 250, .dark_us = 10, .passes = 1}, &err), 0);
    if (dmd_upload(f->dev, c, &err))
        fail_msg("upload: %s", err.msg);
    check_loaded(f, c);
    int nl;
    uint32_t np;
    dlpc900_emu_lut(f->emu, &nl, &np);
    assert_int_equal(nl, 40);
    assert_int_equal(np, 40); /* one pass */
    /* per-pattern exposure after the upload: LUT reprogrammed, images kept */
    uint32_t each[40];
    for (int j = 0; j < 40; j++)
        each[j] = 300 + 10 * (uint32_t)j;
    assert_int_equal(dmd_set_timing(f->dev, &(dmd_timing){.exposure_us = 250, .exposure_us_each = each,
                                                            .trigger = DMD_TRIGGER_EXTERNAL, .passes = 0}, &err), 0);
    dlpc900_lut_entry e;
    assert_int_equal(dlpc900_emu_lut_entry(f->emu, 39, &e), 0);
    assert_int_equal(e.exposure_us, 690);
    assert_int_equal(e.wait_trigger, 1);
    check_loaded(f, c);
    assert_int_equal(dmd_start(f->dev, &err), 0);
    dmd_status st;
    assert_int_equal(dmd_status_get(f->dev, &st, &err), 0);
    assert_true(st.connected);
    assert_true(st.running);
    assert_int_equal(st.loaded_masks, 40);
    assert_int_equal(st.error_code, 0);
    assert_int_equal(dmd_stop(f->dev, &err), 0);
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
    sci_cube_free(c);
}

static void test_validation(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, W + 1, H, 2, NULL), 0);
    assert_int_equal(dmd_upload(f->dev, c, &err), SCI_ESHAPE);
    assert_non_null(strstr(err.msg, "321×200"));
    sci_cube_free(c);
    c = random_masks(3, 2);
    c->data[5] = NAN;
    assert_int_equal(dmd_upload(f->dev, c, &err), SCI_ENONFINITE);
    assert_non_null(strstr(err.msg, "mask 0 pixel (5, 0)"));
    sci_cube_free(c);
    assert_int_equal(sci_cube_new(&c, W, H, 401, NULL), 0);
    assert_int_equal(dmd_upload(f->dev, c, &err), SCI_ESHAPE);
    sci_cube_free(c);
    assert_int_equal(dmd_start(f->dev, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "upload first"));
    assert_int_equal(dmd_set_timing(f->dev, &(dmd_timing){.exposure_us = 0}, &err), -EINVAL);
    /* the device's own limit comes back as a device error with code and text */
    c = random_masks(2, 3);
    assert_int_equal(dmd_set_timing(f->dev, &(dmd_timing){.exposure_us = 60}, &err), 0);
    assert_int_equal(dmd_upload(f->dev, c, &err), SCI_EDEVICE);
    assert_non_null(strstr(err.msg, "error 14 (pattern exposure time out of range)"));
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
    sci_cube_free(c);
}

/* Unplug during an upload: clear error, DISCONNECTED event, calls fail fast; replug: CONNECTED on poll, upload
 * again, start — same process, same handle. */
static void test_unplug_replug(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    sci_cube *c = random_masks(24, 4);
    assert_int_equal(dmd_set_timing(f->dev, &(dmd_timing){.exposure_us = 500}, &err), 0);
    dlpc900_emu_unplug_after(f->emu, 300);
    assert_int_equal(dmd_upload(f->dev, c, &err), -ENODEV);
    assert_non_null(strstr(err.msg, "unplugged"));
    assert_int_equal(f->nevents, 1);
    assert_int_equal(f->events[0], DMD_EVENT_DISCONNECTED);
    assert_string_equal(f->last_serial, "EMU7");
    dmd_status st;
    assert_int_equal(dmd_status_get(f->dev, &st, &err), 0);
    assert_false(st.connected);
    assert_non_null(strstr(st.error_text, "disconnected"));
    assert_int_equal(dmd_start(f->dev, &err), -ENODEV);
    assert_int_equal(dmd_stop(f->dev, &err), 0); /* stop is always safe */
    assert_int_equal(dmd_poll(f->dev, 0, &err), 0);
    assert_int_equal(f->nevents, 1);

    dlpc900_emu_replug(f->emu);
    assert_int_equal(dmd_poll(f->dev, 0, &err), 0);
    assert_int_equal(f->nevents, 2);
    assert_int_equal(f->events[1], DMD_EVENT_CONNECTED);
    assert_int_equal(dmd_start(f->dev, &err), -EINVAL); /* masks were lost with the power */
    assert_int_equal(dmd_upload(f->dev, c, &err), 0);
    check_loaded(f, c);
    assert_int_equal(dmd_start(f->dev, &err), 0);
    assert_int_equal(dlpc900_emu_running(f->emu), 1);

    /* unplug while idle is noticed by poll */
    dlpc900_emu_unplug_after(f->emu, 0);
    assert_int_equal(dmd_poll(f->dev, 0, &err), 0);
    assert_int_equal(f->nevents, 3);
    assert_int_equal(f->events[2], DMD_EVENT_DISCONNECTED);
    assert_int_equal(dmd_poll(f->dev, 0, &err), 0); /* still unplugged: no new event */
    assert_int_equal(f->nevents, 3);
    sci_cube_free(c);
}

int main(void)
{
    seed = getenv("SEED") ? strtoull(getenv("SEED"), NULL, 0) : (uint64_t)time(NULL);
    printf("test_dmd_dlpc900: seed %llu (set SEED to repeat)\n", (unsigned long long)seed);
#define T(fn) cmocka_unit_test_setup_teardown(fn, setup, teardown)
    const struct CMUnitTest tests[] = {T(test_identity), T(test_upload_start_stop), T(test_validation),
                                       T(test_unplug_replug)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
