/* drivers/usb_hotplug.h — USB arrival/departure notices for one VID:PID through libusb hotplug.
 *
 * Used by the DLPC900 backend so an unplugged DMD is noticed even while idle, and re-opened when it returns.
 * Each watcher has its own libusb context (no libusb default context, no globals). Callbacks run inside
 * usb_hotplug_poll on the caller's thread. Arrival is reported as soon as the USB device enumerates; the
 * hidraw node can appear a few milliseconds later, so callers retry the open on later polls.
 *
 *     usb_hotplug *hp;
 *     if (usb_hotplug_new(&hp, 0x0451, 0xC900, on_change, me, &err) == 0)
 *         usb_hotplug_poll(hp, 0, &err);            // from the event loop, or its fd via usb_hotplug_fds
 *     usb_hotplug_free(hp);
 *
 * Errors: -ENOTSUP when libusb lacks hotplug support on this system (callers then detect unplugs by failed
 * transfers only), -EIO for libusb failures, with libusb's error name in the message.
 * Not thread-safe per watcher.
 */
#ifndef SCICAP_DRIVERS_USB_HOTPLUG_H
#define SCICAP_DRIVERS_USB_HOTPLUG_H

#include <stdint.h>

#include "base/error.h"

typedef struct usb_hotplug usb_hotplug;

/* arrived: 1 on arrival, 0 on departure; bus and address identify the device on the bus. */
typedef void (*usb_hotplug_fn)(void *user, int arrived, int bus, int address);

/* Watch vid:pid. Devices already present are not reported (the caller opens them itself). */
int usb_hotplug_new(usb_hotplug **out, uint16_t vid, uint16_t pid, usb_hotplug_fn fn, void *user, sci_error *err);
void usb_hotplug_free(usb_hotplug *hp);
/* Handle pending libusb events for up to timeout_ms (0 = just what is pending). Returns the number of notices
 * delivered during this call, or -EIO. */
int usb_hotplug_poll(usb_hotplug *hp, int timeout_ms, sci_error *err);
/* File descriptors to poll(2) for readability before calling usb_hotplug_poll; returns how many were written
 * (≤ max). */
int usb_hotplug_fds(usb_hotplug *hp, int *fds, int max);

#endif
