/* Tests for drivers/dlpc900_ctl against drivers/dlpc900_emu: the full upload at DMD resolution round-trips
 * (random, blocky, all-0, all-1), the command order the emulator enforces, and every error path — NACK, short
 * reply, timeout, unplug in the middle of an upload — ends in a clear message with the device stopped. */
#include <errno.h>
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
#include "drivers/dlpc900_ctl.h"
#include "drivers/dlpc900_emu.h"
#include "drivers/dlpc900_image.h"

enum { W = 1920, H = 1080 };
static uint64_t seed;

typedef struct fixture {
    dlpc900_emu *emu;
    dlpc900_ctl *ctl;
    int count;
    uint8_t *masks;       /* count × W × H bytes 0/1 */
    uint32_t *pixels;     /* packed images */
    const uint32_t *images[17];
    uint32_t exposure[400], dark[400];
    dlpc900_sequence seq;
} fixture;

static void make_masks(fixture *f, int count, int kind)
{
    size_t npx = (size_t)W * H;
    f->count = count;
    f->masks = malloc(npx * (size_t)count);
    sci_rng rng;
    sci_rng_seed(&rng, seed, (uint64_t)kind);
    for (int k = 0; k < count; k++) {
        uint8_t *m = f->masks + (size_t)k * npx;
        if (kind == 0) {
            for (size_t i = 0; i < npx; i++)
                m[i] = (uint8_t)(sci_rng_u64(&rng) & 1);
        } else if (kind == 1) { /* 4×4 super-pixels */
            uint8_t blocks[(W / 4) * (H / 4)];
            for (size_t i = 0; i < sizeof blocks; i++)
                blocks[i] = (uint8_t)(sci_rng_u64(&rng) & 1);
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++)
                    m[(size_t)y * W + x] = blocks[(y / 4) * (W / 4) + x / 4];
        } else {
            memset(m, kind == 3, npx);
        }
    }
    int nimg = (count + 23) / 24;
    f->pixels = malloc((size_t)nimg * npx * sizeof *f->pixels);
    for (int i = 0; i < nimg; i++) {
        int n = count - i * 24 < 24 ? count - i * 24 : 24;
        dlpc900_image_pack_bytes(f->masks + (size_t)i * 24 * npx, W, H, n, f->pixels + (size_t)i * npx);
        f->images[i] = f->pixels + (size_t)i * npx;
    }
    for (int j = 0; j < count; j++) {
        f->exposure[j] = 200 + (uint32_t)j;
        f->dark[j] = (uint32_t)j % 3;
    }
    f->seq = (dlpc900_sequence){.count = count, .exposure_us = f->exposure, .dark_us = f->dark, .patterns = 0};
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    sci_error err = {0};
    assert_int_equal(dlpc900_emu_new(&f->emu, &(dlpc900_emu_config){.serial = "EMU42"}, &err), 0);
    assert_int_equal(dlpc900_ctl_new(&f->ctl, dlpc900_emu_transport(f->emu), "DLPC900 EMU42", 100, &err), 0);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    dlpc900_ctl_free(f->ctl);
    dlpc900_emu_free(f->emu);
    free(f->masks);
    free(f->pixels);
    free(f);
    return 0;
}

static void check_device_masks(fixture *f)
{
    size_t npx = (size_t)W * H;
    uint8_t *m = malloc(npx);
    int nl;
    uint32_t np;
    dlpc900_emu_lut(f->emu, &nl, &np);
    assert_int_equal(nl, f->count);
    for (int j = 0; j < f->count; j++) {
        assert_int_equal(dlpc900_emu_mask(f->emu, j, m), 0);
        if (memcmp(m, f->masks + (size_t)j * npx, npx) != 0)
            fail_msg("mask %d differs after the round trip (seed %llu)", j, (unsigned long long)seed);
        dlpc900_lut_entry e;
        assert_int_equal(dlpc900_emu_lut_entry(f->emu, j, &e), 0);
        assert_int_equal(e.exposure_us, f->exposure[j]);
        assert_int_equal(e.dark_us, f->dark[j]);
        assert_int_equal(e.image_index, j / 24);
        assert_int_equal(e.bit_position, j % 24);
    }
    free(m);
}

static void roundtrip(void **state, int count, int kind)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, count, kind);
    int rc = dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err);
    if (rc)
        fail_msg("program: %s", err.msg);
    assert_int_equal(dlpc900_emu_refused(f->emu), 0);
    assert_int_equal(dlpc900_emu_mode(f->emu), DLPC900_MODE_OTF);
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
    check_device_masks(f);
    assert_int_equal(dlpc900_ctl_start(f->ctl, &err), 0);
    assert_int_equal(dlpc900_emu_running(f->emu), 1);
    dlpc900_status st;
    assert_int_equal(dlpc900_ctl_status(f->ctl, &st, &err), 0);
    assert_int_equal(st.running, 1);
    assert_int_equal(st.hw, 0x01);
    assert_int_equal(dlpc900_ctl_stop(f->ctl, &err), 0);
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
    dlpc900_traffic t;
    dlpc900_ctl_traffic(f->ctl, &t);
    printf("  %d masks kind %d: %ld reports out (%ld bytes), %ld messages\n", count, kind, t.reports_out,
           t.reports_out * 64, t.messages);
}

static void test_roundtrip_random(void **state) { roundtrip(state, 30, 0); } /* two images, the second partial */
static void test_roundtrip_blocky(void **state) { roundtrip(state, 48, 1); }
static void test_roundtrip_zero(void **state) { roundtrip(state, 24, 2); }
static void test_roundtrip_one(void **state) { roundtrip(state, 24, 3); }

static void test_identify(void **state)
{
    fixture *f = *state;
    dlpc900_identity id;
    sci_error err = {0};
    assert_int_equal(dlpc900_ctl_identify(f->ctl, &id, &err), 0);
    assert_int_equal(id.dmd_type, 1);
    assert_string_equal(dlpc900_dmd_type_name(id.dmd_type), "DLP6500");
    assert_int_equal(id.app_version >> 24, 6);
}

static void assert_contains(const char *msg, const char *part)
{
    if (!strstr(msg, part))
        fail_msg("expected \"%s\" in \"%s\"", part, msg);
}

/* NACK: the device refuses a LUT definition; the message carries command, code and the device's text. */
static void test_nack(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, 24, 2);
    dlpc900_emu_inject(f->emu, DLPC900_CMD_LUT_DEFINE, 5, DLPC900_EMU_FAULT_NACK, DLPC900_ERR_PATTERN_DEF);
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), SCI_EDEVICE);
    assert_contains(err.msg, "DLPC900 EMU42");
    assert_contains(err.msg, "pattern 5");
    assert_contains(err.msg, "pattern LUT definition (0x1A34) refused: error 16 (invalid pattern definition)");
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
}

/* A real refusal by the emulator's limits: exposure below the 105 µs minimum. */
static void test_exposure_too_short(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, 24, 3);
    f->exposure[3] = 50;
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), SCI_EDEVICE);
    assert_contains(err.msg, "error 14 (pattern exposure time out of range)");
    assert_contains(err.msg, "entry 3: exposure 50 us < min 105 us (1-bit, 15 blocks)");
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
}

/* Start, then a NACK on start itself: the device stays stopped. */
static void test_nack_on_start(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, 24, 2);
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), 0);
    dlpc900_emu_inject(f->emu, DLPC900_CMD_PATTERN_START, 1, DLPC900_EMU_FAULT_NACK, DLPC900_ERR_NOT_ALLOWED);
    assert_int_equal(dlpc900_ctl_start(f->ctl, &err), SCI_EDEVICE);
    assert_contains(err.msg, "pattern start/stop (0x1A24) refused: error 5");
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
}

static void test_short_reply(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, 24, 2);
    dlpc900_emu_inject(f->emu, DLPC900_CMD_LUT_CONFIG, 0, DLPC900_EMU_FAULT_SHORT, 0);
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), SCI_EPROTO);
    assert_contains(err.msg, "pattern LUT configuration (0x1A31): short reply: 3 bytes");
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
    /* a read answered short is caught too */
    dlpc900_emu_inject(f->emu, DLPC900_CMD_MAIN_STATUS, 0, DLPC900_EMU_FAULT_SHORT, 0);
    dlpc900_status st;
    assert_int_equal(dlpc900_ctl_status(f->ctl, &st, &err), SCI_EPROTO);
}

static void test_timeout(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, 24, 2);
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), 0);
    /* the check of the main status after start gets no answer */
    dlpc900_emu_inject(f->emu, DLPC900_CMD_MAIN_STATUS, 0, DLPC900_EMU_FAULT_SILENT, 0);
    assert_int_equal(dlpc900_ctl_start(f->ctl, &err), -ETIMEDOUT);
    assert_contains(err.msg, "main status (0x1A0C): no reply within 100 ms");
    assert_int_equal(dlpc900_emu_running(f->emu), 0); /* the failure path stopped it */
    /* the next command works: the late reply never came, nothing stale confuses it */
    assert_int_equal(dlpc900_ctl_start(f->ctl, &err), 0);
    assert_int_equal(dlpc900_emu_running(f->emu), 1);
}

static void test_unplug_mid_upload(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, 48, 0);
    dlpc900_emu_unplug_after(f->emu, 5000); /* well inside the first 6 MB image */
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), -ENODEV);
    assert_contains(err.msg, "DLPC900 EMU42");
    assert_contains(err.msg, "image 1, byte");
    assert_contains(err.msg, "unplugged");
    assert_false(dlpc900_emu_plugged(f->emu));
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
    /* back on the bus: power-on state, a new upload works */
    dlpc900_emu_replug(f->emu);
    int nl;
    uint32_t np;
    dlpc900_emu_lut(f->emu, &nl, &np);
    assert_int_equal(nl, 0);
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), 0);
    check_device_masks(f);
}

/* Device-side rules the emulator enforces (the order the driver must keep). */
static void test_emulator_rules(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    dlpc900_msg m;
    /* start with nothing configured */
    dlpc900_cmd_display_mode(&m, DLPC900_MODE_OTF);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), 0);
    dlpc900_cmd_pattern_start(&m, DLPC900_START);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), SCI_EDEVICE);
    assert_contains(err.msg, "error 16");
    /* 0x0100 sent as a write-with-reply (mcSIM's bug) is an invalid command */
    m = (dlpc900_msg){.flags = DLPC900_FLAG_REPLY, .cmd = DLPC900_CMD_ERROR_CODE};
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), SCI_EDEVICE);
    assert_contains(err.msg, "error 3 (invalid command number)");
    /* trigger delays out of range */
    dlpc900_cmd_trig_in1(&m, 50, 0);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), SCI_EDEVICE);
    assert_contains(err.msg, "error 13");
    dlpc900_cmd_trig_out(&m, 1, 0, -21, 0);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), SCI_EDEVICE);
    dlpc900_cmd_trig_out(&m, 2, 1, -20, 20000);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), 0);
    dlpc900_emu_triggers t;
    dlpc900_emu_triggers_get(f->emu, &t);
    assert_int_equal(t.out_rising_us[1], -20);
    assert_int_equal(t.out_invert[1], 1);
    /* LUT beyond 400 entries */
    dlpc900_cmd_lut_config(&m, 401, 0);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), SCI_EDEVICE);
    assert_contains(err.msg, "error 15");
    /* image data without init; image index beyond memory */
    uint8_t chunk[8] = {0};
    dlpc900_cmd_image_data(&m, chunk, 8);
    m.flags = DLPC900_FLAG_REPLY;
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), SCI_EDEVICE);
    dlpc900_cmd_image_init(&m, 18, 1000);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), SCI_EDEVICE);
    assert_contains(err.msg, "error 17");
    /* a message over the 512-byte command buffer: error bit in the reply */
    uint8_t rep[64] = {0x40, 0x77};
    dlpc900_put16(rep + 2, 600);
    dlpc900_emu_write(f->emu, rep, 64);
    uint8_t back[64];
    assert_int_equal(dlpc900_emu_read(f->emu, back), 64);
    assert_int_equal(back[0], 0x60);
    assert_int_equal(back[1], 0x77);
    /* mode change while running is refused: configure a real sequence and start it */
    make_masks(f, 24, 2);
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), 0);
    assert_int_equal(dlpc900_ctl_start(f->ctl, &err), 0);
    dlpc900_cmd_display_mode(&m, DLPC900_MODE_VIDEO);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), SCI_EDEVICE);
    assert_contains(err.msg, "stop first");
    /* a LUT definition without a following configuration blocks start */
    assert_int_equal(dlpc900_ctl_stop(f->ctl, &err), 0);
    dlpc900_lut_entry e = {.index = 0, .exposure_us = 500, .bit_depth = 1, .led = 7};
    dlpc900_cmd_lut_define(&m, &e);
    assert_int_equal(dlpc900_ctl_write(f->ctl, &m, &err), 0);
    assert_int_equal(dlpc900_ctl_start(f->ctl, &err), SCI_EDEVICE);
    assert_contains(err.msg, "without a LUT configuration");
    assert_int_equal(dlpc900_emu_running(f->emu), 0);
}

/* What the emulator would display over time: 3 patterns, 300+100 µs, 500+0, 200+50, shown twice (NP = 6). */
static void test_displayed_at(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, 3, 2);
    f->exposure[0] = 300; f->dark[0] = 100;
    f->exposure[1] = 500; f->dark[1] = 0;
    f->exposure[2] = 200; f->dark[2] = 50;
    f->seq.patterns = 6;
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), 0);
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 0, NULL), -ENODATA);
    assert_int_equal(dlpc900_ctl_start(f->ctl, &err), 0);
    long pass;
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 0, &pass), 0);
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 299999, NULL), 0);
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 300000, NULL), -1);
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 400000, NULL), 1);
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 900000, NULL), 2);
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 1110000, NULL), -1);
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 1150000 + 10, &pass), 0);
    assert_int_equal(pass, 1);
    assert_int_equal(dlpc900_emu_displayed_at(f->emu, 2 * 1150000 + 10, NULL), -2);
}

/* External trigger: TRIG_IN_1 programmed and every LUT entry waits for it. */
static void test_external_trigger(void **state)
{
    fixture *f = *state;
    sci_error err = {0};
    make_masks(f, 24, 3);
    f->seq.external_trigger = 1;
    f->seq.trig_in1_delay_us = 120;
    f->seq.trig_in1_falling = 1;
    assert_int_equal(dlpc900_ctl_program(f->ctl, f->images, W, H, &f->seq, &err), 0);
    dlpc900_emu_triggers t;
    dlpc900_emu_triggers_get(f->emu, &t);
    assert_int_equal(t.in1_delay_us, 120);
    assert_int_equal(t.in1_falling, 1);
    dlpc900_lut_entry e;
    assert_int_equal(dlpc900_emu_lut_entry(f->emu, 7, &e), 0);
    assert_int_equal(e.wait_trigger, 1);
    /* reprogramming only the LUT keeps the images */
    f->seq.external_trigger = 0;
    f->exposure[7] = 777;
    assert_int_equal(dlpc900_ctl_program_lut(f->ctl, &f->seq, &err), 0);
    assert_int_equal(dlpc900_emu_lut_entry(f->emu, 7, &e), 0);
    assert_int_equal(e.exposure_us, 777);
    assert_int_equal(e.wait_trigger, 0);
    assert_int_equal(dlpc900_ctl_start(f->ctl, &err), 0);
}

int main(void)
{
    seed = getenv("SEED") ? strtoull(getenv("SEED"), NULL, 0) : (uint64_t)time(NULL);
    printf("test_dlpc900_ctl: seed %llu (set SEED to repeat)\n", (unsigned long long)seed);
#define T(fn) cmocka_unit_test_setup_teardown(fn, setup, teardown)
    const struct CMUnitTest tests[] = {
        T(test_roundtrip_random), T(test_roundtrip_blocky), T(test_roundtrip_zero), T(test_roundtrip_one),
        T(test_identify),         T(test_nack),             T(test_exposure_too_short), T(test_nack_on_start),
        T(test_short_reply),      T(test_timeout),          T(test_unplug_mid_upload), T(test_emulator_rules),
        T(test_displayed_at),     T(test_external_trigger),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
