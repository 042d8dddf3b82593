/* drivers/dmd_dlpc900.c — the "dlpc900" DMD backend: dmd_ops over dlpc900_ctl, with USB HID (hidraw) or the
 * in-process emulator as transport, and unplug/replug handling.
 *
 * Connection life: open → connected; a transfer that returns -ENODEV, a hotplug departure confirmed by a failed
 * probe, or (emulator) an unplugged emulator → disconnected: the ctl is dropped, masks are forgotten (the
 * controller lost power), DMD_EVENT_DISCONNECTED is reported. While disconnected every call first tries to
 * re-open the same serial (hotplug arrival makes dmd_poll try at once); success reports DMD_EVENT_CONNECTED.
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/dlpc900_ctl.h"
#include "drivers/dlpc900_emu.h"
#include "drivers/dlpc900_hid.h"
#include "drivers/dlpc900_image.h"
#include "drivers/dmd.h"
#include "drivers/usb_hotplug.h"

#define DLPC900_DMD_MAX_MASKS 400
#define DLPC900_DMD_MIN_EXPOSURE_US 105 /* 1-bit, all blocks active (DLPU018 rev I) */

typedef struct dlpc900_dmd {
    char serial[64];          /* the device we hold; "" until first opened when none was asked for */
    char name[96];            /* "DLPC900 <serial>" for messages */
    int timeout_ms;
    dmd_event_fn on_event;
    void *event_user;
    const sci_log *log;
    dlpc900_emu *emu;         /* borrowed; NULL = USB */
    dlpc900_ctl *ctl;         /* NULL while disconnected */
    usb_hotplug *hp;          /* NULL when hotplug is unavailable or emulating */
    int usb_arrived, usb_left;
    dmd_identity id;
    /* what was programmed */
    int loaded;               /* masks on the device */
    int running;
    dmd_timing timing;        /* scalar part; arrays below */
    uint32_t *exposure_each, *dark_each;
    int each_count;
} dlpc900_dmd;

static void on_usb(void *user, int arrived, int bus, int address)
{
    dlpc900_dmd *d = user;
    if (arrived)
        d->usb_arrived = 1;
    else
        d->usb_left = 1;
}

static void emit(dlpc900_dmd *d, dmd_event ev)
{
    if (d->log)
        sci_log_write(d->log, SCI_LOG_NOTICE, "%s: %s", d->name, ev == DMD_EVENT_CONNECTED ? "connected" : "disconnected");
    if (d->on_event)
        d->on_event(d->event_user, ev, d->serial);
}

static int fill_identity(dlpc900_dmd *d, sci_error *err)
{
    dlpc900_identity id;
    int rc = dlpc900_ctl_identify(d->ctl, &id, err);
    if (rc < 0)
        return rc;
    dmd_identity *o = &d->id;
    memset(o, 0, sizeof *o);
    snprintf(o->backend, sizeof o->backend, "dlpc900");
    snprintf(o->model, sizeof o->model, "%s", dlpc900_dmd_type_name(id.dmd_type));
    snprintf(o->serial, sizeof o->serial, "%s", d->serial);
    snprintf(o->firmware, sizeof o->firmware, "%u.%u.%u", id.app_version >> 24, (id.app_version >> 16) & 0xFF,
             id.app_version & 0xFFFF);
    o->max_masks = DLPC900_DMD_MAX_MASKS;
    o->min_exposure_us = DLPC900_DMD_MIN_EXPOSURE_US;
    if (d->emu) {
        dlpc900_emu_size(d->emu, &o->width, &o->height);
    } else if (id.dmd_type == 1) {
        o->width = 1920;
        o->height = 1080;
    } else {
        /* The DLP9000's two controllers need split images (0x1A2C/0x1A2D): not implemented yet. */
        return sci_error_set(err, -ENOTSUP, "%s: DMD type %d (%s) is not supported; only the DLP6500", d->name,
                             id.dmd_type, o->model);
    }
    return 0;
}

static int dev_connect(dlpc900_dmd *d, sci_error *err)
{
    dlpc900_transport t = {0};
    int rc;
    if (d->emu) {
        if (!dlpc900_emu_plugged(d->emu))
            return sci_error_set(err, -ENODEV, "%s: unplugged", d->name);
        if (d->serial[0] && strcmp(d->serial, dlpc900_emu_serial(d->emu)) != 0)
            return sci_error_set(err, -ENODEV, "DLPC900 %s: not found (the emulator is %s)", d->serial,
                                 dlpc900_emu_serial(d->emu));
        snprintf(d->serial, sizeof d->serial, "%s", dlpc900_emu_serial(d->emu));
        t = dlpc900_emu_transport(d->emu);
    } else {
        dlpc900_hid_info info;
        if ((rc = dlpc900_hid_open(&t, d->serial[0] ? d->serial : NULL, &info, err)) < 0)
            return rc;
        snprintf(d->serial, sizeof d->serial, "%s", info.serial);
    }
    snprintf(d->name, sizeof d->name, "DLPC900 %s", d->serial);
    if ((rc = dlpc900_ctl_new(&d->ctl, t, d->name, d->timeout_ms, err)) < 0)
        return rc;
    if ((rc = fill_identity(d, err)) < 0) {
        dlpc900_ctl_free(d->ctl);
        d->ctl = NULL;
        return rc;
    }
    d->loaded = 0;
    d->running = 0;
    return 0;
}

static void disconnect(dlpc900_dmd *d)
{
    if (!d->ctl)
        return;
    dlpc900_ctl_free(d->ctl);
    d->ctl = NULL;
    d->loaded = 0;
    d->running = 0;
    emit(d, DMD_EVENT_DISCONNECTED);
}

/* Every operation starts here: re-open after an unplug if the device is back. */
static int ensure_connected(dlpc900_dmd *d, sci_error *err)
{
    if (d->ctl)
        return 0;
    sci_error e2 = {0};
    if (dev_connect(d, &e2) < 0)
        return sci_error_set(err, -ENODEV, "%s: disconnected, waiting for it to return (%s)", d->name, e2.msg);
    emit(d, DMD_EVENT_CONNECTED);
    return 0;
}

/* Classify a failure: an unplug drops the connection. Returns rc. */
static int failed(dlpc900_dmd *d, int rc)
{
    if (rc == -ENODEV)
        disconnect(d);
    return rc;
}

static void free_each(dlpc900_dmd *d)
{
    free(d->exposure_each);
    free(d->dark_each);
    d->exposure_each = d->dark_each = NULL;
    d->each_count = 0;
}

static void dmd_dlpc900_close(void *state)
{
    dlpc900_dmd *d = state;
    if (!d)
        return;
    if (d->ctl) {
        sci_error ignored = {0};
        dlpc900_ctl_stop(d->ctl, &ignored);
        dlpc900_ctl_free(d->ctl);
    }
    usb_hotplug_free(d->hp);
    free_each(d);
    free(d);
}

static int dmd_dlpc900_open(void **state, const dmd_config *cfg, sci_error *err)
{
    dlpc900_dmd *d = calloc(1, sizeof *d);
    if (!d)
        return sci_error_set(err, -ENOMEM, "DLPC900: out of memory");
    snprintf(d->serial, sizeof d->serial, "%s", cfg->serial ? cfg->serial : "");
    snprintf(d->name, sizeof d->name, "DLPC900 %s", cfg->serial ? cfg->serial : "(any)");
    d->timeout_ms = cfg->timeout_ms > 0 ? cfg->timeout_ms : 1000;
    d->on_event = cfg->on_event;
    d->event_user = cfg->event_user;
    d->log = cfg->log;
    d->emu = cfg->emulator;
    d->timing = (dmd_timing){.exposure_us = 1000, .trigger = DMD_TRIGGER_INTERNAL};
    int rc = dev_connect(d, err);
    if (rc < 0) {
        dmd_dlpc900_close(d);
        return rc;
    }
    if (!d->emu) {
        sci_error e2 = {0};
        /* Without hotplug, unplugs are still caught by failed transfers; only the early notice is lost. */
        if (usb_hotplug_new(&d->hp, DLPC900_VID, DLPC900_PID, on_usb, d, &e2) < 0 && d->log)
            sci_log_write(d->log, SCI_LOG_WARNING, "%s: %s", d->name, e2.msg);
    }
    *state = d;
    return 0;
}

static int dmd_dlpc900_identify(void *state, dmd_identity *id, sci_error *err)
{
    dlpc900_dmd *d = state;
    int rc = ensure_connected(d, err);
    if (rc < 0)
        return rc;
    *id = d->id;
    return 0;
}

static int build_sequence(dlpc900_dmd *d, int count, dlpc900_sequence *s, uint32_t **exp_out, uint32_t **dark_out,
                          sci_error *err)
{
    uint32_t *exp = malloc((size_t)count * sizeof *exp), *dark = malloc((size_t)count * sizeof *dark);
    if (!exp || !dark) {
        free(exp);
        free(dark);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", d->name);
    }
    int each = d->each_count == count;
    for (int j = 0; j < count; j++) {
        exp[j] = each && d->exposure_each ? d->exposure_each[j] : d->timing.exposure_us;
        dark[j] = each && d->dark_each ? d->dark_each[j] : d->timing.dark_us;
    }
    uint64_t np = (uint64_t)d->timing.passes * (uint64_t)count;
    *s = (dlpc900_sequence){
        .count = count,
        .exposure_us = exp,
        .dark_us = dark,
        .external_trigger = d->timing.trigger == DMD_TRIGGER_EXTERNAL,
        .trig_in1_delay_us = (uint16_t)(d->timing.trigger_delay_us ? d->timing.trigger_delay_us : 105),
        .trig_in1_falling = d->timing.trigger_falling,
        .patterns = np > UINT32_MAX ? 0 : (uint32_t)np,
    };
    *exp_out = exp;
    *dark_out = dark;
    return 0;
}

static int dmd_dlpc900_upload(void *state, const sci_cube *masks, sci_error *err)
{
    dlpc900_dmd *d = state;
    int rc = ensure_connected(d, err);
    if (rc < 0)
        return rc;
    if (masks->w != d->id.width || masks->h != d->id.height)
        return sci_error_set(err, SCI_ESHAPE, "%s: masks are %d×%d, the DMD is %d×%d", d->name, masks->w, masks->h,
                             d->id.width, d->id.height);
    if (masks->n < 1 || masks->n > d->id.max_masks)
        return sci_error_set(err, SCI_ESHAPE, "%s: %d masks, the device holds 1…%d", d->name, masks->n,
                             d->id.max_masks);
    int count = masks->n, nimg = (count + DLPC900_MASKS_PER_IMAGE - 1) / DLPC900_MASKS_PER_IMAGE;
    size_t npx = sci_cube_frame_size(masks);
    uint32_t *pixels = malloc((size_t)nimg * npx * sizeof *pixels);
    const uint32_t *images[(DLPC900_DMD_MAX_MASKS + DLPC900_MASKS_PER_IMAGE - 1) / DLPC900_MASKS_PER_IMAGE];
    if (!pixels)
        return sci_error_set(err, -ENOMEM, "%s: out of memory packing %d masks", d->name, count);
    for (int i = 0; i < nimg && rc == 0; i++) {
        int first = i * DLPC900_MASKS_PER_IMAGE;
        int n = count - first < DLPC900_MASKS_PER_IMAGE ? count - first : DLPC900_MASKS_PER_IMAGE;
        rc = dlpc900_image_pack_cube(masks, first, n, pixels + (size_t)i * npx, err);
        images[i] = pixels + (size_t)i * npx;
    }
    uint32_t *exp = NULL, *dark = NULL;
    dlpc900_sequence s;
    if (rc == 0 && (rc = build_sequence(d, count, &s, &exp, &dark, err)) == 0) {
        d->loaded = 0;
        d->running = 0;
        rc = dlpc900_ctl_program(d->ctl, images, masks->w, masks->h, &s, err);
        if (rc == 0)
            d->loaded = count;
    }
    free(exp);
    free(dark);
    free(pixels);
    return failed(d, rc);
}

static int dmd_dlpc900_set_timing(void *state, const dmd_timing *t, sci_error *err)
{
    dlpc900_dmd *d = state;
    if (t->exposure_us < 1 || t->exposure_us >= 1u << 24 || t->dark_us >= 1u << 24)
        return sci_error_set(err, -EINVAL, "%s: exposure %u µs / dark time %u µs outside 1…16777215 / 0…16777215",
                             d->name, t->exposure_us, t->dark_us);
    if (t->trigger != DMD_TRIGGER_INTERNAL && t->trigger != DMD_TRIGGER_EXTERNAL)
        return sci_error_set(err, -EINVAL, "%s: trigger mode %d is neither internal nor external", d->name, t->trigger);
    if (t->trigger_delay_us > 65535)
        return sci_error_set(err, -EINVAL, "%s: trigger delay %u µs exceeds 65535", d->name, t->trigger_delay_us);
    if ((t->exposure_us_each || t->dark_us_each) && !d->loaded)
        return sci_error_set(err, -EINVAL, "%s: per-pattern times need the masks uploaded first (their count)", d->name);
    free_each(d);
    if (t->exposure_us_each || t->dark_us_each) {
        size_t n = (size_t)d->loaded;
        d->exposure_each = t->exposure_us_each ? malloc(n * sizeof(uint32_t)) : NULL;
        d->dark_each = t->dark_us_each ? malloc(n * sizeof(uint32_t)) : NULL;
        if ((t->exposure_us_each && !d->exposure_each) || (t->dark_us_each && !d->dark_each)) {
            free_each(d);
            return sci_error_set(err, -ENOMEM, "%s: out of memory", d->name);
        }
        if (d->exposure_each)
            memcpy(d->exposure_each, t->exposure_us_each, n * sizeof(uint32_t));
        if (d->dark_each)
            memcpy(d->dark_each, t->dark_us_each, n * sizeof(uint32_t));
        d->each_count = d->loaded;
    }
    d->timing = *t;
    d->timing.exposure_us_each = d->timing.dark_us_each = NULL;
    if (!d->loaded)
        return 0; /* applied at the next upload */
    int rc = ensure_connected(d, err);
    if (rc < 0)
        return rc;
    uint32_t *exp = NULL, *dark = NULL;
    dlpc900_sequence s;
    if ((rc = build_sequence(d, d->loaded, &s, &exp, &dark, err)) == 0) {
        d->running = 0;
        rc = dlpc900_ctl_program_lut(d->ctl, &s, err);
    }
    free(exp);
    free(dark);
    return failed(d, rc);
}

static int dmd_dlpc900_start(void *state, sci_error *err)
{
    dlpc900_dmd *d = state;
    int rc = ensure_connected(d, err);
    if (rc < 0)
        return rc;
    if (!d->loaded)
        return sci_error_set(err, -EINVAL, "%s: no masks on the device (upload first; masks are lost when it is "
                             "unplugged)", d->name);
    rc = dlpc900_ctl_start(d->ctl, err);
    d->running = rc == 0;
    return failed(d, rc);
}

static int dmd_dlpc900_stop(void *state, sci_error *err)
{
    dlpc900_dmd *d = state;
    if (!d->ctl)
        return 0; /* unplugged: a powerless controller shows nothing */
    int rc = dlpc900_ctl_stop(d->ctl, err);
    if (rc == 0)
        d->running = 0;
    return failed(d, rc);
}

static int dmd_dlpc900_status(void *state, dmd_status *st, sci_error *err)
{
    dlpc900_dmd *d = state;
    memset(st, 0, sizeof *st);
    sci_error e2 = {0};
    if (ensure_connected(d, &e2) < 0) {
        snprintf(st->error_text, sizeof st->error_text, "%s", e2.msg);
        return 0; /* a disconnected device is a status, not a failure to report one */
    }
    dlpc900_status s;
    int rc = dlpc900_ctl_status(d->ctl, &s, err);
    if (rc < 0)
        return failed(d, rc);
    st->connected = 1;
    st->running = s.running;
    st->loaded_masks = d->loaded;
    st->error_code = s.error_code;
    if (s.error_code)
        snprintf(st->error_text, sizeof st->error_text, "error %d (%s): %s", s.error_code,
                 dlpc900_errcode_text(s.error_code), s.error_text);
    if (s.hw & DLPC900_HW_ERROR_BITS) {
        st->error_code = st->error_code ? st->error_code : DLPC900_ERR_DEVICE_FAILURE;
        snprintf(st->error_text, sizeof st->error_text, "hardware status 0x%02X reports an error", s.hw);
    }
    return 0;
}

static int dmd_dlpc900_poll(void *state, int timeout_ms, sci_error *err)
{
    dlpc900_dmd *d = state;
    if (d->hp) {
        int rc = usb_hotplug_poll(d->hp, timeout_ms, err);
        if (rc < 0)
            return rc;
    }
    if (d->ctl) {
        int gone = d->emu ? !dlpc900_emu_plugged(d->emu) : 0;
        if (!gone && d->usb_left) {
            /* Some DLPC900 left the bus: probe ours. */
            uint8_t hw;
            sci_error e2 = {0};
            gone = dlpc900_ctl_read(d->ctl, DLPC900_CMD_HW_STATUS, &hw, 1, 1, NULL, &e2) == -ENODEV;
        }
        d->usb_left = 0;
        if (gone)
            disconnect(d);
    }
    if (!d->ctl && (d->emu || d->usb_arrived || !d->hp)) {
        sci_error e2 = {0};
        if (dev_connect(d, &e2) == 0) {
            d->usb_arrived = 0;
            emit(d, DMD_EVENT_CONNECTED);
        }
    }
    return 0;
}

const dmd_ops dmd_dlpc900_ops = {
    .name = "dlpc900",
    .open = dmd_dlpc900_open,
    .close = dmd_dlpc900_close,
    .identify = dmd_dlpc900_identify,
    .upload = dmd_dlpc900_upload,
    .set_timing = dmd_dlpc900_set_timing,
    .start = dmd_dlpc900_start,
    .stop = dmd_dlpc900_stop,
    .status = dmd_dlpc900_status,
    .poll = dmd_dlpc900_poll,
};
