/* Tests for drivers/backends: each device kind's backends looked up by their ops table's name, the drivers' own
 * and those a higher layer passes (sim/'s simulated devices), and the error that lists the known names. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "drivers/backends.h"
#include "drivers/camera_aravis.h"
#include "drivers/camera_v4l2.h"
#include "drivers/trigger_gpiod.h"
#include "sim/camera_sim.h"
#include "sim/dmd_sim.h"
#include "sim/trigger_sim.h"

static const camera_ops *const sim_cameras[] = {&camera_sim_ops, NULL};
static const trigger_ops *const sim_triggers[] = {&trigger_sim_ops, NULL};
static const dmd_ops *const sim_dmds[] = {&dmd_sim_ops, NULL};

/* Every listed table is found by its own name, and the lists hold the hardware backends the drivers have. */
static void test_builtin_found_by_their_names(void **state)
{
    (void)state;
    sci_error err = {0};
    int n = 0;
    for (const camera_ops *const *b = camera_backends_builtin(); *b; b++, n++)
        assert_ptr_equal(camera_backend_find((*b)->name, NULL, &err), *b);
    assert_int_equal(n, 2);
    n = 0;
    for (const trigger_ops *const *b = trigger_backends_builtin(); *b; b++, n++)
        assert_ptr_equal(trigger_backend_find((*b)->name, NULL, &err), *b);
    assert_int_equal(n, 1);
    n = 0;
    for (const dmd_ops *const *b = dmd_backends_builtin(); *b; b++, n++)
        assert_ptr_equal(dmd_backend_find((*b)->name, NULL, &err), *b);
    assert_int_equal(n, 1);
    /* the names a configuration uses (docs/config.md) are those of the tables */
    assert_ptr_equal(camera_backend_find("v4l2", NULL, &err), &camera_v4l2_ops);
    assert_ptr_equal(camera_backend_find("aravis", NULL, &err), &camera_aravis_ops);
    assert_ptr_equal(trigger_backend_find("gpiod", NULL, &err), &trigger_gpiod_ops);
    assert_ptr_equal(dmd_backend_find("dlpc900", NULL, &err), &dmd_dlpc900_ops);
    /* the template is not a backend */
    assert_null(camera_backend_find(camera_skeleton_ops.name, NULL, &err));
}

/* The simulated devices live in sim/, a layer above: found only when the caller passes them. */
static void test_extra_backends(void **state)
{
    (void)state;
    sci_error err = {0};
    assert_null(camera_backend_find("sim", NULL, &err));
    assert_null(trigger_backend_find("sim", NULL, &err));
    assert_null(dmd_backend_find("sim", NULL, &err));
    assert_ptr_equal(camera_backend_find("sim", sim_cameras, &err), &camera_sim_ops);
    assert_ptr_equal(trigger_backend_find("sim", sim_triggers, &err), &trigger_sim_ops);
    assert_ptr_equal(dmd_backend_find("sim", sim_dmds, &err), &dmd_sim_ops);
    /* the drivers' own stay reachable with extra given */
    assert_ptr_equal(dmd_backend_find("dlpc900", sim_dmds, &err), &dmd_dlpc900_ops);
}

/* Unknown name: NULL, SCI_ECONFIG, and a message naming the kind, the name and every known one. */
static void test_unknown_lists_known(void **state)
{
    (void)state;
    sci_error err = {0};
    assert_null(dmd_backend_find("dlp9000", sim_dmds, &err));
    assert_int_equal(err.code, SCI_ECONFIG);
    assert_string_equal(err.msg, "dmd backend \"dlp9000\" is unknown (known: dlpc900, sim)");
    memset(&err, 0, sizeof err);
    assert_null(camera_backend_find("V4L2", sim_cameras, &err)); /* exact: case matters, as for config keys */
    assert_int_equal(err.code, SCI_ECONFIG);
    assert_string_equal(err.msg, "camera backend \"V4L2\" is unknown (known: v4l2, aravis, sim)");
    memset(&err, 0, sizeof err);
    assert_null(trigger_backend_find("", NULL, &err));
    assert_string_equal(err.msg, "trigger backend \"\" is unknown (known: gpiod)");
    memset(&err, 0, sizeof err);
    assert_null(trigger_backend_find(NULL, sim_triggers, &err));
    assert_int_equal(err.code, SCI_ECONFIG);
    assert_string_equal(err.msg, "trigger: no backend given (known: gpiod, sim)");
}

static void test_names(void **state)
{
    (void)state;
    char buf[64];
    assert_string_equal(camera_backend_names(sim_cameras, buf, sizeof buf), "v4l2, aravis, sim");
    assert_string_equal(camera_backend_names(NULL, buf, sizeof buf), "v4l2, aravis");
    assert_string_equal(trigger_backend_names(sim_triggers, buf, sizeof buf), "gpiod, sim");
    assert_string_equal(dmd_backend_names(sim_dmds, buf, sizeof buf), "dlpc900, sim");
    /* a short buffer is cut, never overrun, always terminated */
    memset(buf, 'x', sizeof buf);
    assert_ptr_equal(camera_backend_names(sim_cameras, buf, 8), buf);
    assert_string_equal(buf, "v4l2, a");
    assert_int_equal(buf[8], 'x');
    buf[0] = 'x';
    camera_backend_names(sim_cameras, buf, 0);
    assert_int_equal(buf[0], 'x');
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_builtin_found_by_their_names),
        cmocka_unit_test(test_extra_backends),
        cmocka_unit_test(test_unknown_lists_known),
        cmocka_unit_test(test_names),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
