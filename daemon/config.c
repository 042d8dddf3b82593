/* daemon/config.c — parse and validate scicapd.json (docs/config.md). */
#include "daemon/config.h"

#include <arpa/inet.h>
#include <errno.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/un.h>
#include <unistd.h>

#include "base/json.h"
#include "base/json_fields.h"
#include "recon/solver.h"
#include "daemon/backends.h"
#include "drivers/camera.h"
#include "drivers/trigger.h"

/* The measured curves when the file does not name them: $SCICAP_DATADIR/results.csv when the variable is set (an
 * install elsewhere than PREFIX), else the installed SCICAP_DATADIR/results.csv (`buf` on entry); when that is not
 * readable and the binary runs from a build tree (<tree>/build/scicapd), the tree's bench/results.csv, so that a
 * reconstruction with a budget works before `make install`. Nothing readable: buf names the first candidate, and
 * the budget request's error names it. */
static void default_curves(char *buf, size_t n)
{
    const char *env = getenv("SCICAP_DATADIR");
    if (env && env[0])
        snprintf(buf, n, "%s/results.csv", env);
    if (access(buf, R_OK) == 0)
        return;
    char exe[SCICAPD_PATH_MAX], tree[SCICAPD_PATH_MAX + 32];
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (len <= 0)
        return;
    exe[len] = '\0';
    char *slash = strrchr(exe, '/');
    if (!slash)
        return;
    *slash = '\0';
    snprintf(tree, sizeof tree, "%s/../bench/results.csv", exe);
    if (access(tree, R_OK) == 0 && strlen(tree) < n)
        snprintf(buf, n, "%s", tree);
}

static void defaults(scicapd_config *c)
{
    memset(c, 0, sizeof *c);
    snprintf(c->socket_path, sizeof c->socket_path, "/run/scicapd/control.sock");
    c->socket_mode = 0660;
    snprintf(c->socket_group, sizeof c->socket_group, "scicap");
    /* distinct from the socket's group: reaching the socket must not make a user an admin (cancel others' jobs,
     * shut down); a group that does not exist makes only root and the daemon's user admins */
    snprintf(c->admin_group, sizeof c->admin_group, "scicap-admin");
    c->max_clients = 32;
    c->admin_slots = 2;
    c->request_timeout_ms = 10000;
    c->idle_timeout_ms = 300000;
    c->max_line_bytes = 65536;
    c->max_per_uid = 8;
    c->stall_timeout_ms = 60000;
    snprintf(c->storage_root, sizeof c->storage_root, "/var/lib/scicapd");
    snprintf(c->runtime_dir, sizeof c->runtime_dir, "/run/scicapd");
    c->fsync = 1;
    c->writers = 2;
    c->previews = 1;
    c->camera_readout_us = 100;
    strcpy(c->dmd_backend, "sim");
    strcpy(c->camera_backend, "sim");
    strcpy(c->trigger_backend, "sim");
    c->sim_counts_per_unit = 6000;
    c->sim_dark_counts = 200;
    c->sim_read_noise = 2;
    c->sim_seed = 1;
    c->sim_dmd_latency_us = 300;
    scicapd_mask_set *m = &c->mask_sets[0];
    snprintf(m->name, sizeof m->name, "random8");
    m->frames = 8;
    m->seed = 7;
    m->spec = (sim_mask_spec){.kind = SIM_MASK_RANDOM, .density = 0.5, .block = 4, .step = 1, .dir_y = 1,
                              .scale = 1};
    c->mask_set_count = 1;
    snprintf(c->capture_mask_set, sizeof c->capture_mask_set, "random8");
    c->pattern_us = 1000;
    c->dark_us = 100;
    c->sync_mode = SYNC_MODE_HOST_MASTER;
    snprintf(c->recon_method, sizeof c->recon_method, "%s", solver_list(NULL)[0]->name); /* the table's first */
    strcpy(c->recon_preset, "balanced");
    snprintf(c->recon_curves, sizeof c->recon_curves, "%s/results.csv", SCICAP_DATADIR);
    default_curves(c->recon_curves, sizeof c->recon_curves);
    c->recon_auto = 0;
    c->workers = 2;
    c->recon_checkpoint_every = 100; /* as scicap recon --checkpoint-every */
    c->capture_queue = 16;
    c->recon_queue = 16;
    snprintf(c->web_host, sizeof c->web_host, "127.0.0.1");
    c->web_port = 8080;
    c->web_max_connections = 64;
    c->web_timeout_s = 10;
}

int scicapd_config_default(scicapd_config **out, sci_error *err)
{
    scicapd_config *c = malloc(sizeof *c);
    if (!c)
        return sci_error_set(err, -ENOMEM, "config: out of memory");
    defaults(c);
    *out = c;
    return 0;
}

void scicapd_config_free(scicapd_config *c)
{
    if (!c)
        return;
    json_decref(c->camera_json);
    json_decref(c->trigger_json);
    free(c);
}

/* A string member copied into buf[n]; too long is an error naming the key. */
static int get_str(const sci_json_doc *doc, const json_t *o, const char *op, const char *key, char *buf, size_t n,
                   sci_error *err)
{
    const char *s = NULL;
    int rc = sci_json_get_string(doc, o, op, key, 0, &s, err);
    if (rc != 0)
        return rc;
    char path[256];
    if (strlen(s) >= n)
        return sci_json_fail(doc, err, sci_json_path_key(path, sizeof path, op, key), "longer than %zu bytes",
                             n - 1);
    snprintf(buf, n, "%s", s);
    return 0;
}

/* An object member (absent: NULL, 0); anything else than an object is an error. */
static int get_obj(const sci_json_doc *doc, const json_t *o, const char *op, const char *key, const json_t **out,
                   sci_error *err)
{
    char path[256];
    *out = json_object_get(o, key);
    if (*out && !json_is_object(*out))
        return sci_json_fail(doc, err, sci_json_path_key(path, sizeof path, op, key), "must be an object");
    return 0;
}

/* a control socket path must fit sockaddr_un's sun_path, NUL included */
#define SUN_PATH_BYTES sizeof(((struct sockaddr_un *)0)->sun_path)
#define CFG(key, type, member, ...) {key, type, offsetof(scicapd_config, member), __VA_ARGS__}
#define CFG_SIZE(member) sizeof(((scicapd_config *)0)->member)
#define CFG_STR(key, member, bytes, line) \
    {key, SCI_JSON_STRING, offsetof(scicapd_config, member), .size = (bytes), .help = line}

static const sci_json_field control_fields[] = {
    CFG_STR("socket", socket_path, SUN_PATH_BYTES, "control socket path (at most 107 bytes: sun_path's size)"),
    CFG_STR("group", socket_group, SCICAPD_NAME_MAX, "group of the socket"),
    CFG_STR("admin_group", admin_group, SCICAPD_NAME_MAX, "group whose members may use admin commands"),
    CFG("max_clients", SCI_JSON_INT, max_clients, .lo = 1, .hi = 1024, .help = "connections at once"),
    CFG("max_line_bytes", SCI_JSON_SIZE, max_line_bytes, .lo = 1024, .hi = 16 << 20, .help = "longest request"),
    CFG("admin_slots", SCI_JSON_INT, admin_slots, .lo = 0, .hi = 64, .help = "connections kept for admins"),
    CFG("request_timeout_ms", SCI_JSON_INT, request_timeout_ms, .lo = 100, .hi = 3600000, .help = "ms"),
    CFG("idle_timeout_ms", SCI_JSON_INT, idle_timeout_ms, .lo = 0, .hi = 86400000, .help = "ms, 0: none"),
    CFG("max_per_uid", SCI_JSON_INT, max_per_uid, .lo = 0, .hi = 1024, .help = "connections per user, 0: any"),
    CFG("stall_timeout_ms", SCI_JSON_INT, stall_timeout_ms, .lo = 0, .hi = 86400000, .help = "ms, 0: none"),
};

static int parse_control(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"socket", "mode", "group", "admin_group", "max_clients", "max_line_bytes",
                                       "admin_slots", "request_timeout_ms", "idle_timeout_ms", "max_per_uid",
                                       "stall_timeout_ms", NULL};
    int rc;
    if ((rc = sci_json_check_keys(doc, o, "control", keys, err)) < 0 ||
        (rc = sci_json_fields_read(doc, o, "control", control_fields, SCI_JSON_FIELDS_COUNT(control_fields), c,
                                   err)) < 0)
        return rc;
    if (c->admin_slots >= c->max_clients && !json_object_get(o, "admin_slots"))
        c->admin_slots = c->max_clients - 1; /* the default shrinks with a small max_clients */
    if (c->admin_slots >= c->max_clients)
        return sci_json_fail(doc, err, "control.admin_slots", "must be smaller than control.max_clients (%d), or "
                             "no ordinary user could connect", c->max_clients);
    if (c->socket_path[0] != '/')
        return sci_json_fail(doc, err, "control.socket", "must be an absolute path (got \"%s\")", c->socket_path);
    char mode[16] = "";
    if ((rc = get_str(doc, o, "control", "mode", mode, sizeof mode, err)) < 0)
        return rc;
    if (rc == 0 && mode[0]) {
        char *end;
        unsigned long m = strtoul(mode, &end, 8);
        if (*end || m > 0777 || (m & 0600) != 0600)
            return sci_json_fail(doc, err, "control.mode", "must be an octal mode string such as \"0660\" that "
                                 "lets the owner read and write (got \"%s\")", mode);
        c->socket_mode = (unsigned)m;
    }
    return 0;
}

static int parse_storage(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"root", "runtime_dir", "fsync", "writers", "previews", NULL};
    static const sci_json_field fields[] = {
        CFG("writers", SCI_JSON_INT, writers, .lo = 1, .hi = 16, .help = "threads writing capture folders"),
        CFG("previews", SCI_JSON_BOOL, previews, .help = "write preview PNGs in capture folders"),
        CFG_STR("root", storage_root, SCICAPD_PATH_MAX - 64, "captures live here (64 bytes kept for names)"),
        CFG_STR("runtime_dir", runtime_dir, SCICAPD_PATH_MAX, "pid file and runtime state"),
        CFG("fsync", SCI_JSON_BOOL, fsync, .help = "make every write durable before it is reported"),
    };
    int rc;
    if ((rc = sci_json_check_keys(doc, o, "storage", keys, err)) < 0 ||
        (rc = sci_json_fields_read(doc, o, "storage", fields, SCI_JSON_FIELDS_COUNT(fields), c, err)) < 0)
        return rc;
    if (c->storage_root[0] != '/')
        return sci_json_fail(doc, err, "storage.root", "must be an absolute path (got \"%s\")", c->storage_root);
    return 0;
}

/* Is `name` a backend of this kind? The device tables say (daemon/backends.h), so a new backend needs no edit
 * here. */
static int backend_known(const char *kind, const char *name, sci_error *err)
{
    scicapd_camera_backend cb;
    if (strcmp(kind, "camera") == 0)
        return scicapd_camera_backend_get(name, &cb, err);
    if (strcmp(kind, "trigger") == 0)
        return scicapd_trigger_backend_find(name, err) ? 0 : SCI_ECONFIG;
    return scicapd_dmd_backend_find(name, err) ? 0 : SCI_ECONFIG;
}

/* "dmd": {"backend": "sim", "serial": "..."}; "camera"/"trigger": {"backend": ..., backend keys...}. `strip`
 * names the daemon's own keys, left out of the copy in *rest. */
static int parse_device(const sci_json_doc *doc, const json_t *dev, const char *name, char *backend, size_t bn,
                        const char *const *strip, json_t **rest, sci_error *err)
{
    const json_t *o;
    char path[64];
    int rc = get_obj(doc, dev, "devices", name, &o, err);
    if (rc < 0 || !o)
        return rc;
    snprintf(path, sizeof path, "devices.%s", name);
    char value[16];
    if ((rc = get_str(doc, o, path, "backend", value, sizeof value, err)) < 0)
        return rc;
    if (rc == 0) {
        sci_error e2 = {0};
        char bpath[80];
        if (backend_known(name, value, &e2) < 0)
            return sci_json_fail(doc, err, sci_json_path_key(bpath, sizeof bpath, path, "backend"), "%s", e2.msg);
        snprintf(backend, bn, "%s", value);
    }
    if (rest) {
        json_t *copy = json_deep_copy(o);
        if (!copy)
            return sci_error_set(err, -ENOMEM, "config: out of memory");
        json_object_del(copy, "backend");
        for (int i = 0; strip && strip[i]; i++)
            json_object_del(copy, strip[i]);
        json_decref(*rest);
        *rest = copy;
    }
    return 0;
}

/* A driver's own validation (camera_config_from_json, trigger_config_from_json) reports "where.key: reason";
 * re-issue it with the file position of that key. */
static int driver_fail(const sci_json_doc *doc, const sci_error *e2, sci_error *err)
{
    char path[256];
    const char *sep = strstr(e2->msg, ": ");
    size_t n = sep ? (size_t)(sep - e2->msg) : 0;
    if (!sep || n >= sizeof path)
        return sci_json_fail(doc, err, "devices", "%s", e2->msg);
    memcpy(path, e2->msg, n);
    path[n] = '\0';
    return sci_json_fail(doc, err, path, "%s", sep + 2);
}

static int parse_dmd(const sci_json_doc *doc, const json_t *d, scicapd_config *c, sci_error *err)
{
    static const char *const dkeys[] = {"backend", "serial", "emulator", "timeout_ms", "trigger_delay_us",
                                        "trigger_falling", NULL};
    static const sci_json_field fields[] = {
        CFG_STR("serial", dmd_serial, SCICAPD_NAME_MAX, "which DMD, \"\": the first found"),
        CFG("emulator", SCI_JSON_BOOL, dmd_emulator, .help = "the DLPC900 protocol emulated in-process"),
        CFG("timeout_ms", SCI_JSON_INT, dmd_timeout_ms, .lo = 1, .hi = 60000, .help = "per USB transfer"),
        CFG("trigger_delay_us", SCI_JSON_U32, dmd_trigger_delay_us, .lo = 0, .hi = 65535, .help = "microseconds"),
        CFG("trigger_falling", SCI_JSON_BOOL, dmd_trigger_falling, .help = "trigger on the falling edge"),
    };
    int rc;
    if ((rc = sci_json_check_keys(doc, d, "devices.dmd", dkeys, err)) < 0 ||
        (rc = sci_json_fields_read(doc, d, "devices.dmd", fields, SCI_JSON_FIELDS_COUNT(fields), c, err)) < 0)
        return rc;
    if (!scicapd_dmd_is_dlpc900(scicapd_dmd_backend_find(c->dmd_backend, NULL))) {
        static const char *const hw[] = {"emulator", "timeout_ms", "trigger_delay_us", "trigger_falling", NULL};
        for (int i = 0; hw[i]; i++)
            if (json_object_get(d, hw[i])) {
                char p[128];
                return sci_json_fail(doc, err, sci_json_path_key(p, sizeof p, "devices.dmd", hw[i]),
                                     "only for the \"dlpc900\" backend (the \"sim\" DMD is always emulated)");
            }
    }
    return 0;
}

static int parse_devices(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"dmd", "camera", "trigger", NULL};
    static const char *const cam_strip[] = {"readout_us", "usb", NULL};
    static const sci_json_field cam_fields[] = {
        CFG("readout_us", SCI_JSON_U32, camera_readout_us, .lo = 0, .hi = 1000000, .help = "sensor readout"),
    };
    static const sci_json_field usb_fields[] = {
        CFG_STR("vendor", camera_usb_vendor, CFG_SIZE(camera_usb_vendor), "USB vendor id (lsusb)"),
        CFG_STR("product", camera_usb_product, CFG_SIZE(camera_usb_product), "USB product id (lsusb)"),
        CFG_STR("serial", camera_usb_serial, SCICAPD_NAME_MAX, "USB serial, \"\": any"),
    };
    int rc;
    if ((rc = sci_json_check_keys(doc, o, "devices", keys, err)) < 0 ||
        (rc = parse_device(doc, o, "dmd", c->dmd_backend, sizeof c->dmd_backend, NULL, NULL, err)) < 0 ||
        (rc = parse_device(doc, o, "camera", c->camera_backend, sizeof c->camera_backend, cam_strip,
                           &c->camera_json, err)) < 0 ||
        (rc = parse_device(doc, o, "trigger", c->trigger_backend, sizeof c->trigger_backend, NULL,
                           &c->trigger_json, err)) < 0)
        return rc;
    const json_t *d = json_object_get(o, "dmd");
    if (d && (rc = parse_dmd(doc, d, c, err)) < 0)
        return rc;
    const json_t *cam = json_object_get(o, "camera");
    if (cam && (rc = sci_json_fields_read(doc, cam, "devices.camera", cam_fields, SCI_JSON_FIELDS_COUNT(cam_fields), c, err)) < 0)
        return rc;
    const json_t *usb = cam ? json_object_get(cam, "usb") : NULL;
    if (usb) { /* the camera's USB ids, for `scicapd --udev-rules` only (daemon/udev_rules.h) */
        static const char *const ukeys[] = {"vendor", "product", "serial", NULL};
        if (!json_is_object(usb))
            return sci_json_fail(doc, err, "devices.camera.usb", "must be an object {\"vendor\", \"product\", "
                                 "\"serial\"}");
        if ((rc = sci_json_check_keys(doc, usb, "devices.camera.usb", ukeys, err)) < 0 ||
            (rc = sci_json_fields_read(doc, usb, "devices.camera.usb", usb_fields, SCI_JSON_FIELDS_COUNT(usb_fields),
                                       c, err)) < 0)
            return rc;
        if (!c->camera_usb_vendor[0] || !c->camera_usb_product[0])
            return sci_json_fail(doc, err, "devices.camera.usb", "needs \"vendor\" and \"product\" (lsusb: "
                                 "ID vendor:product)");
    }
    /* names checked by parse_device against the same tables */
    scicapd_camera_backend b;
    sci_error e2 = {0};
    if (scicapd_camera_backend_get(c->camera_backend, &b, &e2) < 0)
        return sci_json_fail(doc, err, "devices.camera.backend", "%s", e2.msg);
    const trigger_ops *tops = scicapd_trigger_backend_find(c->trigger_backend, NULL);
    int sim_cam = b.simulated, sim_trig = scicapd_trigger_simulated(tops);
    if (!b.parse && c->camera_json && json_object_size(c->camera_json) > 0)
        return sci_json_fail(doc, err, "devices.camera", "the %s camera takes no settings besides \"backend\" "
                             "(its size is the scene's)", c->camera_backend);
    if (sim_trig && c->trigger_json && json_object_size(c->trigger_json) > 0)
        return sci_json_fail(doc, err, "devices.trigger", "the %s trigger takes no settings besides \"backend\"",
                             c->trigger_backend);
    /* The drivers' own validation, at load time, so that a typo is found by --check-config and by reload. */
    int fake_cam = 0;
    if (b.parse) {
        camera_config cc;
        scicapd_camera_opts opts;
        if (b.parse(c->camera_json, "devices.camera", &cc, &opts, &e2) < 0)
            return driver_fail(doc, &e2, err);
        if (!cc.device && !cc.card && !cc.bus_info)
            return sci_json_fail(doc, err, "devices.camera", "%s", b.locate_hint);
        fake_cam = scicapd_camera_is_fake(&b, &cc);
    }
    /* Aravis's fake camera lives inside the daemon's process: no wire reaches it either way, so besides a gpiod
     * trigger it may run with the simulated one (tests and dry runs of the GenICam path, docs/config.md). */
    if (sim_cam != sim_trig && !(fake_cam && sim_trig))
        return sci_json_fail(doc, err,
                             json_object_get(o, "trigger") ? "devices.trigger.backend" : "devices.camera.backend",
                             "camera \"%s\" with trigger \"%s\": the trigger output starts the camera and the "
                             "camera's strobe comes back to a trigger input, so both are simulated (\"sim\") or "
                             "both real (\"v4l2\" or \"aravis\" with \"gpiod\"); the DMD may be either. Only "
                             "Aravis's in-process fake camera (\"device\": \"Fake_1\") may also pair with the "
                             "\"sim\" trigger", c->camera_backend, c->trigger_backend);
    if (!sim_trig) {
        trigger_config tc;
        if (trigger_config_from_json(c->trigger_json, "devices.trigger", &tc,
                                     &e2) < 0)
            return driver_fail(doc, &e2, err);
        if (tc.output.offset < 0 && !tc.output.name)
            return sci_json_fail(doc, err, "devices.trigger", "the gpiod trigger needs \"output\" (the line that "
                                 "starts the DMD and the camera)");
    }
    return 0;
}

static int parse_simulator(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"scene", "counts_per_unit", "dark_counts", "read_noise_counts", "seed",
                                       "dmd_latency_us", NULL};
    static const sci_json_field fields[] = {
        CFG("counts_per_unit", SCI_JSON_DOUBLE, sim_counts_per_unit, .lo = 1, .hi = 65535, .help = "white"),
        CFG("dark_counts", SCI_JSON_DOUBLE, sim_dark_counts, .lo = 0, .hi = 60000, .help = "dark offset"),
        CFG("read_noise_counts", SCI_JSON_DOUBLE, sim_read_noise, .lo = 0, .hi = 1000, .help = "read noise sigma"),
        CFG("seed", SCI_JSON_U64, sim_seed, .lo = 0, .hi = 9007199254740992.0, .help = "noise seed"),
        CFG("dmd_latency_us", SCI_JSON_U32, sim_dmd_latency_us, .lo = 0, .hi = 100000, .help = "microseconds"),
    };
    int rc;
    const json_t *sc = json_object_get(o, "scene");
    if ((rc = sci_json_check_keys(doc, o, "simulator", keys, err)) < 0)
        return rc;
    if (sc && !json_is_null(sc) &&
        (rc = get_str(doc, o, "simulator", "scene", c->scene_path, sizeof c->scene_path, err)) < 0)
        return rc;
    return sci_json_fields_read(doc, o, "simulator", fields, SCI_JSON_FIELDS_COUNT(fields), c, err);
}

static int parse_mask_set(const sci_json_doc *doc, const json_t *o, const char *path, scicapd_mask_set *m,
                          sci_error *err)
{
    static const char *const keys[] = {"type", "frames", "seed", "density", "block", "step", "direction", "path",
                                       NULL};
    static const char *const kinds[] = {"random", "shifting", "superpixel", "file", NULL};
    static const char *const dirs[] = {"x", "y", NULL};
#define MASK(key, type, member, ...) {key, type, offsetof(scicapd_mask_set, member), __VA_ARGS__}
    static const sci_json_field fields[] = {
        MASK("type", SCI_JSON_ENUM, spec.kind, .names = kinds, .required = 1, .help = "how the masks are made"),
        MASK("frames", SCI_JSON_INT, frames, .lo = 1, .hi = 400, .help = "N, masks per snapshot"),
        MASK("seed", SCI_JSON_U64, seed, .lo = 0, .hi = 9007199254740992.0, .help = "random kinds"),
        MASK("density", SCI_JSON_DOUBLE, spec.density, .lo = 1e-6, .hi = 1, .help = "probability of on"),
        MASK("block", SCI_JSON_INT, spec.block, .lo = 1, .hi = 4096, .help = "superpixel size, mirrors"),
        MASK("step", SCI_JSON_INT, spec.step, .lo = -64, .hi = 64, .help = "shifting: pixels per frame"),
        MASK("direction", SCI_JSON_ENUM, spec.dir_y, .names = dirs, .help = "shifting: along x or y"),
        {"path", SCI_JSON_STRING, offsetof(scicapd_mask_set, spec.path), .size = sizeof(((sim_mask_spec *)0)->path),
         .help = "file kind: the masks' file"},
    };
#undef MASK
    _Static_assert(sizeof(sim_mask_kind) == sizeof(int), "a mask kind is read as an int");
    int rc;
    if (!json_is_object(o))
        return sci_json_fail(doc, err, path, "must be an object");
    m->frames = 8;
    m->seed = 7;
    m->spec = (sim_mask_spec){.kind = SIM_MASK_RANDOM, .density = 0.5, .block = 4, .step = 1, .dir_y = 1,
                              .scale = 1};
    if ((rc = sci_json_check_keys(doc, o, path, keys, err)) < 0 ||
        (rc = sci_json_fields_read(doc, o, path, fields, SCI_JSON_FIELDS_COUNT(fields), m, err)) < 0)
        return rc;
    if (m->spec.kind == SIM_MASK_FILE && !m->spec.path[0]) {
        char p[256];
        return sci_json_fail(doc, err, sci_json_path_key(p, sizeof p, path, "path"), "required for type \"file\"");
    }
    return 0;
}

static int parse_mask_sets(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    const char *name;
    json_t *v;
    c->mask_set_count = 0;
    json_object_foreach((json_t *)o, name, v) {
        char path[256];
        sci_json_path_key(path, sizeof path, "mask_sets", name);
        if (c->mask_set_count == SCICAPD_MAX_MASK_SETS)
            return sci_json_fail(doc, err, path, "more than %d mask sets", SCICAPD_MAX_MASK_SETS);
        if (!name[0] || strlen(name) >= SCICAPD_NAME_MAX || strcspn(name, "/ \t\n") != strlen(name) || name[0] == '.')
            return sci_json_fail(doc, err, path, "a mask set name must be 1..%d characters without '/', spaces or "
                                 "a leading dot", SCICAPD_NAME_MAX - 1);
        scicapd_mask_set *m = &c->mask_sets[c->mask_set_count];
        snprintf(m->name, sizeof m->name, "%s", name);
        int rc = parse_mask_set(doc, v, path, m, err);
        if (rc < 0)
            return rc;
        c->mask_set_count++;
    }
    if (c->mask_set_count == 0)
        return sci_json_fail(doc, err, "mask_sets", "must define at least one mask set");
    return 0;
}

static int parse_capture(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"mask_set", "pattern_us", "dark_us", "exposure_us", "sync_mode",
                                       "counts_per_unit", NULL};
    static const char *const modes[] = {"dmd-master", "host-master", "camera-master", NULL};
    static const sci_json_field fields[] = {
        CFG_STR("mask_set", capture_mask_set, SCICAPD_NAME_MAX, "masks shown"),
        CFG("pattern_us", SCI_JSON_U32, pattern_us, .lo = 1, .hi = 10000000, .help = "each mask, microseconds"),
        CFG("dark_us", SCI_JSON_U32, dark_us, .lo = 0, .hi = 10000000, .help = "dark time between masks"),
        CFG("exposure_us", SCI_JSON_U32, exposure_us, .lo = 0, .hi = 60000000, .help = "camera exposure"),
        CFG("sync_mode", SCI_JSON_ENUM, sync_mode, .names = modes, .help = "who triggers whom"),
        CFG("counts_per_unit", SCI_JSON_DOUBLE, counts_per_unit, .lo = 0, .hi = 1e9, .help = "white, 0: auto"),
    };
    _Static_assert(sizeof(enum sync_mode) == sizeof(int), "sync_mode is read as an int");
    int rc;
    if ((rc = sci_json_check_keys(doc, o, "capture", keys, err)) < 0)
        return rc;
    return sci_json_fields_read(doc, o, "capture", fields, SCI_JSON_FIELDS_COUNT(fields), c, err);
}

static const sci_json_field recon_fields[] = {
    CFG("auto", SCI_JSON_BOOL, recon_auto, .help = "reconstruct every capture"),
    CFG("workers", SCI_JSON_INT, workers, .lo = 1, .hi = 16, .help = "reconstructions at once"),
    CFG("threads", SCI_JSON_INT, recon_threads, .lo = 0, .hi = 256, .help = "threads each, 0: all cores"),
    CFG("checkpoint_every", SCI_JSON_INT, recon_checkpoint_every, .lo = 0, .hi = 1000000, .help = "steps, 0: none"),
};

static int parse_recon(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"method", "preset", "auto", "workers", "threads", "curves",
                                       "checkpoint_every", NULL};
    const char *m = NULL;
    solver_preset p;
    int rc;
    if ((rc = sci_json_check_keys(doc, o, "reconstruction", keys, err)) < 0 ||
        (rc = sci_json_get_string(doc, o, "reconstruction", "method", 0, &m, err)) < 0)
        return rc;
    if (rc == 0 && !solver_find(m)) {
        char names[256];
        return sci_json_fail(doc, err, "reconstruction.method", "must be one of %s (got \"%.32s\")",
                             solver_names_text(names, sizeof names, ", "), m);
    }
    if (rc == 0)
        snprintf(c->recon_method, sizeof c->recon_method, "%s", m);
    if ((rc = solver_preset_get(doc, o, "reconstruction", "preset", &p, err)) < 0)
        return rc;
    if (rc == 0) /* an alias is stored as the preset it means */
        snprintf(c->recon_preset, sizeof c->recon_preset, "%s", solver_preset_name(p));
    if ((rc = sci_json_fields_read(doc, o, "reconstruction", recon_fields, SCI_JSON_FIELDS_COUNT(recon_fields), c,
                                   err)) < 0)
        return rc;
    const solver_ops *method = solver_find(c->recon_method);
    if (c->recon_auto && method && (method->caps & SOLVER_NEEDS_CAMERA))
        return sci_json_fail(doc, err, "reconstruction.auto", "every capture reconstructed with %s, which needs a "
                             "camera that bench captures do not carry: choose another method, or auto false",
                             method->name);
    const char *curves = NULL;
    if ((rc = sci_json_get_string(doc, o, "reconstruction", "curves", 0, &curves, err)) < 0)
        return rc;
    if (rc == 0) {
        if (!curves[0] || strlen(curves) >= sizeof c->recon_curves)
            return sci_json_fail(doc, err, "reconstruction.curves", "must be a path shorter than %zu bytes",
                                 sizeof c->recon_curves);
        snprintf(c->recon_curves, sizeof c->recon_curves, "%s", curves);
    }
    return 0;
}

static int parse_queues(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"capture", "reconstruction", NULL};
    static const sci_json_field fields[] = {
        CFG("capture", SCI_JSON_INT, capture_queue, .lo = 1, .hi = 4096, .help = "captures waiting"),
        CFG("reconstruction", SCI_JSON_INT, recon_queue, .lo = 1, .hi = 4096, .help = "reconstructions waiting"),
    };
    int rc;
    if ((rc = sci_json_check_keys(doc, o, "queues", keys, err)) < 0)
        return rc;
    return sci_json_fields_read(doc, o, "queues", fields, SCI_JSON_FIELDS_COUNT(fields), c, err);
}

/* "listen": "HOST:PORT" or "[V6]:PORT" with a numeric address: a name would be resolved at each start and
 * could quietly mean every interface. */
static int parse_listen(const sci_json_doc *doc, const char *s, scicapd_config *c, sci_error *err)
{
    const char *colon = strrchr(s, ':');
    const char *host = s, *host_end = colon;
    if (s[0] == '[') {
        host = s + 1;
        host_end = strchr(s, ']');
        if (!host_end || host_end[1] != ':')
            host_end = NULL;
    }
    char *end = NULL;
    long port = colon ? strtol(colon + 1, &end, 10) : -1;
    if (!colon || !host_end || host_end <= host || (size_t)(host_end - host) >= sizeof c->web_host ||
        !end || *end || end == colon + 1 || port < 0 || port > 65535)
        return sci_json_fail(doc, err, "web.listen", "must be \"ADDRESS:PORT\" with a numeric address, e.g. "
                             "\"127.0.0.1:8080\" or \"[::1]:8080\" (got \"%s\")", s);
    char host_buf[64];
    snprintf(host_buf, sizeof host_buf, "%.*s", (int)(host_end - host), host);
    if (s[0] != '[' && strchr(host_buf, ':'))
        return sci_json_fail(doc, err, "web.listen", "an IPv6 address goes in brackets: \"[%s]:PORT\" (got \"%s\")",
                             host_buf, s);
    unsigned char addr[16];
    if (inet_pton(s[0] == '[' ? AF_INET6 : AF_INET, host_buf, addr) != 1)
        return sci_json_fail(doc, err, "web.listen", "\"%s\" is not a numeric %s address", host_buf,
                             s[0] == '[' ? "IPv6" : "IPv4");
    snprintf(c->web_host, sizeof c->web_host, "%s", host_buf);
    c->web_port = (int)port;
    return 0;
}

static int parse_web(const sci_json_doc *doc, const json_t *o, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"enabled", "listen", "control", "token_file", "max_connections",
                                       "timeout_s", NULL};
    static const sci_json_field fields[] = {
        CFG("enabled", SCI_JSON_BOOL, web_enabled, .help = "serve the web interface"),
        CFG("control", SCI_JSON_BOOL, web_control, .help = "let the web interface start and stop captures"),
    };
    static const sci_json_field more[] = {
        CFG_STR("token_file", web_token_file, SCICAPD_PATH_MAX, "file holding the access token"),
        CFG("max_connections", SCI_JSON_INT, web_max_connections, .lo = 4, .hi = 1000, .help = "at once"),
        CFG("timeout_s", SCI_JSON_INT, web_timeout_s, .lo = 1, .hi = 3600, .help = "idle connection, seconds"),
    };
    int rc;
    char listen[96] = "";
    c->web_enabled = 1;
    if ((rc = sci_json_check_keys(doc, o, "web", keys, err)) < 0 ||
        (rc = sci_json_fields_read(doc, o, "web", fields, SCI_JSON_FIELDS_COUNT(fields), c, err)) < 0 ||
        (rc = get_str(doc, o, "web", "listen", listen, sizeof listen, err)) < 0 ||
        (rc = sci_json_fields_read(doc, o, "web", more, SCI_JSON_FIELDS_COUNT(more), c, err)) < 0)
        return rc;
    if (listen[0] && (rc = parse_listen(doc, listen, c, err)) < 0)
        return rc;
    if (c->web_token_file[0] && c->web_token_file[0] != '/')
        return sci_json_fail(doc, err, "web.token_file", "must be an absolute path (got \"%s\")",
                             c->web_token_file);
    return 0;
}

static int parse_doc(const sci_json_doc *doc, scicapd_config *c, sci_error *err)
{
    static const char *const keys[] = {"version", "control", "storage", "devices", "simulator", "mask_sets",
                                       "capture", "reconstruction", "queues", "web", NULL};
    const json_t *root = sci_json_doc_root(doc);
    if (!json_is_object(root))
        return sci_json_fail(doc, err, "", "the configuration must be a JSON object");
    long long version = 1;
    int rc;
    if ((rc = sci_json_check_keys(doc, root, "", keys, err)) < 0 ||
        (rc = sci_json_get_int(doc, root, "", "version", 0, 1, 1, &version, err)) < 0)
        return rc;
    static const struct {
        const char *key;
        int (*parse)(const sci_json_doc *, const json_t *, scicapd_config *, sci_error *);
    } sections[] = {{"control", parse_control},     {"storage", parse_storage},     {"devices", parse_devices},
                    {"simulator", parse_simulator}, {"mask_sets", parse_mask_sets}, {"capture", parse_capture},
                    {"reconstruction", parse_recon}, {"queues", parse_queues},     {"web", parse_web}};
    for (size_t i = 0; i < sizeof sections / sizeof sections[0]; i++) {
        const json_t *o;
        if ((rc = get_obj(doc, root, "", sections[i].key, &o, err)) < 0)
            return rc;
        if (o && (rc = sections[i].parse(doc, o, c, err)) < 0)
            return rc;
    }
    if (!scicapd_config_mask_set(c, c->capture_mask_set))
        return sci_json_fail(doc, err, json_object_get(json_object_get(root, "capture"), "mask_set")
                                           ? "capture.mask_set" : "mask_sets",
                             "the default mask set \"%s\" is not defined in mask_sets", c->capture_mask_set);
    return 0;
}

static int load_doc(scicapd_config **out, sci_json_doc *doc, const char *path, sci_error *err)
{
    scicapd_config *c = malloc(sizeof *c);
    if (!c) {
        sci_json_doc_free(doc);
        return sci_error_set(err, -ENOMEM, "config: out of memory");
    }
    defaults(c);
    snprintf(c->path, sizeof c->path, "%s", path ? path : "");
    int rc = parse_doc(doc, c, err);
    sci_json_doc_free(doc);
    if (rc < 0) {
        scicapd_config_free(c);
        return rc;
    }
    *out = c;
    return 0;
}

int scicapd_config_load(scicapd_config **out, const char *path, sci_error *err)
{
    if (!path)
        return scicapd_config_default(out, err);
    sci_json_doc *doc;
    int rc = sci_json_doc_load_file(&doc, path, err);
    if (rc < 0)
        return rc;
    return load_doc(out, doc, path, err);
}

int scicapd_config_load_string(scicapd_config **out, const char *name, const char *text, sci_error *err)
{
    sci_json_doc *doc;
    int rc = sci_json_doc_load_string(&doc, name, text, strlen(text), err);
    if (rc < 0)
        return rc;
    return load_doc(out, doc, NULL, err);
}

const scicapd_mask_set *scicapd_config_mask_set(const scicapd_config *c, const char *name)
{
    for (int i = 0; i < c->mask_set_count; i++)
        if (strcmp(c->mask_sets[i].name, name) == 0)
            return &c->mask_sets[i];
    return NULL;
}

/* json_equal says 0 when either side is NULL: two absent objects are equal here. */
static int same_json(const json_t *a, const json_t *b) { return (!a && !b) || (a && b && json_equal(a, b)); }

void scicapd_config_uncalibrated_scale(const scicapd_config *c, double *counts_per_unit, double *dark_level)
{
    *counts_per_unit = c->counts_per_unit > 0 ? c->counts_per_unit : c->sim_counts_per_unit;
    *dark_level = c->sim_dark_counts;
}

int scicapd_config_devices_differ(const scicapd_config *a, const scicapd_config *b)
{
    return strcmp(a->dmd_backend, b->dmd_backend) || strcmp(a->camera_backend, b->camera_backend) ||
           strcmp(a->trigger_backend, b->trigger_backend) || strcmp(a->dmd_serial, b->dmd_serial) ||
           a->dmd_emulator != b->dmd_emulator || a->dmd_timeout_ms != b->dmd_timeout_ms ||
           a->dmd_trigger_delay_us != b->dmd_trigger_delay_us || a->dmd_trigger_falling != b->dmd_trigger_falling ||
           a->camera_readout_us != b->camera_readout_us || !same_json(a->camera_json, b->camera_json) ||
           !same_json(a->trigger_json, b->trigger_json) || strcmp(a->scene_path, b->scene_path) ||
           a->sim_counts_per_unit != b->sim_counts_per_unit || a->sim_dark_counts != b->sim_dark_counts ||
           a->sim_read_noise != b->sim_read_noise || a->sim_seed != b->sim_seed ||
           a->sim_dmd_latency_us != b->sim_dmd_latency_us;
}

int scicapd_config_copy(scicapd_config **out, const scicapd_config *c, sci_error *err)
{
    scicapd_config *n = malloc(sizeof *n);
    if (!n)
        return sci_error_set(err, -ENOMEM, "config: out of memory");
    *n = *c;
    n->camera_json = c->camera_json ? json_deep_copy(c->camera_json) : NULL;
    n->trigger_json = c->trigger_json ? json_deep_copy(c->trigger_json) : NULL;
    if ((c->camera_json && !n->camera_json) || (c->trigger_json && !n->trigger_json)) {
        scicapd_config_free(n);
        return sci_error_set(err, -ENOMEM, "config: out of memory");
    }
    *out = n;
    return 0;
}

/* Devices and the simulator are re-opened by the acquisition thread at reload (between jobs): no restart. */
json_t *scicapd_config_restart_keys(const scicapd_config *a, const scicapd_config *b)
{
    json_t *r = json_array();
    if (strcmp(a->socket_path, b->socket_path) || a->socket_mode != b->socket_mode ||
        strcmp(a->socket_group, b->socket_group))
        json_array_append_new(r, json_string("control.socket"));
    if (strcmp(a->storage_root, b->storage_root) || strcmp(a->runtime_dir, b->runtime_dir))
        json_array_append_new(r, json_string("storage"));
    if (a->writers != b->writers)
        json_array_append_new(r, json_string("storage.writers"));
    if (a->workers != b->workers || a->recon_threads != b->recon_threads)
        json_array_append_new(r, json_string("reconstruction.workers"));
    if (a->recon_checkpoint_every != b->recon_checkpoint_every) /* the workers took it at the start */
        json_array_append_new(r, json_string("reconstruction.checkpoint_every"));
    if (a->web_enabled != b->web_enabled || strcmp(a->web_host, b->web_host) || a->web_port != b->web_port ||
        a->web_control != b->web_control || strcmp(a->web_token_file, b->web_token_file) ||
        a->web_max_connections != b->web_max_connections || a->web_timeout_s != b->web_timeout_s)
        json_array_append_new(r, json_string("web")); /* the server and its token are made once, at start */
    return r;
}

json_t *scicapd_config_to_json(const scicapd_config *c)
{
    char mode[8];
    snprintf(mode, sizeof mode, "%04o", c->socket_mode);
    json_t *sets = json_array();
    for (int i = 0; i < c->mask_set_count; i++)
        json_array_append_new(sets, json_string(c->mask_sets[i].name));
    return json_pack("{s:s, s:{s:s, s:s, s:s, s:s, s:i, s:I}, s:{s:s, s:s, s:b, s:i, s:b}, s:{s:s, s:s, s:s}, s:s, s:o,"
                     " s:{s:s, s:I, s:I, s:I, s:s}, s:{s:s, s:s, s:b, s:i, s:i, s:i}, s:{s:i, s:i}, s:{s:b, s:s, s:i, s:b}}",
                     "path", c->path, "control", "socket", c->socket_path, "mode", mode, "group", c->socket_group,
                     "admin_group", c->admin_group, "max_clients", c->max_clients, "max_line_bytes", (json_int_t)c->max_line_bytes, "storage",
                     "root", c->storage_root, "runtime_dir", c->runtime_dir, "fsync", c->fsync, "writers",
                     c->writers, "previews", c->previews, "devices", "dmd",
                     c->dmd_backend, "camera", c->camera_backend, "trigger", c->trigger_backend, "scene",
                     c->scene_path[0] ? c->scene_path : "(embedded default)", "mask_sets", sets, "capture",
                     "mask_set", c->capture_mask_set, "pattern_us", (json_int_t)c->pattern_us, "dark_us",
                     (json_int_t)c->dark_us, "exposure_us", (json_int_t)c->exposure_us, "sync_mode",
                     sync_mode_name(c->sync_mode), "reconstruction", "method", c->recon_method, "preset",
                     c->recon_preset, "auto", c->recon_auto, "workers", c->workers, "threads", c->recon_threads,
                     "checkpoint_every", c->recon_checkpoint_every,
                     "queues", "capture", c->capture_queue, "reconstruction", c->recon_queue, "web", "enabled",
                     c->web_enabled, "host", c->web_host, "port", c->web_port, "control", c->web_control);
}
