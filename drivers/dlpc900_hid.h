/* drivers/dlpc900_hid.h — DLPC900 reports over hidapi (hidraw backend on Linux).
 *
 * Why hidraw and not libusb: usbhid owns the device, so libusb users get "resource busy" unless they detach the
 * kernel driver (reference §12). hidraw needs read/write access to /dev/hidraw* (a udev rule in systemd/).
 *
 * Discovery: VID 0x0451, PID 0xC900; a DLPC900 may expose more than one HID interface, and TI's GUI talks to
 * interface 0, so interface 0 is preferred. A serial number picks one of several DMDs.
 * Framing: hid_write takes 65 bytes (report ID 0, then the 64-byte report); on Linux hid_read returns 64 bytes
 * without the report ID. hidapi keeps process-wide state (hid_init); this module calls hid_init, never hid_exit.
 * Errors: -ENODEV when the device has left the bus (checked by enumerating again after a failed transfer),
 * -EIO otherwise, -ETIMEDOUT for reads with nothing within the timeout; messages carry hidapi's text and the path.
 */
#ifndef SCICAP_DRIVERS_DLPC900_HID_H
#define SCICAP_DRIVERS_DLPC900_HID_H

#include <stddef.h>

#include "base/error.h"
#include "drivers/dlpc900_transport.h"

typedef struct dlpc900_hid_info {
    char path[256];
    char serial[64];
    char product[64];
    int interface_number;
} dlpc900_hid_info;

/* Fill up to `max` entries (interface 0 entries first); *count receives the number of DLPC900 interfaces found
 * (may exceed max). 0 devices is not an error. -EIO when hidapi cannot initialise. */
int dlpc900_hid_list(dlpc900_hid_info *out, int max, int *count, sci_error *err);
/* Open the device with `serial` (NULL = first found). On success *t is a transport owning the handle
 * (dlpc900_transport_close releases it) and info (may be NULL) describes it. -ENODEV when no such device,
 * -EACCES-like failures as -EIO with hidapi's reason and a hint about /dev/hidraw permissions. */
int dlpc900_hid_open(dlpc900_transport *t, const char *serial, dlpc900_hid_info *info, sci_error *err);

#endif
