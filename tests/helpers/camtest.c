/* tests/helpers/camtest.c — see camtest.h. */
#include "tests/helpers/camtest.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "drivers/camera_aravis.h"

void camtest_wait_frame(camera *cam, int64_t timeout_ns, camera_frame *fr)
{
    sci_error err = {0};
    int rc = camera_wait_frame(cam, timeout_ns, fr, &err);
    if (rc < 0)
        fail_msg("camera_wait_frame: %d %s", rc, err.msg);
}

uint64_t camtest_aravis_frame_id(camera *cam)
{
    camera_aravis_stream_stats st;
    assert_int_equal(camera_aravis_stream_stats_get(cam, &st), 0);
    return st.last_frame_id;
}
