#include "drivers/dlpc900_hid.h"

#include <errno.h>
#include <hidapi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <wchar.h>

#include "drivers/dlpc900_proto.h"

typedef struct hid_ctx {
    hid_device *dev;
    char path[256];
} hid_ctx;

static void wide_to_utf8(char *out, size_t n, const wchar_t *w)
{
    snprintf(out, n, "%ls", w ? w : L"");
}

static void fill_info(dlpc900_hid_info *o, const struct hid_device_info *d)
{
    snprintf(o->path, sizeof o->path, "%s", d->path ? d->path : "");
    wide_to_utf8(o->serial, sizeof o->serial, d->serial_number);
    wide_to_utf8(o->product, sizeof o->product, d->product_string);
    o->interface_number = d->interface_number;
}

int dlpc900_hid_list(dlpc900_hid_info *out, int max, int *count, sci_error *err)
{
    if (hid_init() != 0)
        return sci_error_set(err, -EIO, "hidapi: initialisation failed");
    struct hid_device_info *all = hid_enumerate(DLPC900_VID, DLPC900_PID);
    int n = 0;
    /* Two passes: interface 0 first (the one TI's GUI uses), then the others. */
    for (int pass = 0; pass < 2; pass++)
        for (struct hid_device_info *d = all; d; d = d->next) {
            if ((d->interface_number == 0) != (pass == 0))
                continue;
            if (n < max)
                fill_info(&out[n], d);
            n++;
        }
    hid_free_enumeration(all);
    *count = n;
    return 0;
}

static int still_present(const char *path)
{
    struct hid_device_info *all = hid_enumerate(DLPC900_VID, DLPC900_PID);
    int found = 0;
    for (struct hid_device_info *d = all; d && !found; d = d->next)
        found = d->path && strcmp(d->path, path) == 0;
    hid_free_enumeration(all);
    return found;
}

static int transfer_failed(hid_ctx *h, const char *what, sci_error *err)
{
    char why[160];
    wide_to_utf8(why, sizeof why, hid_error(h->dev));
    if (!still_present(h->path))
        return sci_error_set(err, -ENODEV, "%s: device unplugged during %s", h->path, what);
    return sci_error_set(err, -EIO, "%s: %s failed: %s", h->path, what, why);
}

static int hid_t_write(void *ctx, const uint8_t report[DLPC900_REPORT_SIZE], int timeout_ms, sci_error *err)
{
    hid_ctx *h = ctx;
    uint8_t buf[DLPC900_REPORT_SIZE + 1];
    buf[0] = 0; /* report ID: all 65 bytes go to hid_write, or the last payload byte is lost (helical's bug) */
    memcpy(buf + 1, report, DLPC900_REPORT_SIZE);
    int n = hid_write(h->dev, buf, sizeof buf);
    if (n < 0)
        return transfer_failed(h, "write", err);
    return 0;
}

static int hid_t_read(void *ctx, uint8_t report[DLPC900_REPORT_SIZE], int timeout_ms, sci_error *err)
{
    hid_ctx *h = ctx;
    int n = hid_read_timeout(h->dev, report, DLPC900_REPORT_SIZE, timeout_ms);
    if (n < 0)
        return transfer_failed(h, "read", err);
    if (n == 0)
        return sci_error_set(err, -ETIMEDOUT, "%s: no reply within %d ms", h->path, timeout_ms);
    return n;
}

static void hid_t_close(void *ctx)
{
    hid_ctx *h = ctx;
    if (!h)
        return;
    hid_close(h->dev);
    free(h);
}

static const dlpc900_transport_ops hid_transport_ops = {
    .name = "hidraw",
    .write = hid_t_write,
    .read = hid_t_read,
    .close = hid_t_close,
};

int dlpc900_hid_open(dlpc900_transport *t, const char *serial, dlpc900_hid_info *info, sci_error *err)
{
    dlpc900_hid_info list[16];
    int n = 0, rc = dlpc900_hid_list(list, 16, &n, err);
    if (rc < 0)
        return rc;
    const dlpc900_hid_info *pick = NULL;
    for (int i = 0; i < n && i < 16 && !pick; i++)
        if (!serial || strcmp(list[i].serial, serial) == 0)
            pick = &list[i];
    if (!pick)
        return sci_error_set(err, -ENODEV, "DLPC900 %s: not found (VID 0x%04X PID 0x%04X, %d interface(s) present)",
                             serial ? serial : "(any)", DLPC900_VID, DLPC900_PID, n);
    hid_ctx *h = calloc(1, sizeof *h);
    if (!h)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", pick->path);
    snprintf(h->path, sizeof h->path, "%s", pick->path);
    h->dev = hid_open_path(pick->path);
    if (!h->dev) {
        free(h);
        char why[160];
        wide_to_utf8(why, sizeof why, hid_error(NULL));
        return sci_error_set(err, -EIO, "%s (DLPC900 %s): open failed: %s (is /dev/hidraw* readable and writable "
                             "by this user? see the udev rule in systemd/)", pick->path, pick->serial, why);
    }
    hid_set_nonblocking(h->dev, 0);
    t->ops = &hid_transport_ops;
    t->ctx = h;
    if (info)
        *info = *pick;
    return 0;
}
