#include "drivers/usb_hotplug.h"

#include <errno.h>
#include <libusb.h>
#include <poll.h>
#include <stdlib.h>

struct usb_hotplug {
    libusb_context *ctx;
    libusb_hotplug_callback_handle handle;
    usb_hotplug_fn fn;
    void *user;
    int delivered; /* notices during the current poll */
};

static int LIBUSB_CALL on_hotplug(libusb_context *ctx, libusb_device *dev, libusb_hotplug_event ev, void *user)
{
    usb_hotplug *hp = user;
    hp->delivered++;
    if (hp->fn)
        hp->fn(hp->user, ev == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED, libusb_get_bus_number(dev),
               libusb_get_device_address(dev));
    return 0; /* stay registered */
}

int usb_hotplug_new(usb_hotplug **out, uint16_t vid, uint16_t pid, usb_hotplug_fn fn, void *user, sci_error *err)
{
    usb_hotplug *hp = calloc(1, sizeof *hp);
    if (!hp)
        return sci_error_set(err, -ENOMEM, "usb hotplug %04x:%04x: out of memory", vid, pid);
    hp->fn = fn;
    hp->user = user;
    int rc = libusb_init(&hp->ctx);
    if (rc < 0) {
        free(hp);
        return sci_error_set(err, -EIO, "usb hotplug %04x:%04x: libusb_init: %s", vid, pid, libusb_error_name(rc));
    }
    if (!libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG)) {
        libusb_exit(hp->ctx);
        free(hp);
        return sci_error_set(err, -ENOTSUP, "usb hotplug %04x:%04x: libusb has no hotplug support here", vid, pid);
    }
    rc = libusb_hotplug_register_callback(hp->ctx, LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT,
                                          0, vid, pid, LIBUSB_HOTPLUG_MATCH_ANY, on_hotplug, hp, &hp->handle);
    if (rc != LIBUSB_SUCCESS) {
        libusb_exit(hp->ctx);
        free(hp);
        return sci_error_set(err, -EIO, "usb hotplug %04x:%04x: register callback: %s", vid, pid,
                             libusb_error_name(rc));
    }
    *out = hp;
    return 0;
}

void usb_hotplug_free(usb_hotplug *hp)
{
    if (!hp)
        return;
    libusb_hotplug_deregister_callback(hp->ctx, hp->handle);
    libusb_exit(hp->ctx);
    free(hp);
}

int usb_hotplug_poll(usb_hotplug *hp, int timeout_ms, sci_error *err)
{
    struct timeval tv = {.tv_sec = timeout_ms / 1000, .tv_usec = (timeout_ms % 1000) * 1000};
    hp->delivered = 0;
    int rc = libusb_handle_events_timeout_completed(hp->ctx, &tv, NULL);
    if (rc < 0 && rc != LIBUSB_ERROR_INTERRUPTED && rc != LIBUSB_ERROR_TIMEOUT)
        return sci_error_set(err, -EIO, "usb hotplug: handle events: %s", libusb_error_name(rc));
    return hp->delivered;
}

int usb_hotplug_fds(usb_hotplug *hp, int *fds, int max)
{
    const struct libusb_pollfd **p = libusb_get_pollfds(hp->ctx);
    int n = 0;
    for (int i = 0; p && p[i] && n < max; i++)
        fds[n++] = p[i]->fd;
    libusb_free_pollfds(p);
    return n;
}
