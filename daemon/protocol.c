/* daemon/protocol.c — request checks, argument parsing, reply and event encoding (protocol version 1). */
#include "daemon/protocol.h"
#include "io/curves.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *const cmd_names[SCICAPD_CMD_COUNT] = {
    "status", "devices", "capture", "calibrate", "reconstruct", "jobs", "cancel", "watch", "reload", "shutdown",
    "simulate", "import", "captures",
};
static const char *const err_names[SCICAPD_E_COUNT] = {
    "ok", "too_long", "bad_json", "bad_version", "unknown_command", "bad_arguments", "permission", "busy",
    "not_found", "failed", "shutting_down", "unsupported", "timeout",
};

const char *scicapd_cmd_name(scicapd_cmd c) { return (unsigned)c < SCICAPD_CMD_COUNT ? cmd_names[c] : "?"; }
int scicapd_cmd_is_admin(scicapd_cmd c)
{
    return c == SCICAPD_CMD_RELOAD || c == SCICAPD_CMD_SHUTDOWN || c == SCICAPD_CMD_SIMULATE;
}
const char *scicapd_errcode_name(scicapd_errcode e) { return (unsigned)e < SCICAPD_E_COUNT ? err_names[e] : "?"; }

void scicapd_request_clear(scicapd_request *r)
{
    json_decref(r->id);
    sci_json_doc_free(r->doc);
    memset(r, 0, sizeof *r);
}

scicapd_errcode scicapd_request_parse(const char *line, size_t len, scicapd_request *out, sci_error *err)
{
    memset(out, 0, sizeof *out);
    out->id = json_null();
    if (memchr(line, '\0', len)) {
        sci_error_set(err, SCI_EPROTO, "request: NUL byte in the line");
        return SCICAPD_E_BAD_JSON;
    }
    if (sci_json_doc_load_string(&out->doc, "request", line, len, err) < 0)
        return SCICAPD_E_BAD_JSON;
    const json_t *root = sci_json_doc_root(out->doc);
    if (!json_is_object(root)) {
        sci_json_fail(out->doc, err, "", "a request must be a JSON object");
        return SCICAPD_E_BAD_JSON;
    }
    json_t *id = json_object_get(root, "id");
    if (id) {
        if (!json_is_integer(id) && !(json_is_string(id) && json_string_length(id) <= 64)) {
            sci_json_fail(out->doc, err, "id", "must be an integer or a string of at most 64 bytes");
            return SCICAPD_E_BAD_JSON;
        }
        json_decref(out->id);
        out->id = json_incref(id);
    }
    long long v = SCICAPD_PROTOCOL_VERSION;
    if (sci_json_get_int(out->doc, root, "", "v", 0, SCICAPD_PROTOCOL_VERSION, SCICAPD_PROTOCOL_VERSION, &v,
                         err) < 0) {
        sci_error_prefix(err, "this daemon speaks protocol version %d: ", SCICAPD_PROTOCOL_VERSION);
        return SCICAPD_E_BAD_VERSION;
    }
    const char *cmd = NULL;
    if (sci_json_get_string(out->doc, root, "", "cmd", 1, &cmd, err) < 0)
        return SCICAPD_E_UNKNOWN_COMMAND;
    out->cmd = SCICAPD_CMD_COUNT;
    for (int i = 0; i < SCICAPD_CMD_COUNT; i++)
        if (strcmp(cmd, cmd_names[i]) == 0)
            out->cmd = (scicapd_cmd)i;
    if (out->cmd == SCICAPD_CMD_COUNT) {
        sci_json_fail(out->doc, err, "cmd", "unknown command \"%.64s\"", cmd);
        return SCICAPD_E_UNKNOWN_COMMAND;
    }
    static const char *const top[] = {"v", "id", "cmd", "args", NULL};
    if (sci_json_check_keys(out->doc, root, "", top, err) < 0)
        return SCICAPD_E_BAD_JSON;
    out->args = json_object_get(root, "args");
    return SCICAPD_OK;
}

/* ---- arguments ---- */

static int args_obj(const scicapd_request *r, const char *const *keys, sci_error *err)
{
    if (!r->args)
        return 0;
    if (!json_is_object(r->args))
        return sci_json_fail(r->doc, err, "args", "must be an object");
    return sci_json_check_keys(r->doc, r->args, "args", keys, err);
}

int scicapd_args_none(const scicapd_request *r, sci_error *err)
{
    static const char *const keys[] = {NULL};
    return args_obj(r, keys, err);
}

static int get_u32(const scicapd_request *r, const char *key, long long lo, long long hi, uint32_t *out,
                   sci_error *err)
{
    long long v = *out;
    int rc = r->args ? sci_json_get_int(r->doc, r->args, "args", key, 0, lo, hi, &v, err) : 1;
    if (rc == 0)
        *out = (uint32_t)v;
    return rc < 0 ? rc : 0;
}

static int get_mask_set(const scicapd_request *r, const scicapd_config *cfg, scicapd_mask_set *out,
                        sci_error *err)
{
    const char *name = cfg->capture_mask_set;
    if (r->args && sci_json_get_string(r->doc, r->args, "args", "mask_set", 0, &name, err) < 0)
        return SCI_ECONFIG;
    const scicapd_mask_set *m = scicapd_config_mask_set(cfg, name);
    if (!m)
        return sci_json_fail(r->doc, err, "args.mask_set", "no mask set \"%.64s\" in the configuration", name);
    *out = *m;
    return 0;
}

uint32_t scicapd_auto_exposure_us(int n, uint32_t pattern_us, uint32_t dark_us, uint32_t latency_us)
{
    uint64_t t = (uint64_t)latency_us + (uint64_t)n * (pattern_us + dark_us) + 500;
    return t > 60000000 ? 60000000 : (uint32_t)t;
}

int scicapd_recon_spec_resolve(const char *method, const char *preset, const sci_json_doc *doc,
                               const json_t *params, const char *path, scicapd_recon_spec *out, sci_error *err)
{
    memset(out, 0, sizeof *out);
    sci_error e2 = {0};
    solver_preset pr;
    if (!(out->method = solver_find_err(method, &e2)))
        return sci_error_set(err, SCI_ECONFIG, "method \"%.32s\": %s", method, e2.msg);
    if (out->method->settings_size > sizeof out->settings)
        return sci_error_set(err, SCI_ECONFIG, "method %s: its settings (%zu bytes) do not fit a spec", method,
                             out->method->settings_size);
    if (solver_preset_parse(preset, &pr, NULL, &e2) < 0)
        return sci_error_set(err, SCI_ECONFIG, "preset \"%.32s\": expected fast, balanced or best", preset);
    snprintf(out->preset, sizeof out->preset, "%s", preset);
    out->method->defaults(out->settings);
    solver_settings_preset(out->method, out->settings, pr);
    /* the classical methods' trace: PSNR at every iteration (the progress events carry it), SSIM at the end; the
     * NeRF methods keep their own intervals (a PSNR there is a full render). Only "iters" is a key every method
     * has (solver_list_check): a method without these keys keeps its own trace. */
    if (!(out->method->caps & SOLVER_NEEDS_CAMERA)) {
        static const struct { const char *key; int value; } trace[] = {{"metrics_every", 1}, {"ssim_every", 0}};
        for (size_t i = 0; i < sizeof trace / sizeof trace[0]; i++) {
            json_t *v = json_integer(trace[i].value);
            int rc = v ? solver_settings_set(out->method, out->settings, trace[i].key, v, NULL, trace[i].key, err)
                       : sci_error_set(err, -ENOMEM, "out of memory");
            json_decref(v);
            if (rc < 0)
                return rc;
        }
    }
    if (params && solver_settings_from_json(out->method, out->settings, params, doc, path, err) < 0)
        return SCI_ECONFIG;
    return 0;
}

json_t *scicapd_recon_budget_json(const scicapd_recon_spec *s)
{
    if (!(s->budget_s > 0))
        return NULL;
    json_t *b = json_pack("{s:f, s:s, s:f, s:f}", "budget_s", s->budget_s, "method", s->method->name, "predicted_s",
                          s->predicted_s, "expected_psnr_db", s->expected_db);
    if (b && s->budget_setting[0])
        json_object_set_new(b, "setting", json_string(s->budget_setting));
    return b;
}

json_t *scicapd_recon_spec_json(const scicapd_recon_spec *s)
{
    json_t *j = scicapd_recon_spec_json_plain(s);
    json_t *b = j ? scicapd_recon_budget_json(s) : NULL;
    if (b)
        json_object_set_new(j, "budget", b);
    return j;
}

void scicapd_capture_id_normalize(const char *in, char *out, size_t n)
{
    const char *d = in[0] == 'c' ? in + 1 : in;
    size_t len = strlen(d);
    if (len == 0 || len > 12 || strspn(d, "0123456789") != len) {
        snprintf(out, n, "%s", in);
        return;
    }
    snprintf(out, n, "c%06llu", strtoull(d, NULL, 10));
}

/* A budget: the most accurate measured setting of any method whose predicted time fits (io/curves.h), for a
 * problem of `voxels`, among the scenes of its kind (with a camera, where the NeRF methods were measured, or
 * without); `method` restricts the choice when the request named one. */
static int apply_budget(const scicapd_config *cfg, const sci_json_doc *doc, const char *path, double budget_s,
                        const char *method, int has_camera, double voxels, scicapd_recon_spec *out, sci_error *err)
{
    sci_curves *cv = NULL;
    sci_error e2 = {0};
    if (sci_curves_load(&cv, cfg->recon_curves, &e2) < 0)
        return sci_json_fail(doc, err, path, "no measured curves to choose from (%s); run make bench-report", e2.msg);
    sci_curve_choice ch;
    int rc = sci_curves_pick(cv, method, has_camera, voxels, budget_s, &ch, &e2);
    sci_curves_free(cv);
    if (rc < 0)
        return sci_json_fail(doc, err, path, "%s", e2.msg);
    /* the curves file is data a user may edit: its setting is read as the method's settings, type- and
     * range-checked, never read as 0 */
    json_t *params = sci_curves_setting_json(ch.setting);
    scicapd_recon_spec chosen;
    rc = params ? scicapd_recon_spec_resolve(ch.method, "balanced", NULL, params, "setting", &chosen, &e2) : -EINVAL;
    json_decref(params);
    if (rc < 0)
        return sci_json_fail(doc, err, path, "recon_curves: setting '%s' of %s is malformed: %s", ch.setting,
                             ch.method, e2.msg);
    out->method = chosen.method;
    memcpy(out->settings, chosen.settings, sizeof out->settings);
    snprintf(out->preset, sizeof out->preset, "budget");
    snprintf(out->budget_setting, sizeof out->budget_setting, "%s", ch.setting);
    out->budget_s = budget_s;
    out->predicted_s = ch.predicted_s;
    out->expected_db = ch.mean_psnr;
    return 0;
}

json_t *scicapd_recon_spec_json_plain(const scicapd_recon_spec *s)
{
    json_t *j = solver_settings_to_json(s->method, s->settings);
    if (j)
        json_object_set_new(j, "preset", json_string(s->preset));
    return j;
}

/* method / preset / params members of `obj` at `path` with defaults from the configuration. */
static int get_recon(const scicapd_request *r, const json_t *obj, const char *path, const scicapd_config *cfg,
                     scicapd_recon_spec *out, sci_error *err)
{
    const char *method = cfg->recon_method, *preset = cfg->recon_preset;
    const json_t *params = NULL;
    if (obj) {
        int rc;
        const char *m = NULL;
        if ((rc = sci_json_get_string(r->doc, obj, path, "method", 0, &m, err)) < 0)
            return rc;
        if (rc == 0) {
            char mp[64], names[256];
            if (!solver_find(m))
                return sci_json_fail(r->doc, err, sci_json_path_key(mp, sizeof mp, path, "method"),
                                     "unknown method '%.32s' (%s)", m, solver_names_text(names, sizeof names, ", "));
            method = m;
        }
        solver_preset pr;
        if ((rc = solver_preset_get(r->doc, obj, path, "preset", &pr, err)) < 0)
            return rc;
        if (rc == 0)
            preset = solver_preset_name(pr);
        params = json_object_get(obj, "params");
    }
    char pp[64];
    return scicapd_recon_spec_resolve(method, preset, r->doc, params, sci_json_path_key(pp, sizeof pp, path, "params"),
                                      out, err);
}

int scicapd_args_capture(const scicapd_request *r, const scicapd_config *cfg, scicapd_capture_args *out,
                         sci_error *err)
{
    static const char *const keys[] = {"mask_set", "pattern_us", "dark_us", "exposure_us", "sync_mode", "count",
                                       "reconstruct", "method", "preset", "params", NULL};
    static const char *const modes[] = {"dmd-master", "host-master", "camera-master", NULL};
    memset(out, 0, sizeof *out);
    int rc;
    if ((rc = args_obj(r, keys, err)) < 0 || (rc = get_mask_set(r, cfg, &out->mask_set, err)) < 0)
        return rc;
    out->pattern_us = cfg->pattern_us;
    out->dark_us = cfg->dark_us;
    out->exposure_us = cfg->exposure_us;
    out->sync = cfg->sync_mode;
    out->count = 1;
    out->reconstruct = cfg->recon_auto;
    long long count = 1;
    int mode = (int)out->sync;
    if ((rc = get_u32(r, "pattern_us", 1, 10000000, &out->pattern_us, err)) < 0 ||
        (rc = get_u32(r, "dark_us", 0, 10000000, &out->dark_us, err)) < 0 ||
        (rc = get_u32(r, "exposure_us", 0, 60000000, &out->exposure_us, err)) < 0)
        return rc;
    if (r->args && ((rc = sci_json_get_int(r->doc, r->args, "args", "count", 0, 1, 1000, &count, err)) < 0 ||
                    (rc = sci_json_get_enum(r->doc, r->args, "args", "sync_mode", 0, modes, &mode, err)) < 0 ||
                    (rc = sci_json_get_bool(r->doc, r->args, "args", "reconstruct", 0, &out->reconstruct, err)) < 0))
        return rc;
    out->count = (int)count;
    out->sync = (enum sync_mode)mode;
    if ((uint64_t)out->mask_set.frames * (out->pattern_us + out->dark_us) > 60000000)
        return sci_json_fail(r->doc, err, r->args && json_object_get(r->args, "pattern_us") ? "args.pattern_us" : "args",
                             "%d masks of %u+%u us last longer than 60 s", out->mask_set.frames, out->pattern_us,
                             out->dark_us);
    if ((rc = get_recon(r, r->args, "args", cfg, &out->recon, err)) < 0)
        return rc;
    /* a bench snapshot carries no camera poses: a method that needs them would only fail once per snapshot */
    if (out->reconstruct && (out->recon.method->caps & SOLVER_NEEDS_CAMERA))
        return sci_json_fail(r->doc, err, json_object_get(r->args, "method") ? "args.method" : "args.reconstruct",
                             "%s needs a camera (a static scene with poses), which a bench capture does not carry; "
                             "reconstruct a problem folder imported with scicap capture --from instead",
                             out->recon.method->name);
    return 0;
}

int scicapd_args_calibrate(const scicapd_request *r, const scicapd_config *cfg, scicapd_calib_args *out,
                           sci_error *err)
{
    static const char *const keys[] = {"kind", "mask_set", "pattern_us", "dark_us", "exposure_us", "average", NULL};
    static const char *const kinds[] = {"dark", "masks", NULL};
    memset(out, 0, sizeof *out);
    int rc, kind = 0;
    long long avg = 4;
    if ((rc = args_obj(r, keys, err)) < 0)
        return rc;
    if (!r->args || !json_object_get(r->args, "kind"))
        return sci_json_fail(r->doc, err, r->args ? "args" : "", "args.kind is required: \"dark\" or \"masks\"");
    if ((rc = sci_json_get_enum(r->doc, r->args, "args", "kind", 1, kinds, &kind, err)) < 0 ||
        (rc = get_mask_set(r, cfg, &out->mask_set, err)) < 0 ||
        (rc = sci_json_get_int(r->doc, r->args, "args", "average", 0, 1, 64, &avg, err)) < 0)
        return rc;
    out->kind = (scicapd_calib_kind)kind;
    out->average = (int)avg;
    out->pattern_us = cfg->pattern_us;
    out->dark_us = cfg->dark_us;
    out->exposure_us = cfg->exposure_us;
    if ((rc = get_u32(r, "pattern_us", 1, 10000000, &out->pattern_us, err)) < 0 ||
        (rc = get_u32(r, "dark_us", 0, 10000000, &out->dark_us, err)) < 0 ||
        (rc = get_u32(r, "exposure_us", 0, 60000000, &out->exposure_us, err)) < 0)
        return rc;
    return 0;
}

int scicapd_args_reconstruct(const scicapd_request *r, const scicapd_config *cfg, scicapd_recon_args *out,
                             sci_error *err)
{
    static const char *const keys[] = {"capture", "method", "preset", "params", "budget_s", NULL};
    memset(out, 0, sizeof *out);
    const char *cap = NULL;
    int rc;
    if ((rc = args_obj(r, keys, err)) < 0)
        return rc;
    if (!r->args)
        return sci_json_fail(r->doc, err, "", "args.capture is required (a capture id)");
    if ((rc = sci_json_get_string(r->doc, r->args, "args", "capture", 1, &cap, err)) < 0)
        return rc;
    if (!cap[0] || strlen(cap) >= sizeof out->capture_id || strchr(cap, '/') || cap[0] == '.')
        return sci_json_fail(r->doc, err, "args.capture", "not a capture id: \"%.64s\"", cap);
    scicapd_capture_id_normalize(cap, out->capture_id, sizeof out->capture_id);
    if ((rc = get_recon(r, r->args, "args", cfg, &out->spec, err)) < 0)
        return rc;
    double budget = 0;
    if ((rc = sci_json_get_double(r->doc, r->args, "args", "budget_s", 0, 1e-6, 1e6, &budget, err)) < 0)
        return rc;
    const int no_budget = rc == 1, needs_camera = (out->spec.method->caps & SOLVER_NEEDS_CAMERA) != 0;
    if (no_budget && !needs_camera)
        return 0;
    /* The capture's size, from its manifest: times scale with w·h·N; and whether it has a camera (a static
     * scene: the NeRF methods' curves count too, and only such a capture can be reconstructed by them). */
    char path[SCICAPD_PATH_MAX + 96];
    snprintf(path, sizeof path, "%s/captures/%s/problem.json", cfg->storage_root, out->capture_id);
    json_t *man = json_load_file(path, 0, NULL);
    double voxels = man ? (double)json_integer_value(json_object_get(man, "w")) *
                              (double)json_integer_value(json_object_get(man, "h")) *
                              (double)json_integer_value(json_object_get(man, "n"))
                        : 0;
    int has_camera = man && json_is_object(json_object_get(man, "camera"));
    json_decref(man);
    if (no_budget) { /* refused now rather than failed by the worker (an unknown capture is the worker's to say) */
        if (voxels > 0 && !has_camera)
            return sci_json_fail(r->doc, err, "args.method", "%s needs a capture with a camera (a static scene, e.g. "
                                 "a problem folder imported with scicap capture --from); capture \"%s\" has none",
                                 out->spec.method->name, out->capture_id);
        return 0;
    }
    if (!(voxels > 0))
        return sci_json_fail(r->doc, err, "args.capture", "capture \"%s\" not found (needed to size the budget)",
                             out->capture_id);
    const char *method = json_object_get(r->args, "method") ? out->spec.method->name : NULL;
    return apply_budget(cfg, r->doc, "args.budget_s", budget, method, has_camera, voxels, &out->spec, err);
}

int scicapd_args_cancel(const scicapd_request *r, uint64_t *job, sci_error *err)
{
    static const char *const keys[] = {"job", NULL};
    long long j;
    int rc;
    if ((rc = args_obj(r, keys, err)) < 0)
        return rc;
    if (!r->args)
        return sci_json_fail(r->doc, err, "", "args.job is required (a job number)");
    if ((rc = sci_json_get_int(r->doc, r->args, "args", "job", 1, 1, (long long)1 << 53, &j, err)) < 0)
        return rc;
    *job = (uint64_t)j;
    return 0;
}

int scicapd_args_captures(const scicapd_request *r, long *limit, sci_error *err)
{
    static const char *const keys[] = {"limit", NULL};
    long long v = 0;
    int rc;
    if ((rc = args_obj(r, keys, err)) < 0)
        return rc;
    if (r->args && (rc = sci_json_get_int(r->doc, r->args, "args", "limit", 0, 0, 1000000, &v, err)) < 0)
        return rc;
    *limit = (long)v;
    return 0;
}

int scicapd_args_simulate(const scicapd_request *r, scicapd_simulate_args *out, sci_error *err)
{
    static const char *const keys[] = {"fault", "n", NULL};
    static const char *const faults[] = {"dmd-unplug", "dmd-replug", "camera-stall", "trigger-miss",
                                         "acquire-delay", NULL};
    int rc, f;
    long long n = 0;
    if ((rc = args_obj(r, keys, err)) < 0)
        return rc;
    if (!r->args)
        return sci_json_fail(r->doc, err, "", "args.fault is required");
    if ((rc = sci_json_get_enum(r->doc, r->args, "args", "fault", 1, faults, &f, err)) < 0 ||
        (rc = sci_json_get_int(r->doc, r->args, "args", "n", 0, 0, 1000000, &n, err)) < 0)
        return rc;
    out->fault = (scicapd_fault)f;
    out->n = (long)n;
    return 0;
}

/* ---- encoding ---- */

static char *line_of(json_t *msg)
{
    char *s = msg ? json_dumps(msg, JSON_COMPACT | JSON_ENSURE_ASCII) : NULL;
    json_decref(msg);
    if (!s)
        return NULL;
    size_t n = strlen(s);
    char *out = realloc(s, n + 2);
    if (!out) {
        free(s);
        return NULL;
    }
    out[n] = '\n';
    out[n + 1] = '\0';
    return out;
}

static json_t *id_or_null(const json_t *id) { return id ? json_incref((json_t *)id) : json_null(); }

char *scicapd_reply_ok(const json_t *id, json_t *result)
{
    return line_of(json_pack("{s:i, s:o, s:b, s:o}", "v", SCICAPD_PROTOCOL_VERSION, "id", id_or_null(id), "ok", 1,
                             "result", result ? result : json_object()));
}

/* "request:L:C: args.PATH: reason" (sci_json_fail's form for the request line): PATH into arg, the reason's start
 * returned; NULL for any other message. */
static const char *split_arg_error(const char *msg, char *arg, size_t n)
{
    int line, col, off = 0;
    if (strncmp(msg, "request:", 8) != 0 || sscanf(msg + 8, "%d:%d: %n", &line, &col, &off) != 2 || off == 0)
        return NULL;
    const char *p = msg + 8 + off;
    const char *sep = strstr(p, ": ");
    if (strncmp(p, "args", 4) != 0 || !sep || (p[4] != '.' && p + 4 != sep))
        return NULL;
    const char *key = p[4] == '.' ? p + 5 : p + 4;
    snprintf(arg, n, "%.*s", (int)(sep - key), key);
    return sep + 2;
}

char *scicapd_reply_error(const json_t *id, scicapd_errcode code, const char *message)
{
    const char *text = message && message[0] ? message : scicapd_errcode_name(code);
    json_t *e = json_pack("{s:s, s:s}", "code", scicapd_errcode_name(code), "message", text);
    char arg[128];
    const char *reason = e ? split_arg_error(text, arg, sizeof arg) : NULL;
    if (reason) {
        json_object_set_new(e, "arg", json_string(arg));
        json_object_set_new(e, "reason", json_string(reason));
    }
    return line_of(json_pack("{s:i, s:o, s:b, s:o}", "v", SCICAPD_PROTOCOL_VERSION, "id", id_or_null(id), "ok", 0,
                             "error", e));
}

char *scicapd_event(const char *name, uint64_t job, const json_t *id, json_t *data)
{
    return line_of(json_pack("{s:i, s:s, s:I, s:o, s:o}", "v", SCICAPD_PROTOCOL_VERSION, "event", name, "job",
                             (json_int_t)job, "id", id_or_null(id), "data", data ? data : json_object()));
}
