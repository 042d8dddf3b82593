/* Tests for sim/dmd_sim: the simulated DMD behind dmd_ops, the displayed-mask query, and usb_hotplug's
 * life cycle on this machine (a watcher that opens, polls and closes, or says why hotplug is unavailable). */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "drivers/usb_hotplug.h"
#include "sim/dmd_sim.h"

static void test_sim_backend(void **state)
{
    dmd *dev;
    dmd_config cfg = dmd_config_default();
    cfg.width = 64;
    cfg.height = 32;
    sci_error err = {0};
    assert_int_equal(dmd_open(&dev, &dmd_sim_ops, &cfg, &err), 0);
    dmd_identity id;
    assert_int_equal(dmd_identify(dev, &id, &err), 0);
    assert_string_equal(id.backend, "sim");
    assert_string_equal(id.serial, "SIM0001");
    assert_int_equal(id.width, 64);
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, 64, 32, 3, &err), 0);
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 64 * 32; i++)
            sci_cube_frame(c, k)[i] = (float)((i % (k + 2)) == 0);
    assert_int_equal(dmd_set_timing(dev, &(dmd_timing){.exposure_us = 1000, .dark_us = 500, .passes = 2}, &err), 0);
    assert_int_equal(dmd_upload(dev, c, &err), 0);
    assert_int_equal(dmd_sim_displayed_at(dev, 0), -ENODATA);
    assert_int_equal(dmd_start(dev, &err), 0);
    assert_true(dmd_sim_started_ns(dev) > 0);
    assert_int_equal(dmd_sim_displayed_at(dev, 0), 0);
    assert_int_equal(dmd_sim_displayed_at(dev, 1200000), -1);
    assert_int_equal(dmd_sim_displayed_at(dev, 1500000), 1);
    assert_int_equal(dmd_sim_displayed_at(dev, 3000000), 2);
    assert_int_equal(dmd_sim_displayed_at(dev, 4500000), 0);  /* second pass */
    assert_int_equal(dmd_sim_displayed_at(dev, 9000000), -2); /* after two passes */
    uint8_t m[64 * 32];
    for (int k = 0; k < 3; k++) {
        assert_int_equal(dmd_sim_mask(dev, k, m), 0);
        for (int i = 0; i < 64 * 32; i++)
            assert_int_equal(m[i], (i % (k + 2)) == 0);
    }
    assert_non_null(dmd_sim_emulator(dev));
    dmd_status st;
    assert_int_equal(dmd_status_get(dev, &st, &err), 0);
    assert_true(st.running);
    assert_int_equal(dmd_stop(dev, &err), 0);
    assert_int_equal(dmd_sim_displayed_at(dev, 0), -ENODATA);
    /* a handle of another backend is refused */
    dlpc900_emu *emu;
    assert_int_equal(dlpc900_emu_new(&emu, &(dlpc900_emu_config){.serial = "EMU1", .width = 64, .height = 32}, &err),
                     0);
    dmd_config oc = dmd_config_default();
    oc.emulator = emu;
    dmd *other;
    assert_int_equal(dmd_open(&other, &dmd_dlpc900_ops, &oc, &err), 0);
    assert_int_equal(dmd_sim_displayed_at(other, 0), -EINVAL);
    assert_null(dmd_sim_emulator(other));
    assert_int_equal(dmd_sim_displayed_at(NULL, 0), -EINVAL);
    dmd_close(other);
    dlpc900_emu_free(emu);
    sci_cube_free(c);
    dmd_close(dev);
    dmd_close(NULL); /* harmless */
}

/* Two simulated DMDs in one process do not share state (no module statics). */
static void test_two_sims(void **state)
{
    dmd *a, *b;
    dmd_config ca = dmd_config_default(), cb = dmd_config_default();
    ca.width = cb.width = 16;
    ca.height = cb.height = 8;
    ca.serial = "A";
    cb.serial = "B";
    sci_error err = {0};
    assert_int_equal(dmd_open(&a, &dmd_sim_ops, &ca, &err), 0);
    assert_int_equal(dmd_open(&b, &dmd_sim_ops, &cb, &err), 0);
    sci_cube *c;
    assert_int_equal(sci_cube_new(&c, 16, 8, 1, &err), 0);
    assert_int_equal(dmd_upload(a, c, &err), 0);
    assert_int_equal(dmd_start(a, &err), 0);
    dmd_status sa, sb;
    dmd_status_get(a, &sa, &err);
    dmd_status_get(b, &sb, &err);
    assert_true(sa.running);
    assert_false(sb.running);
    assert_int_equal(sb.loaded_masks, 0);
    dmd_identity id;
    dmd_identify(b, &id, &err);
    assert_string_equal(id.serial, "B");
    sci_cube_free(c);
    dmd_close(a);
    dmd_close(b);
}

static void test_usb_hotplug_lifecycle(void **state)
{
    usb_hotplug *hp = NULL;
    sci_error err = {0};
    int rc = usb_hotplug_new(&hp, 0x0451, 0xC900, NULL, NULL, &err);
    if (rc == -ENOTSUP || rc == -EIO) {
        /* Containers without /dev/bus/usb or udev: the backend then relies on failed transfers. Say so. */
        printf("  usb hotplug unavailable here: %s\n", err.msg);
        assert_non_null(strstr(err.msg, "0451:c900"));
        return;
    }
    assert_int_equal(rc, 0);
    assert_int_equal(usb_hotplug_poll(hp, 0, &err), 0); /* no DLPC900 comes or goes during the test */
    int fds[8];
    printf("  usb hotplug: %d fd(s) to poll\n", usb_hotplug_fds(hp, fds, 8));
    usb_hotplug_free(hp);
    usb_hotplug_free(NULL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sim_backend),
        cmocka_unit_test(test_two_sims),
        cmocka_unit_test(test_usb_hotplug_lifecycle),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
