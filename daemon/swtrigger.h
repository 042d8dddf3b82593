/* daemon/swtrigger.h — a trigger whose output pulse also fires the camera's software trigger.
 *
 * A GenICam camera in "trigger": "software" mode (drivers/camera_aravis.h) exposes one frame per TriggerSoftware
 * command instead of per edge on a line. The acquisition starts a snapshot with trigger_pulse (drivers/capture.h:
 * in host master the pulse starts the DMD sequence and the exposure), so this backend wraps the configured
 * trigger (gpiod or sim): its pulse drives the wrapped output line first, then sends the camera's software
 * trigger, which is where the exposure starts. Inputs, flush and identity are the wrapped trigger's.
 *
 *     scicapd_swtrigger_options o = {.inner = gpio_trigger, .cam = aravis_camera};
 *     trigger_config tc = trigger_config_default();
 *     tc.backend_options = &o;
 *     trigger *t;
 *     if (trigger_open(&t, &scicapd_swtrigger_ops, &tc, &err) < 0) ...   // on failure inner stays the caller's
 *     trigger_pulse(t, 10, &t0, &err);                                   // GPIO pulse, then TriggerSoftware
 *     trigger_close(t);                                                  // closes inner too
 *
 * Ownership: on success the wrapper owns `inner` (closed with it); `cam` is borrowed and must outlive every
 * pulse (the daemon closes the wrapper before or with the camera, never uses it after). The pulse's *t_ns is the
 * wrapped trigger's edge; the software trigger follows it by the time one GenICam command takes (a register
 * write: tens of µs on GigE Vision, less in-process). Errors of the software trigger are returned by the pulse
 * (-ENODEV after the camera's control was lost, -ENOTSUP without TriggerSoftware). One thread at a time.
 */
#ifndef SCICAP_DAEMON_SWTRIGGER_H
#define SCICAP_DAEMON_SWTRIGGER_H

#include <stdint.h>

#include "drivers/camera.h"
#include "drivers/trigger.h"

extern const trigger_ops scicapd_swtrigger_ops;

typedef struct scicapd_swtrigger_options {
    trigger *inner;  /* owned by the wrapper once trigger_open succeeded */
    camera *cam;     /* an Aravis camera in software-trigger mode (borrowed) */
} scicapd_swtrigger_options;

/* Software triggers sent since open and the host time (CLOCK_MONOTONIC, ns) just before the last one was sent
 * (0 if none). -EINVAL if `t` is not a software-trigger wrapper. */
int scicapd_swtrigger_stats(trigger *t, uint64_t *sent, int64_t *last_ns);

#endif
