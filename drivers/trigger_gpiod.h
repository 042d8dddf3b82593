/* drivers/trigger_gpiod.h — the GPIO trigger backend on libgpiod, API v1 (1.6, Debian 12) or v2 (2.x), chosen at
 * build time by SCICAP_GPIOD_MAJOR (the Makefile reads it from pkg-config; there is no compile-time version macro
 * in libgpiod). Built without libgpiod (SCICAP_GPIOD_MAJOR 0), open fails with -ENOTSUP.
 *
 * Chip: a path ("/dev/gpiochip0"), a name ("gpiochip0") or a label ("pinctrl-bcm2711"). Lines: by offset or by
 * name. The output is requested as an output, driven inactive; the inputs with both-edge detection (v2: event
 * clock CLOCK_MONOTONIC, per-line sequence numbers; v1: CLOCK_MONOTONIC since Linux 5.7, a kernel queue of 16
 * events that drops the newest silently — line_seqno is then counted here and cannot show losses).
 *
 * Errors name the chip and line: -ENOENT (no such chip / no line of that name), -EINVAL (offset beyond the chip's
 * line count), -EBUSY (the line is requested by another consumer, named), -EACCES (permissions: udev rule, group).
 * backend_options: unused (NULL).
 */
#ifndef SCICAP_DRIVERS_TRIGGER_GPIOD_H
#define SCICAP_DRIVERS_TRIGGER_GPIOD_H

#include "drivers/trigger.h"

extern const trigger_ops trigger_gpiod_ops;

#endif
