/* Tests for drivers/dlpc900_hid on a machine without a DLPC900: enumeration works and reports what it found,
 * and opening a missing device fails with -ENODEV and a message naming serial, VID and PID — directly and
 * through the dlpc900 DMD backend. (Transfers are covered against the emulator in test_dlpc900_ctl.) */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "drivers/dlpc900_hid.h"
#include "drivers/dmd.h"

static void test_list(void **state)
{
    dlpc900_hid_info info[4];
    int n = -1;
    sci_error err = {0};
    assert_int_equal(dlpc900_hid_list(info, 4, &n, &err), 0);
    assert_true(n >= 0);
    printf("  %d DLPC900 HID interface(s) on this machine\n", n);
}

static void test_open_missing(void **state)
{
    dlpc900_transport t = {0};
    sci_error err = {0};
    assert_int_equal(dlpc900_hid_open(&t, "NO-SUCH-SERIAL", NULL, &err), -ENODEV);
    assert_non_null(strstr(err.msg, "DLPC900 NO-SUCH-SERIAL: not found (VID 0x0451 PID 0xC900"));
    assert_null(t.ops);

    dmd *dev = (dmd *)&t; /* anything: a failed open must set it to NULL */
    dmd_config cfg = dmd_config_default();
    cfg.serial = "NO-SUCH-SERIAL";
    assert_int_equal(dmd_open(&dev, &dmd_dlpc900_ops, &cfg, &err), -ENODEV);
    assert_non_null(strstr(err.msg, "NO-SUCH-SERIAL"));
    assert_null(dev);
    dmd_close(dev); /* harmless on a handle that failed to open */
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_list), cmocka_unit_test(test_open_missing)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
