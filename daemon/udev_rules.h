/* daemon/udev_rules.h — udev rules that give group scicap exactly the devices a configuration names.
 *
 * `scicapd --udev-rules [--config FILE]` prints them; the packaged systemd/70-scicap.rules only covers the
 * DLPC900 (its USB ids are fixed) and the uhid node of its emulator, so that webcams and other cameras on the
 * machine stay out of the group. Per backend:
 *   dmd dlpc900    hidraw and usb nodes of USB 0451:c900 (with ATTRS{serial} when devices.dmd.serial is set);
 *                  the emulator ("emulator": true): the uhid node and the emulated hidraw node
 *   camera v4l2    the video4linux node named by devices.camera.device: /dev/v4l/by-id/BUS-SERIAL-video-indexN
 *                  matches ENV{ID_SERIAL} and ATTR{index}, /dev/v4l/by-path/PATH-video-indexN matches
 *                  ENV{ID_PATH}; with devices.camera.usb {"vendor", "product", "serial"} the USB ids instead
 *   camera aravis  devices.camera.usb (a USB3 Vision camera's usb node); GigE Vision needs no device node
 *   trigger gpiod  the chip named by devices.trigger.chip (gpiochipN or /dev/gpiochipN)
 *   sim            nothing
 * A device that cannot be matched narrowly (e.g. camera "/dev/video0", whose number changes between boots) is
 * an error naming the key to change: a wide rule is never guessed.
 */
#ifndef SCICAP_DAEMON_UDEV_RULES_H
#define SCICAP_DAEMON_UDEV_RULES_H

#include <stdio.h>

#include "base/error.h"
#include "daemon/config.h"

/* The group and mode the rules give (the unit's Group= and scicapd.sysusers). */
#define SCICAPD_UDEV_GROUP "scicap"
#define SCICAPD_UDEV_MODE "0660"

/* Write the rules for c to f. SCI_ECONFIG naming the device key when a device cannot be matched narrowly;
 * -EIO when f fails. */
int scicapd_udev_rules_write(FILE *f, const scicapd_config *c, sci_error *err);

#endif
