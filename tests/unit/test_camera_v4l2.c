/* The V4L2 backend's bad-input errors on this machine's real nodes: a node that is not a capture device, a node
 * that does not exist, a card that no device has. (Streaming needs a device: vivid, tests/vm.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>
#include <errno.h>

#include "drivers/camera_v4l2.h"

static void not_a_capture_device(void **state)
{
    (void)state;
    camera_config cfg = camera_config_default();
    cfg.device = "/dev/null";
    camera *cam = NULL;
    sci_error err = {0};
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -ENOTTY);
    assert_null(cam);
    assert_string_equal(err.msg, "/dev/null: not a V4L2 device (VIDIOC_QUERYCAP refused)");
}

static void missing_node(void **state)
{
    (void)state;
    camera_config cfg = camera_config_default();
    cfg.device = "/dev/v4l/by-id/usb-none-video-index0";
    camera *cam = NULL;
    sci_error err = {0};
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -ENOENT);
    assert_non_null(strstr(err.msg, "/dev/v4l/by-id/usb-none-video-index0: no such device node"));
}

static void card_not_found(void **state)
{
    (void)state;
    camera_config cfg = camera_config_default();
    cfg.card = "No Such Camera 9000";
    camera *cam = NULL;
    sci_error err = {0};
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -ENOENT);
    assert_non_null(strstr(err.msg, "card \"No Such Camera 9000\""));
    cfg = camera_config_default();
    assert_int_equal(camera_open(&cam, &camera_v4l2_ops, &cfg, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "no device, card or bus_info"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(not_a_capture_device),
        cmocka_unit_test(missing_node),
        cmocka_unit_test(card_not_found),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
