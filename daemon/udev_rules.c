/* daemon/udev_rules.c — udev rules for the configured devices (see the header). */
#include "daemon/udev_rules.h"

#include <ctype.h>
#include <errno.h>
#include <string.h>

#define GM "GROUP=\"" SCICAPD_UDEV_GROUP "\", MODE=\"" SCICAPD_UDEV_MODE "\""

/* udev match values are globs: refuse what would widen the match or break the line. */
static int safe_value(const char *s)
{
    if (!s[0])
        return 0;
    for (const char *p = s; *p; p++)
        if (!isprint((unsigned char)*p) || strchr("\"*?[]\\|", *p))
            return 0;
    return 1;
}

static int hex4(const char *s)
{
    if (strlen(s) != 4)
        return 0;
    for (int i = 0; i < 4; i++)
        if (!isxdigit((unsigned char)s[i]))
            return 0;
    return 1;
}

/* ", ATTRS{idVendor}==..." for devices.camera.usb; 1 when written, 0 when absent, SCI_ECONFIG when bad. */
static int usb_match(char *buf, size_t n, const scicapd_config *c, sci_error *err)
{
    if (!c->camera_usb_vendor[0])
        return 0;
    if (!hex4(c->camera_usb_vendor) || !hex4(c->camera_usb_product) ||
        (c->camera_usb_serial[0] && !safe_value(c->camera_usb_serial)))
        return sci_error_set(err, SCI_ECONFIG, "devices.camera.usb: vendor and product must be 4 hex digits "
                             "(lsusb shows them as VVVV:PPPP), serial printable without * ? [ ] \" \\ |");
    char lower_v[5], lower_p[5];
    for (int i = 0; i < 5; i++) {
        lower_v[i] = (char)tolower((unsigned char)c->camera_usb_vendor[i]);
        lower_p[i] = (char)tolower((unsigned char)c->camera_usb_product[i]);
    }
    snprintf(buf, n, "ATTRS{idVendor}==\"%s\", ATTRS{idProduct}==\"%s\"%s%s%s", lower_v, lower_p,
             c->camera_usb_serial[0] ? ", ATTRS{serial}==\"" : "", c->camera_usb_serial,
             c->camera_usb_serial[0] ? "\"" : "");
    return 1;
}

static int dlpc900_rules(FILE *f, const scicapd_config *c, sci_error *err)
{
    if (c->dmd_emulator) {
        fprintf(f, "# dmd: the in-process DLPC900 emulator (uhid) and the hidraw node it creates\n"
                   "KERNEL==\"uhid\", " GM "\n"
                   "SUBSYSTEM==\"hidraw\", KERNELS==\"0003:0451:C900.*\", " GM "\n");
        return 0;
    }
    char serial[96] = "";
    if (c->dmd_serial[0]) {
        if (!safe_value(c->dmd_serial))
            return sci_error_set(err, SCI_ECONFIG, "devices.dmd.serial \"%s\": not usable in a udev match",
                                 c->dmd_serial);
        snprintf(serial, sizeof serial, ", ATTRS{serial}==\"%s\"", c->dmd_serial);
    }
    fprintf(f, "# dmd: TI DLPC900 on USB 0451:c900%s%s\n", c->dmd_serial[0] ? ", serial " : " (any serial)",
            c->dmd_serial);
    fprintf(f, "SUBSYSTEM==\"hidraw\", ATTRS{idVendor}==\"0451\", ATTRS{idProduct}==\"c900\"%s, " GM
               ", SYMLINK+=\"scicap-dmd\"\n", serial);
    fprintf(f, "SUBSYSTEM==\"usb\", ATTRS{idVendor}==\"0451\", ATTRS{idProduct}==\"c900\"%s, " GM "\n", serial);
    return 0;
}

/* /dev/v4l/by-id/BUS-SERIAL-video-indexN or /dev/v4l/by-path/PATH-video-indexN: the udev keys behind them. */
static int v4l_match(char *buf, size_t n, const char *dev, sci_error *err)
{
    static const char by_id[] = "/dev/v4l/by-id/", by_path[] = "/dev/v4l/by-path/";
    int is_id = strncmp(dev, by_id, sizeof by_id - 1) == 0, is_path = strncmp(dev, by_path, sizeof by_path - 1) == 0;
    const char *name = is_id ? dev + sizeof by_id - 1 : is_path ? dev + sizeof by_path - 1 : NULL;
    const char *idx = name ? strstr(name, "-video-index") : NULL;
    if (!name || !idx || idx == name || !isdigit((unsigned char)idx[12]))
        return sci_error_set(err, SCI_ECONFIG, "devices.camera.device \"%s\": not a stable name, so no narrow "
                             "udev rule matches it; name the camera by /dev/v4l/by-id/... (or by-path), or add "
                             "devices.camera.usb {\"vendor\", \"product\", \"serial\"}", dev);
    char key[256];
    size_t klen = (size_t)(idx - name);
    const char *start = name;
    if (is_id) { /* BUS-SERIAL: udev's 60-persistent-v4l.rules joins ID_BUS and ID_SERIAL with '-' */
        const char *dash = memchr(name, '-', klen);
        if (!dash || dash + 1 >= idx)
            return sci_error_set(err, SCI_ECONFIG, "devices.camera.device \"%s\": expected by-id/BUS-SERIAL-"
                                 "video-indexN", dev);
        start = dash + 1;
        klen = (size_t)(idx - start);
    }
    if (klen >= sizeof key)
        return sci_error_set(err, SCI_ECONFIG, "devices.camera.device: name too long");
    memcpy(key, start, klen);
    key[klen] = '\0';
    if (!safe_value(key) || !safe_value(idx + 12))
        return sci_error_set(err, SCI_ECONFIG, "devices.camera.device \"%s\": not usable in a udev match", dev);
    snprintf(buf, n, "ENV{%s}==\"%s\", ATTR{index}==\"%s\"", is_id ? "ID_SERIAL" : "ID_PATH", key, idx + 12);
    return 0;
}

/* A camera's rules: its devices.camera.usb match when given, else a V4L2 device's stable name (v4l2) or nothing for
 * Aravis (a GigE Vision camera has no device node). */
static int camera_rules(FILE *f, const scicapd_config *c, int v4l2, sci_error *err)
{
    char m[512];
    int usb = usb_match(m, sizeof m, c, err);
    if (usb < 0)
        return usb;
    const char *dev = json_string_value(json_object_get(c->camera_json, "device"));
    if (v4l2) {
        if (!usb) {
            int rc = v4l_match(m, sizeof m, dev ? dev : "/dev/video0", err);
            if (rc < 0)
                return rc;
        }
        fprintf(f, "# camera: V4L2 %s\nSUBSYSTEM==\"video4linux\", %s, " GM "\n", dev ? dev : "(default device)", m);
        return 0;
    }
    if (!usb) {
        fprintf(f, "# camera: GenICam \"%s\" through Aravis: a GigE Vision camera needs no device node; for a "
                   "USB3 Vision camera add devices.camera.usb {\"vendor\", \"product\", \"serial\"}\n",
                dev ? dev : "(first found)");
        return 0;
    }
    fprintf(f, "# camera: USB3 Vision \"%s\" through Aravis (libusb)\nSUBSYSTEM==\"usb\", %s, " GM "\n",
            dev ? dev : "(first found)", m);
    return 0;
}

static int v4l2_rules(FILE *f, const scicapd_config *c, sci_error *err) { return camera_rules(f, c, 1, err); }

static int aravis_rules(FILE *f, const scicapd_config *c, sci_error *err) { return camera_rules(f, c, 0, err); }

static int gpiod_rules(FILE *f, const scicapd_config *c, sci_error *err)
{
    const char *chip = json_string_value(json_object_get(c->trigger_json, "chip"));
    if (chip && strncmp(chip, "/dev/", 5) == 0)
        chip += 5;
    int ok = chip && strncmp(chip, "gpiochip", 8) == 0 && chip[8];
    for (const char *p = ok ? chip + 8 : ""; *p; p++)
        ok &= isdigit((unsigned char)*p) != 0;
    if (!ok)
        return sci_error_set(err, SCI_ECONFIG, "devices.trigger.chip \"%s\": name the chip gpiochipN (gpiodetect "
                             "lists them) for a udev rule", chip ? chip : "");
    fprintf(f, "# trigger: GPIO chip %s\nSUBSYSTEM==\"gpio\", KERNEL==\"%s\", " GM "\n", chip, chip);
    return 0;
}

/* The backends that open a device node, one row each (a backend with none, the simulated ones, has no row): a new
 * hardware backend adds its row here as well as in drivers/backends.c. */
typedef struct udev_row {
    const char *kind, *backend;
    int (*rules)(FILE *f, const scicapd_config *c, sci_error *err);
} udev_row;

static const udev_row udev_rows[] = {
    {"dmd", "dlpc900", dlpc900_rules},
    {"camera", "v4l2", v4l2_rules},
    {"camera", "aravis", aravis_rules},
    {"trigger", "gpiod", gpiod_rules},
};

static const udev_row *udev_row_find(const char *kind, const char *backend)
{
    for (size_t i = 0; i < sizeof udev_rows / sizeof udev_rows[0]; i++)
        if (strcmp(udev_rows[i].kind, kind) == 0 && strcmp(udev_rows[i].backend, backend) == 0)
            return &udev_rows[i];
    return NULL;
}

int scicapd_udev_rules_write(FILE *f, const scicapd_config *c, sci_error *err)
{
    fprintf(f, "# udev rules for the devices of %s, made by `scicapd --udev-rules`.\n"
               "# Install as /etc/udev/rules.d/71-scicap-local.rules, then: udevadm control --reload-rules && "
               "udevadm trigger\n", c->path[0] ? c->path : "the built-in configuration");
    const char *kinds[3][2] = {{"dmd", c->dmd_backend}, {"camera", c->camera_backend}, {"trigger", c->trigger_backend}};
    for (int k = 0; k < 3; k++) {
        const udev_row *r = udev_row_find(kinds[k][0], kinds[k][1]);
        if (!r) {
            fprintf(f, "# %s: backend \"%s\" needs no device node\n", kinds[k][0], kinds[k][1]);
            continue;
        }
        int rc = r->rules(f, c, err);
        if (rc < 0)
            return rc;
    }
    if (fflush(f) != 0 || ferror(f))
        return sci_error_set(err, -EIO, "writing the rules: %s", strerror(errno));
    return 0;
}
