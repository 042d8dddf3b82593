/* tests/helpers/camtest.h — what the camera tests (tests/unit/test_camera_aravis.c, tests/aravis-gv/) do on every
 * frame: wait for it or fail the test, and read the frame id the Aravis stream saw last.
 *
 * For use inside cmocka tests: an error fails the test (fail_msg / assert), nothing is returned. */
#ifndef SCICAP_TESTS_CAMTEST_H
#define SCICAP_TESTS_CAMTEST_H

#include <stdint.h>

#include "drivers/camera.h"

/* The next frame into *fr within timeout_ns nanoseconds; a timeout or any error fails the test with its code and
 * message. The frame is the camera's until the caller requeues it (drivers/camera.h). */
void camtest_wait_frame(camera *cam, int64_t timeout_ns, camera_frame *fr);

/* The GenICam frame (block) id of the last frame an Aravis camera's stream delivered. */
uint64_t camtest_aravis_frame_id(camera *cam);

#endif
