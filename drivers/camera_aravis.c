/* drivers/camera_aravis.c — GenICam cameras through Aravis 0.8 (contract in camera_aravis.h). */
#include "drivers/camera_aravis.h"

#include <arv.h>
#include <errno.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* GenICam PixelFormat (PFNC) values and ours. Order is the preference when nothing is asked: more bits first,
 * monochrome before Bayer. */
static const struct {
    ArvPixelFormat arv;
    const char *genicam;
    enum pixfmt ours;
} aravis_formats[] = {
    {ARV_PIXEL_FORMAT_MONO_16, "Mono16", PIXFMT_Y16},        {ARV_PIXEL_FORMAT_MONO_12, "Mono12", PIXFMT_Y12},
    {ARV_PIXEL_FORMAT_MONO_10, "Mono10", PIXFMT_Y10},        {ARV_PIXEL_FORMAT_MONO_8, "Mono8", PIXFMT_GREY},
    {ARV_PIXEL_FORMAT_BAYER_RG_16, "BayerRG16", PIXFMT_SRGGB16}, {ARV_PIXEL_FORMAT_BAYER_GR_16, "BayerGR16", PIXFMT_SGRBG16},
    {ARV_PIXEL_FORMAT_BAYER_GB_16, "BayerGB16", PIXFMT_SGBRG16}, {ARV_PIXEL_FORMAT_BAYER_BG_16, "BayerBG16", PIXFMT_SBGGR16},
    {ARV_PIXEL_FORMAT_BAYER_RG_12, "BayerRG12", PIXFMT_SRGGB12}, {ARV_PIXEL_FORMAT_BAYER_GR_12, "BayerGR12", PIXFMT_SGRBG12},
    {ARV_PIXEL_FORMAT_BAYER_GB_12, "BayerGB12", PIXFMT_SGBRG12}, {ARV_PIXEL_FORMAT_BAYER_BG_12, "BayerBG12", PIXFMT_SBGGR12},
    {ARV_PIXEL_FORMAT_BAYER_RG_10, "BayerRG10", PIXFMT_SRGGB10}, {ARV_PIXEL_FORMAT_BAYER_GR_10, "BayerGR10", PIXFMT_SGRBG10},
    {ARV_PIXEL_FORMAT_BAYER_GB_10, "BayerGB10", PIXFMT_SGBRG10}, {ARV_PIXEL_FORMAT_BAYER_BG_10, "BayerBG10", PIXFMT_SBGGR10},
    {ARV_PIXEL_FORMAT_BAYER_RG_8, "BayerRG8", PIXFMT_SRGGB8},    {ARV_PIXEL_FORMAT_BAYER_GR_8, "BayerGR8", PIXFMT_SGRBG8},
    {ARV_PIXEL_FORMAT_BAYER_GB_8, "BayerGB8", PIXFMT_SGBRG8},    {ARV_PIXEL_FORMAT_BAYER_BG_8, "BayerBG8", PIXFMT_SBGGR8},
};
#define ARAVIS_NFORMATS (sizeof aravis_formats / sizeof aravis_formats[0])

/* One pool buffer's bookkeeping, reached through the ArvBuffer's user data. */
typedef struct aravis_slot {
    uint64_t underruns_before; /* stream underruns counted before this buffer was filled (see aravis_push) */
} aravis_slot;

typedef struct aravis_cam {
    ArvCamera *cam;
    ArvStream *stream;
    gulong lost_handler;
    atomic_int control_lost;  /* set from Aravis's heartbeat thread */
    char id[256];             /* what was asked (device id, address), for messages and recover */
    char want_model[64], want_serial[64];
    camera_identity ident;
    camera_aravis_options opt;
    char trigger_line[64], trigger_activation[32];
    char ctrl_names[CAMERA_MAX_CONTROLS][64];
    int64_t ctrl_values[CAMERA_MAX_CONTROLS];
    int nctrl;
    char profile_name[32];
    camera_config want;       /* the last format request (no strings), for recover */
    int have_fmt;
    camera_format fmt;
    ArvPixelFormat arv_fmt;
    uint32_t exposure_us;
    int32_t gain;
    int buffer_count;
    aravis_slot slots[CAMERA_MAX_BUFFERS];
    int streaming;
    int ids_from_camera;      /* GigE / USB3 Vision: frame ids are the camera's, numbering every frame it sent */
    /* loss accounting for the current stream (camera_aravis.h, "sequence") */
    uint64_t underruns_at_start, last_mark;
    uint64_t discarded, id_gaps, lost_reported;
    uint64_t last_frame_id;
    int have_frame_id;
    uint32_t sequence;
    int have_sequence;
} aravis_cam;

/* GError → -errno with a message naming the device and the call; frees the GError. */
static int aravis_fail(const aravis_cam *c, GError *e, const char *what, sci_error *err)
{
    int rc = SCI_EDEVICE;
    if (e && e->domain == ARV_DEVICE_ERROR) {
        switch (e->code) {
        case ARV_DEVICE_ERROR_NOT_FOUND: rc = -ENOENT; break;
        case ARV_DEVICE_ERROR_FEATURE_NOT_FOUND:
        case ARV_DEVICE_ERROR_WRONG_FEATURE: rc = -ENOTSUP; break;
        case ARV_DEVICE_ERROR_NOT_CONTROLLER:
        case ARV_DEVICE_ERROR_PROTOCOL_ERROR_ACCESS_DENIED: rc = -EBUSY; break;
        case ARV_DEVICE_ERROR_NOT_CONNECTED: rc = -ENODEV; break;
        case ARV_DEVICE_ERROR_TIMEOUT:
        case ARV_DEVICE_ERROR_TRANSFER_ERROR: rc = -EIO; break;
        default: break;
        }
    } else if (e && e->domain == ARV_GC_ERROR) {
        switch (e->code) {
        case ARV_GC_ERROR_OUT_OF_RANGE: rc = -ERANGE; break;
        case ARV_GC_ERROR_NODE_NOT_FOUND:
        case ARV_GC_ERROR_ENUM_ENTRY_NOT_FOUND: rc = -ENOTSUP; break;
        default: rc = -EINVAL; break;
        }
    }
    if (atomic_load(&c->control_lost))
        rc = -ENODEV;
    rc = sci_error_set(err, rc, "%s: %s failed: %s", c->id, what, e ? e->message : "unknown error");
    if (e)
        g_error_free(e);
    return rc;
}

static void aravis_on_control_lost(ArvDevice *dev, gpointer user)
{
    (void)dev;
    atomic_store(&((aravis_cam *)user)->control_lost, 1);
}

/* Find a device id by model / serial (both optional) over Aravis's device list. */
static int aravis_find(aravis_cam *c, sci_error *err)
{
    arv_update_device_list();
    unsigned n = arv_get_n_devices();
    for (unsigned i = 0; i < n; i++) {
        const char *model = arv_get_device_model(i), *serial = arv_get_device_serial_nbr(i);
        if ((!c->want_model[0] || (model && strcmp(model, c->want_model) == 0)) &&
            (!c->want_serial[0] || (serial && strcmp(serial, c->want_serial) == 0))) {
            snprintf(c->id, sizeof c->id, "%s", arv_get_device_id(i));
            return 0;
        }
    }
    return sci_error_set(err, -ENOENT, "aravis: no camera with model \"%s\" serial \"%s\" among %u found",
                         c->want_model, c->want_serial, n);
}

/* Open c->id (or look it up) and fill the identity. */
static int aravis_connect(aravis_cam *c, sci_error *err)
{
    if (!c->id[0]) {
        int rc = aravis_find(c, err);
        if (rc < 0)
            return rc;
    }
    if (strncmp(c->id, "Fake_", 5) == 0)
        arv_enable_interface("Fake"); /* the in-process simulated camera, only when asked for by name */
    GError *e = NULL;
    c->cam = arv_camera_new(c->id, &e);
    if (!c->cam) {
        if (!e)
            return sci_error_set(err, -ENOENT, "%s: no such GenICam camera (Aravis found none by that id or address)",
                                 c->id);
        if (e->domain == ARV_DEVICE_ERROR && e->code == ARV_DEVICE_ERROR_NOT_FOUND) {
            int rc = sci_error_set(err, -ENOENT, "%s: no such GenICam camera (%s)", c->id, e->message);
            g_error_free(e);
            return rc;
        }
        return aravis_fail(c, e, "arv_camera_new", err);
    }
    if (e)
        g_clear_error(&e);
    atomic_store(&c->control_lost, 0);
    c->lost_handler = g_signal_connect(arv_camera_get_device(c->cam), "control-lost",
                                       G_CALLBACK(aravis_on_control_lost), c);
    c->ids_from_camera = arv_camera_is_gv_device(c->cam) || arv_camera_is_uv_device(c->cam);
    camera_identity *id = &c->ident;
    memset(id, 0, sizeof *id);
    snprintf(id->backend, sizeof id->backend, "aravis");
    snprintf(id->driver, sizeof id->driver, "%s",
             arv_camera_is_gv_device(c->cam) ? "GigEVision" : arv_camera_is_uv_device(c->cam) ? "USB3Vision" : "Fake");
    const char *vendor = arv_camera_get_vendor_name(c->cam, NULL), *model = arv_camera_get_model_name(c->cam, NULL);
    const char *serial = arv_camera_get_device_serial_number(c->cam, NULL);
    snprintf(id->card, sizeof id->card, "%s %s", vendor ? vendor : "?", model ? model : "?");
    snprintf(id->bus_info, sizeof id->bus_info, "%s", serial ? serial : "");
    snprintf(id->path, sizeof id->path, "%s", c->id);
    return 0;
}

static void aravis_disconnect(aravis_cam *c)
{
    if (c->stream) {
        g_object_unref(c->stream); /* stops Aravis's stream thread and frees the pool */
        c->stream = NULL;
    }
    if (c->cam) {
        if (c->lost_handler)
            g_signal_handler_disconnect(arv_camera_get_device(c->cam), c->lost_handler);
        c->lost_handler = 0;
        g_object_unref(c->cam);
        c->cam = NULL;
    }
    c->streaming = 0;
}

/* Set one named feature from an integer, by the node's type. */
static int aravis_set_feature(aravis_cam *c, const char *name, int64_t value, sci_error *err)
{
    ArvGcNode *node = arv_device_get_feature(arv_camera_get_device(c->cam), name);
    if (!node)
        return sci_error_set(err, -ENOTSUP, "%s (%s): no GenICam feature \"%s\" (trigger profile \"%s\")", c->id,
                             c->ident.card, name, c->profile_name);
    GError *e = NULL;
    if (ARV_IS_GC_BOOLEAN(node))
        arv_gc_boolean_set_value(ARV_GC_BOOLEAN(node), value != 0, &e);
    else if (ARV_IS_GC_ENUMERATION(node))
        arv_gc_enumeration_set_int_value(ARV_GC_ENUMERATION(node), value, &e);
    else if (ARV_IS_GC_FLOAT(node))
        arv_gc_float_set_value(ARV_GC_FLOAT(node), (double)value, &e);
    else if (ARV_IS_GC_INTEGER(node))
        arv_gc_integer_set_value(ARV_GC_INTEGER(node), value, &e);
    else
        return sci_error_set(err, -ENOTSUP, "%s: feature \"%s\" is not an integer, enumeration, boolean or float "
                             "(trigger profile \"%s\")", c->id, name, c->profile_name);
    if (e) {
        char what[160];
        snprintf(what, sizeof what, "setting \"%s\" = %lld (trigger profile \"%s\")", name, (long long)value,
                 c->profile_name);
        return aravis_fail(c, e, what, err);
    }
    return 0;
}

static int aravis_apply_profile(aravis_cam *c, sci_error *err)
{
    for (int i = 0; i < c->nctrl; i++) {
        int rc = aravis_set_feature(c, c->ctrl_names[i], c->ctrl_values[i], err);
        if (rc < 0)
            return rc;
    }
    return 0;
}

static int aravis_open(void **state, const camera_config *cfg, sci_error *err)
{
    aravis_cam *c = calloc(1, sizeof *c);
    if (!c)
        return sci_error_set(err, -ENOMEM, "aravis: out of memory");
    int rc;
    c->gain = -1;
    c->buffer_count = cfg->buffer_count ? cfg->buffer_count : 4;
    const char *name = cfg->device ? cfg->device : "aravis";
    if (c->buffer_count < 2 || c->buffer_count > CAMERA_MAX_BUFFERS) {
        rc = sci_error_set(err, -EINVAL, "%s: buffer count %d is outside 2..%d", name, c->buffer_count,
                           CAMERA_MAX_BUFFERS);
        goto fail;
    }
    if (cfg->trigger_profile_count > CAMERA_MAX_CONTROLS || cfg->trigger_profile_count < 0) {
        rc = sci_error_set(err, -EINVAL, "%s: more than %d trigger profile controls", name, CAMERA_MAX_CONTROLS);
        goto fail;
    }
    const camera_aravis_options *o = cfg->backend_options;
    if (o) {
        if (o->trigger != CAMERA_ARAVIS_TRIGGER_FREE_RUN && o->trigger != CAMERA_ARAVIS_TRIGGER_SOFTWARE &&
            o->trigger != CAMERA_ARAVIS_TRIGGER_LINE) {
            rc = sci_error_set(err, -EINVAL, "%s: trigger mode %d is not free-run, software or line", name,
                               (int)o->trigger);
            goto fail;
        }
        c->opt = *o;
    }
    snprintf(c->trigger_line, sizeof c->trigger_line, "%s", c->opt.trigger_line ? c->opt.trigger_line : "Line0");
    snprintf(c->trigger_activation, sizeof c->trigger_activation, "%s",
             c->opt.trigger_activation ? c->opt.trigger_activation : "");
    c->opt.trigger_line = c->opt.trigger_activation = NULL; /* borrowed: the copies above are used instead */
    snprintf(c->profile_name, sizeof c->profile_name, "%s",
             cfg->trigger_profile_name ? cfg->trigger_profile_name : "unnamed");
    for (int i = 0; i < cfg->trigger_profile_count; i++) {
        snprintf(c->ctrl_names[i], sizeof c->ctrl_names[i], "%s", cfg->trigger_profile[i].name);
        c->ctrl_values[i] = cfg->trigger_profile[i].value;
    }
    c->nctrl = cfg->trigger_profile_count;
    snprintf(c->id, sizeof c->id, "%s", cfg->device ? cfg->device : "");
    snprintf(c->want_model, sizeof c->want_model, "%s", cfg->card ? cfg->card : "");
    snprintf(c->want_serial, sizeof c->want_serial, "%s", cfg->bus_info ? cfg->bus_info : "");
    if ((rc = aravis_connect(c, err)) < 0)
        goto fail;
    if ((rc = aravis_apply_profile(c, err)) < 0)
        goto fail_disconnect;
    *state = c;
    return 0;
fail_disconnect:
    aravis_disconnect(c);
fail:
    free(c);
    return rc;
}

static void aravis_close(void *state)
{
    aravis_cam *c = state;
    if (!c)
        return;
    if (c->streaming && c->cam)
        arv_camera_stop_acquisition(c->cam, NULL);
    aravis_disconnect(c);
    free(c);
}

static void aravis_identity(void *state, camera_identity *out)
{
    *out = ((aravis_cam *)state)->ident;
}

/* Append `s` to a comma-separated list in buf. */
static void list_add(char *buf, size_t len, const char *s)
{
    size_t used = strlen(buf);
    if (used < len)
        snprintf(buf + used, len - used, "%s%s", used ? ", " : "", s);
}

static int aravis_choose_format(aravis_cam *c, enum pixfmt want, size_t *which, sci_error *err)
{
    GError *e = NULL;
    guint n = 0;
    gint64 *offered = arv_camera_dup_available_pixel_formats(c->cam, &n, &e);
    if (e)
        return aravis_fail(c, e, "reading PixelFormat entries", err);
    const char **names = arv_camera_dup_available_pixel_formats_as_strings(c->cam, &n, NULL);
    char list[512] = "";
    for (guint i = 0; names && i < n; i++)
        list_add(list, sizeof list, names[i]);
    g_free(names);
    int rc = -ENOTSUP;
    for (size_t k = 0; k < ARAVIS_NFORMATS && rc < 0; k++) {
        if (want != PIXFMT_NONE && aravis_formats[k].ours != want)
            continue;
        for (guint i = 0; i < n; i++)
            if ((ArvPixelFormat)offered[i] == aravis_formats[k].arv) {
                *which = k;
                rc = 0;
                break;
            }
    }
    g_free(offered);
    if (rc == 0)
        return 0;
    if (want == PIXFMT_NONE)
        return sci_error_set(err, -ENOTSUP, "%s (%s): offers no unpacked Mono or Bayer format (it offers %s)", c->id,
                             c->ident.card, list[0] ? list : "nothing");
    for (size_t k = 0; k < ARAVIS_NFORMATS; k++)
        if (aravis_formats[k].ours == want)
            return sci_error_set(err, -ENOTSUP, "%s (%s): does not offer %s (GenICam %s); it offers %s", c->id,
                                 c->ident.card, pixfmt_name(want), aravis_formats[k].genicam, list[0] ? list : "nothing");
    return sci_error_set(err, -ENOTSUP, "%s: format %s has no GenICam equivalent here (Mono8/10/12/16, Bayer 8/10/12/16)",
                         c->id, pixfmt_name(want));
}

static int aravis_set_dimension(aravis_cam *c, const char *feature, uint32_t v, sci_error *err)
{
    GError *e = NULL;
    gint64 min = 0, max = 0, inc = 1;
    arv_camera_get_integer_bounds(c->cam, feature, &min, &max, &e);
    if (e)
        return aravis_fail(c, e, feature, err);
    inc = arv_camera_get_integer_increment(c->cam, feature, NULL);
    if (inc < 1)
        inc = 1;
    if ((gint64)v < min || (gint64)v > max || ((gint64)v - min) % inc)
        return sci_error_set(err, -ENOTSUP, "%s: %s %u is not offered (%lld..%lld in steps of %lld)", c->id, feature, v,
                             (long long)min, (long long)max, (long long)inc);
    arv_camera_set_integer(c->cam, feature, v, &e);
    return e ? aravis_fail(c, e, feature, err) : 0;
}

static int aravis_set_format(void *state, const camera_config *want, camera_format *out, sci_error *err)
{
    aravis_cam *c = state;
    if (c->streaming)
        return sci_error_set(err, -EBUSY, "%s: cannot change the format while streaming", c->id);
    size_t k;
    int rc;
    if ((rc = aravis_choose_format(c, want->pixfmt, &k, err)) < 0)
        return rc;
    GError *e = NULL;
    arv_camera_set_pixel_format(c->cam, aravis_formats[k].arv, &e);
    if (e)
        return aravis_fail(c, e, "setting PixelFormat", err);
    if ((want->width || want->height) && (!want->width || !want->height))
        return sci_error_set(err, -EINVAL, "%s: frame size %ux%u: give both width and height", c->id, want->width,
                             want->height);
    if (want->width && ((rc = aravis_set_dimension(c, "Width", want->width, err)) < 0 ||
                        (rc = aravis_set_dimension(c, "Height", want->height, err)) < 0))
        return rc;
    if (want->interval_num && want->interval_den) {
        arv_camera_set_frame_rate(c->cam, (double)want->interval_den / want->interval_num, &e);
        if (e)
            return aravis_fail(c, e, "setting the frame rate", err);
    }
    gint x, y, w, h;
    arv_camera_get_region(c->cam, &x, &y, &w, &h, &e);
    ArvPixelFormat got = e ? 0 : arv_camera_get_pixel_format(c->cam, &e);
    guint payload = e ? 0 : arv_camera_get_payload(c->cam, &e);
    if (e)
        return aravis_fail(c, e, "reading the format back", err);
    if (got != aravis_formats[k].arv || w <= 0 || h <= 0 ||
        (want->width && ((uint32_t)w != want->width || (uint32_t)h != want->height)))
        return sci_error_set(err, -ENOTSUP, "%s: asked for %ux%u %s, the camera has %dx%d PixelFormat 0x%08x", c->id,
                             want->width, want->height, aravis_formats[k].genicam, w, h, (unsigned)got);
    enum pixfmt pf = aravis_formats[k].ours;
    size_t stride = pixfmt_min_stride(pf, (uint32_t)w);
    if ((size_t)payload < stride * (size_t)h)
        return sci_error_set(err, SCI_EDEVICE, "%s: payload of %u bytes is short of %dx%d %s", c->id, payload, w, h,
                             aravis_formats[k].genicam);
    c->fmt = (camera_format){.width = (uint32_t)w, .height = (uint32_t)h, .pixfmt = pf,
                             .bits_per_sample = pixfmt_info_get(pf)->bits_per_sample, .bytesperline = (uint32_t)stride,
                             .sizeimage = payload};
    if (arv_camera_is_frame_rate_available(c->cam, NULL)) {
        double fps = arv_camera_get_frame_rate(c->cam, NULL);
        if (fps > 0 && isfinite(fps)) {
            if (fabs(fps - round(fps)) < 1e-6 && round(fps) >= 1) {
                c->fmt.interval_num = 1;
                c->fmt.interval_den = (uint32_t)round(fps);
            } else {
                c->fmt.interval_num = 1000;
                c->fmt.interval_den = (uint32_t)round(fps * 1000);
            }
        }
    }
    c->arv_fmt = aravis_formats[k].arv;
    c->want = camera_config_format_request((uint32_t)w, (uint32_t)h, pf, want);
    c->have_fmt = 1;
    *out = c->fmt;
    return 0;
}

static int aravis_set_exposure(void *state, uint32_t *exposure_us, sci_error *err)
{
    aravis_cam *c = state;
    GError *e = NULL;
    if (!arv_camera_is_exposure_time_available(c->cam, NULL))
        return sci_error_set(err, -ENOTSUP, "%s (%s): no ExposureTime feature", c->id, c->ident.card);
    if (arv_camera_is_exposure_auto_available(c->cam, NULL)) {
        arv_camera_set_exposure_time_auto(c->cam, ARV_AUTO_OFF, &e); /* a manual value is ignored while auto is on */
        if (e)
            return aravis_fail(c, e, "setting ExposureAuto Off", err);
    }
    double min = 0, max = 0;
    arv_camera_get_exposure_time_bounds(c->cam, &min, &max, &e);
    if (e)
        return aravis_fail(c, e, "reading the exposure bounds", err);
    if (*exposure_us < min || *exposure_us > max)
        return sci_error_set(err, -ERANGE, "%s: exposure %u us is outside the camera's %.0f..%.0f us", c->id,
                             *exposure_us, min, max);
    arv_camera_set_exposure_time(c->cam, (double)*exposure_us, &e);
    double got = e ? 0 : arv_camera_get_exposure_time(c->cam, &e);
    if (e)
        return aravis_fail(c, e, "setting the exposure time", err);
    *exposure_us = got < 1 ? 1 : (uint32_t)lround(got);
    c->exposure_us = *exposure_us;
    return 0;
}

static int aravis_set_gain(void *state, int32_t *gain, sci_error *err)
{
    aravis_cam *c = state;
    GError *e = NULL;
    if (!arv_camera_is_gain_available(c->cam, NULL))
        return sci_error_set(err, -ENOTSUP, "%s (%s): no Gain or GainRaw feature", c->id, c->ident.card);
    if (arv_camera_is_gain_auto_available(c->cam, NULL)) {
        arv_camera_set_gain_auto(c->cam, ARV_AUTO_OFF, &e);
        if (e)
            return aravis_fail(c, e, "setting GainAuto Off", err);
    }
    double min = 0, max = 0;
    arv_camera_get_gain_bounds(c->cam, &min, &max, &e);
    if (e)
        return aravis_fail(c, e, "reading the gain bounds", err);
    if (*gain < min || *gain > max)
        return sci_error_set(err, -ERANGE, "%s: gain %d is outside the camera's %g..%g", c->id, (int)*gain, min, max);
    arv_camera_set_gain(c->cam, (double)*gain, &e);
    double got = e ? 0 : arv_camera_get_gain(c->cam, &e);
    if (e)
        return aravis_fail(c, e, "setting the gain", err);
    *gain = (int32_t)lround(got);
    c->gain = *gain;
    return 0;
}

static int aravis_apply_trigger(aravis_cam *c, sci_error *err)
{
    GError *e = NULL;
    switch (c->opt.trigger) {
    case CAMERA_ARAVIS_TRIGGER_FREE_RUN:
        arv_camera_clear_triggers(c->cam, &e);
        return e ? aravis_fail(c, e, "switching triggers off (free run)", err) : 0;
    case CAMERA_ARAVIS_TRIGGER_SOFTWARE:
        if (!arv_camera_is_software_trigger_supported(c->cam, NULL))
            return sci_error_set(err, -ENOTSUP, "%s (%s): no software trigger (TriggerSoftware)", c->id, c->ident.card);
        arv_camera_set_trigger(c->cam, "Software", &e);
        return e ? aravis_fail(c, e, "setting TriggerSource Software", err) : 0;
    case CAMERA_ARAVIS_TRIGGER_LINE:
        arv_camera_set_trigger(c->cam, c->trigger_line, &e);
        if (e) {
            char what[96];
            snprintf(what, sizeof what, "setting TriggerSource %s", c->trigger_line);
            return aravis_fail(c, e, what, err);
        }
        if (c->trigger_activation[0]) {
            arv_camera_set_string(c->cam, "TriggerActivation", c->trigger_activation, &e);
            if (e) {
                char what[96];
                snprintf(what, sizeof what, "setting TriggerActivation %s", c->trigger_activation);
                return aravis_fail(c, e, what, err);
            }
        }
        return 0;
    }
    return sci_error_set(err, -EINVAL, "%s: trigger mode %d unknown", c->id, (int)c->opt.trigger);
}

static uint64_t aravis_underruns(aravis_cam *c)
{
    guint64 done = 0, failed = 0, under = 0;
    arv_stream_get_statistics(c->stream, &done, &failed, &under);
    return under;
}

/* Give a buffer (back) to the stream, marking how many underruns precede its fill. Underruns happen only while
 * the input queue is empty, and the queue is FIFO: a buffer pushed onto an empty queue is filled before any
 * further underrun, so the count now is the count before its fill; one pushed behind others inherits the mark
 * of the one pushed just before it. (A frame being filled right now holds no buffer of the queue: it was marked
 * when pushed, and no underrun can happen between that push and the current count.) */
static void aravis_push(aravis_cam *c, ArvBuffer *b)
{
    aravis_slot *s = (aravis_slot *)arv_buffer_get_user_data(b);
    gint n_in = 0, n_out = 0;
    arv_stream_get_n_buffers(c->stream, &n_in, &n_out);
    if (n_in == 0)
        c->last_mark = aravis_underruns(c);
    s->underruns_before = c->last_mark;
    arv_stream_push_buffer(c->stream, b);
}

static int aravis_start(void *state, sci_error *err)
{
    aravis_cam *c = state;
    GError *e = NULL;
    int rc;
    if (!c->have_fmt)
        return sci_error_set(err, -EINVAL, "%s: start before a format was set", c->id);
    if ((rc = aravis_apply_trigger(c, err)) < 0)
        return rc;
    arv_camera_set_acquisition_mode(c->cam, ARV_ACQUISITION_MODE_CONTINUOUS, &e);
    if (e)
        return aravis_fail(c, e, "setting AcquisitionMode Continuous", err);
    if (arv_camera_is_gv_device(c->cam)) {
        if (c->opt.packet_size)
            arv_camera_gv_set_packet_size(c->cam, (gint)c->opt.packet_size, &e);
        else
            arv_camera_gv_auto_packet_size(c->cam, &e);
        if (e)
            return aravis_fail(c, e, "setting the GigE Vision packet size", err);
    }
    guint payload = arv_camera_get_payload(c->cam, &e);
    if (e)
        return aravis_fail(c, e, "reading PayloadSize", err);
    c->stream = arv_camera_create_stream(c->cam, NULL, NULL, &e);
    if (!c->stream)
        return e ? aravis_fail(c, e, "creating the stream", err)
                 : sci_error_set(err, SCI_EDEVICE, "%s: Aravis created no stream", c->id);
    c->underruns_at_start = c->last_mark = aravis_underruns(c);
    c->discarded = c->id_gaps = c->lost_reported = 0;
    c->have_frame_id = c->have_sequence = 0;
    c->sequence = 0;
    for (int i = 0; i < c->buffer_count; i++) {
        ArvBuffer *b = arv_buffer_new_full(payload, NULL, &c->slots[i], NULL);
        if (!b) {
            rc = sci_error_set(err, -ENOMEM, "%s: no memory for buffer %d of %u bytes", c->id, i, payload);
            goto fail;
        }
        aravis_push(c, b);
    }
    arv_camera_start_acquisition(c->cam, &e);
    if (e) {
        rc = aravis_fail(c, e, "AcquisitionStart", err);
        goto fail;
    }
    c->streaming = 1;
    return 0;
fail:
    g_object_unref(c->stream);
    c->stream = NULL;
    return rc;
}

static int aravis_stop(void *state, sci_error *err)
{
    aravis_cam *c = state;
    GError *e = NULL;
    int rc = 0;
    if (c->cam && !atomic_load(&c->control_lost))
        arv_camera_stop_acquisition(c->cam, &e);
    if (e)
        rc = aravis_fail(c, e, "AcquisitionStop", err);
    if (c->stream) {
        g_object_unref(c->stream);
        c->stream = NULL;
    }
    c->streaming = 0;
    return rc;
}

/* Frames missing between two GenICam frame ids. GigE Vision 1.x block ids are 16 bits with 0 invalid: 65535 is
 * followed by 1. Anything that is not a step forward (repeat, restart) counts as no loss. */
static uint64_t aravis_id_gap(uint64_t last, uint64_t id)
{
    if (id > last)
        return id - last - 1;
    if (last <= 0xffff && id <= 0xffff && last - id > 0x8000) /* 16-bit wrap, skipping 0 */
        return (id + 0xffff) - last - 1;
    return 0;
}

static int64_t clock_ns(clockid_t id)
{
    struct timespec t;
    clock_gettime(id, &t);
    return (int64_t)t.tv_sec * 1000000000LL + t.tv_nsec;
}

static int aravis_wait_frame(void *state, int64_t timeout_ns, camera_frame *out, sci_error *err)
{
    aravis_cam *c = state;
    int64_t deadline = clock_ns(CLOCK_MONOTONIC) + timeout_ns;
    for (;;) {
        if (atomic_load(&c->control_lost))
            return sci_error_set(err, -ENODEV, "%s (%s): camera lost (no answer to the heartbeat)", c->id,
                                 c->ident.card);
        int64_t left = deadline - clock_ns(CLOCK_MONOTONIC);
        ArvBuffer *b = left <= 0 ? arv_stream_try_pop_buffer(c->stream)
                                 : arv_stream_timeout_pop_buffer(c->stream, (guint64)((left + 999) / 1000));
        if (!b) {
            if (atomic_load(&c->control_lost))
                continue;
            return sci_error_set(err, -ETIMEDOUT, "%s: no frame within %lld ms", c->id,
                                 (long long)((timeout_ns + 999999) / 1000000));
        }
        if (arv_buffer_get_status(b) != ARV_BUFFER_STATUS_SUCCESS) {
            c->discarded++; /* a damaged frame is a lost frame: its id is spent, so no double count (max below) */
            aravis_push(c, b);
            continue;
        }
        const aravis_slot *s = arv_buffer_get_user_data(b);
        uint64_t id = arv_buffer_get_frame_id(b);
        int64_t sys_ns = (int64_t)arv_buffer_get_system_timestamp(b);
        gint w = arv_buffer_get_image_width(b), h = arv_buffer_get_image_height(b), xpad = 0, ypad = 0;
        ArvPixelFormat pf = arv_buffer_get_image_pixel_format(b);
        arv_buffer_get_image_padding(b, &xpad, &ypad);
        size_t size = 0;
        const void *data = arv_buffer_get_image_data(b, &size);
        int rc;
        if (!data || pf != c->arv_fmt || w != (gint)c->fmt.width || h != (gint)c->fmt.height || xpad < 0)
            rc = sci_error_set(err, SCI_EDEVICE, "%s: frame %llu is %dx%d PixelFormat 0x%08x, not the %ux%u 0x%08x "
                               "negotiated", c->id, (unsigned long long)id, w, h, (unsigned)pf, c->fmt.width,
                               c->fmt.height, (unsigned)c->arv_fmt);
        else
            rc = camera_frame_unpack(out, &c->fmt, data, size, c->fmt.bytesperline + (size_t)xpad, err);
        uint64_t under = s->underruns_before - c->underruns_at_start;
        aravis_push(c, b); /* back to the pool at once, whatever happened */
        if (rc < 0)
            return sci_error_prefix(err, "%s: frame %llu: ", c->id, (unsigned long long)id), rc;
        if (c->have_frame_id)
            c->id_gaps += aravis_id_gap(c->last_frame_id, id);
        c->last_frame_id = id;
        c->have_frame_id = 1;
        /* A camera on a wire numbers every frame it sends, so its id gaps are the losses (frames that found no
         * buffer and damaged ones included); Aravis's underrun count is no frame count there (GigE Vision counts
         * every packet of a frame that found no buffer). The in-process fake numbers only frames it filled, so
         * there the losses are the underruns, attributed by the push marks, and the discarded buffers. */
        uint64_t lost = c->ids_from_camera ? c->id_gaps : under + c->discarded;
        uint32_t lost_before = (uint32_t)(lost - c->lost_reported);
        c->lost_reported = lost;
        c->sequence = c->have_sequence ? c->sequence + 1 + lost_before : lost_before;
        c->have_sequence = 1;
        int64_t now_mono = clock_ns(CLOCK_MONOTONIC), now_real = clock_ns(CLOCK_REALTIME);
        out->sequence = c->sequence;
        out->timestamp_ns = sys_ns > 0 ? sys_ns - (now_real - now_mono) : now_mono;
        out->ts_source = CAMERA_TS_EOF;
        out->corrupt = 0;
        out->exposure_us = c->exposure_us;
        out->gain = c->gain;
        return 0;
    }
}

static int aravis_recover(void *state, sci_error *err)
{
    aravis_cam *c = state;
    int was_streaming = c->streaming;
    aravis_disconnect(c); /* no acquisition stop: the camera may be gone; reopening takes control anew */
    int rc;
    if ((rc = aravis_connect(c, err)) < 0 || (rc = aravis_apply_profile(c, err)) < 0)
        return rc;
    camera_format f;
    if (c->have_fmt && (rc = aravis_set_format(c, &c->want, &f, err)) < 0)
        return rc;
    return camera_recover_controls(&camera_aravis_ops, c, c->exposure_us, c->gain, was_streaming, err);
}

const camera_ops camera_aravis_ops = {
    .name = "aravis",
    .open = aravis_open,
    .close = aravis_close,
    .identity = aravis_identity,
    .set_format = aravis_set_format,
    .set_exposure_us = aravis_set_exposure,
    .set_gain = aravis_set_gain,
    .start = aravis_start,
    .stop = aravis_stop,
    .wait_frame = aravis_wait_frame,
    .recover = aravis_recover,
};

/* ---- the backend's own entry points ---- */

int camera_aravis_trigger_software(camera *cam, sci_error *err)
{
    aravis_cam *c = camera_backend_state(cam, &camera_aravis_ops);
    if (!c)
        return sci_error_set(err, -EINVAL, "software trigger: not an Aravis camera");
    if (atomic_load(&c->control_lost))
        return sci_error_set(err, -ENODEV, "%s: camera lost (no answer to the heartbeat)", c->id);
    if (!arv_camera_is_software_trigger_supported(c->cam, NULL))
        return sci_error_set(err, -ENOTSUP, "%s (%s): no software trigger (TriggerSoftware)", c->id, c->ident.card);
    GError *e = NULL;
    arv_camera_software_trigger(c->cam, &e);
    return e ? aravis_fail(c, e, "TriggerSoftware", err) : 0;
}

int camera_aravis_stream_stats_get(camera *cam, camera_aravis_stream_stats *out)
{
    aravis_cam *c = camera_backend_state(cam, &camera_aravis_ops);
    if (!c)
        return -EINVAL;
    memset(out, 0, sizeof *out);
    if (c->stream) {
        guint64 done = 0, failed = 0, under = 0;
        arv_stream_get_statistics(c->stream, &done, &failed, &under);
        out->completed = done;
        out->failures = failed;
        out->underruns = under - c->underruns_at_start;
    }
    out->id_gaps = c->id_gaps;
    out->last_frame_id = c->last_frame_id;
    return 0;
}

struct _ArvCamera *camera_aravis_arv_camera(camera *cam)
{
    aravis_cam *c = camera_backend_state(cam, &camera_aravis_ops);
    return c ? c->cam : NULL;
}

/* ---- config ---- */

static const char *const aravis_keys[] = {"trigger", "trigger_line", "trigger_activation", "packet_size", NULL};

int camera_aravis_options_from_json(const json_t *obj, const char *where, camera_aravis_options *out, sci_error *err)
{
    memset(out, 0, sizeof *out);
    if (!json_is_object(obj))
        return sci_error_set(err, SCI_ECONFIG, "%s: must be an object", where);
    const json_t *v = json_object_get(obj, "trigger");
    if (v) {
        static const char *const names[] = {"free-run", "software", "line"};
        const char *s = json_string_value(v);
        int found = -1;
        for (int i = 0; s && i < 3; i++)
            if (strcmp(s, names[i]) == 0)
                found = i;
        if (found < 0)
            return sci_error_set(err, SCI_ECONFIG, "%s.trigger: must be \"free-run\", \"software\" or \"line\"", where);
        out->trigger = (enum camera_aravis_trigger)found;
    }
    if ((v = json_object_get(obj, "trigger_line"))) {
        if (!json_is_string(v) || !json_string_value(v)[0])
            return sci_error_set(err, SCI_ECONFIG, "%s.trigger_line: must be a line name such as \"Line1\"", where);
        out->trigger_line = json_string_value(v);
    }
    if ((v = json_object_get(obj, "trigger_activation"))) {
        if (!json_is_string(v) || !json_string_value(v)[0])
            return sci_error_set(err, SCI_ECONFIG, "%s.trigger_activation: must be a string such as \"RisingEdge\"",
                                 where);
        out->trigger_activation = json_string_value(v);
    }
    if ((v = json_object_get(obj, "packet_size"))) {
        if (!json_is_integer(v) || json_integer_value(v) < 576 || json_integer_value(v) > 16384)
            return sci_error_set(err, SCI_ECONFIG, "%s.packet_size: must be an integer number of bytes in 576..16384",
                                 where);
        out->packet_size = (uint32_t)json_integer_value(v);
    }
    if ((out->trigger_line || out->trigger_activation) && out->trigger != CAMERA_ARAVIS_TRIGGER_LINE)
        return sci_error_set(err, SCI_ECONFIG, "%s: trigger_line / trigger_activation need \"trigger\": \"line\"", where);
    return 0;
}

int camera_aravis_config_from_json(const json_t *obj, const char *where, camera_config *cfg,
                                   camera_aravis_options *opt, sci_error *err)
{
    int rc = camera_aravis_options_from_json(obj, where, opt, err);
    if (rc < 0)
        return rc;
    /* camera_config_from_json refuses keys it does not know: hand it a shallow copy without ours. The copy's
     * values are the same json_t objects, so the strings it returns stay owned by `obj`. */
    json_t *rest = json_copy((json_t *)obj);
    if (!rest)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", where);
    for (int i = 0; aravis_keys[i]; i++)
        json_object_del(rest, aravis_keys[i]);
    rc = camera_config_from_json(rest, where, cfg, err);
    json_decref(rest);
    if (rc < 0)
        return rc;
    cfg->backend_options = opt;
    return 0;
}
