/* daemon/protocol.h — the control protocol of scicapd, version 1, in one place (docs/protocol.md).
 *
 * Newline-delimited JSON over a Unix stream socket. One request per line:
 *     {"v": 1, "id": 7, "cmd": "capture", "args": {"mask_set": "random8", "count": 2}}
 * One reply per request, carrying its id:
 *     {"v": 1, "id": 7, "ok": true, "result": {...}}
 *     {"v": 1, "id": 7, "ok": false, "error": {"code": "busy", "message": "capture queue full (16 jobs)"}}
 * and events, streamed to the client that asked for the job and to every client that sent "watch":
 *     {"v": 1, "event": "recon.progress", "job": 12, "id": 7, "data": {"iter": 40, "psnr": 31.2, "eta_s": 0.8}}
 *
 * Checks run in this fixed order before anything is dispatched; the first failure is answered (with the id
 * when it could be read) and the connection keeps serving:
 *     1 size      the line is at most max_line_bytes                     -> "too_long"
 *     2 JSON      the line is one JSON object                            -> "bad_json"
 *     3 version   "v" is 1 (absent means 1)                              -> "bad_version"
 *     4 command   "cmd" names a known command                            -> "unknown_command"
 *     5 arguments "args" is an object of the command's keys, typed and in range -> "bad_arguments"
 *     6 permission admin commands need root, the daemon's user or the admin group; cancel needs the job's
 *                 owner (its submitter's uid) or an admin                 -> "permission"
 * Before any of them, the connection itself: a line not complete within control.request_timeout_ms of its first
 * byte, or a connection idle past control.idle_timeout_ms, is answered "timeout" (id null) and closed.
 * The "id" must be an integer or a string of at most 64 bytes when present (else "bad_json" with id null).
 * Pure functions of their inputs; thread-safe.
 */
#ifndef SCICAP_DAEMON_PROTOCOL_H
#define SCICAP_DAEMON_PROTOCOL_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "base/json.h"
#include "daemon/config.h"
#include "drivers/sync.h"
#include "io/curves.h"
#include "recon/solver.h"

#define SCICAPD_PROTOCOL_VERSION 1

typedef enum scicapd_cmd {
    SCICAPD_CMD_STATUS,
    SCICAPD_CMD_DEVICES,
    SCICAPD_CMD_CAPTURE,
    SCICAPD_CMD_CALIBRATE,
    SCICAPD_CMD_RECONSTRUCT,
    SCICAPD_CMD_JOBS,
    SCICAPD_CMD_CANCEL,
    SCICAPD_CMD_WATCH,
    SCICAPD_CMD_RELOAD,
    SCICAPD_CMD_SHUTDOWN,
    SCICAPD_CMD_SIMULATE, /* fault injection on the simulated bench (admin; refused on hardware) */
    SCICAPD_CMD_IMPORT,   /* captures from files the client passes as descriptors (daemon/import.h) */
    SCICAPD_CMD_CAPTURES, /* the stored captures and their reconstructions (daemon/catalog.h) */
    SCICAPD_CMD_COUNT
} scicapd_cmd;

const char *scicapd_cmd_name(scicapd_cmd c);
/* 1 for commands that need the admin permission (reload, shutdown, simulate). */
int scicapd_cmd_is_admin(scicapd_cmd c);

/* Error codes of failed replies, as they appear on the wire. */
typedef enum scicapd_errcode {
    SCICAPD_OK = 0,
    SCICAPD_E_TOO_LONG,
    SCICAPD_E_BAD_JSON,
    SCICAPD_E_BAD_VERSION,
    SCICAPD_E_UNKNOWN_COMMAND,
    SCICAPD_E_BAD_ARGUMENTS,
    SCICAPD_E_PERMISSION,
    SCICAPD_E_BUSY,          /* a bounded queue is full, or too many clients */
    SCICAPD_E_NOT_FOUND,     /* no such job, capture or mask set */
    SCICAPD_E_FAILED,        /* the command ran and failed (message says why) */
    SCICAPD_E_SHUTTING_DOWN,
    SCICAPD_E_UNSUPPORTED,   /* e.g. simulate on real hardware */
    SCICAPD_E_TIMEOUT,       /* the connection missed its request or idle deadline and is closed */
    SCICAPD_E_COUNT
} scicapd_errcode;

const char *scicapd_errcode_name(scicapd_errcode e);

/* A request after checks 2–4. */
typedef struct scicapd_request {
    json_t *id;          /* new reference: integer, string, or null when absent/unreadable */
    scicapd_cmd cmd;
    sci_json_doc *doc;   /* the parsed line (owned; positions for argument errors) */
    const json_t *args;  /* borrowed from doc; NULL when absent (= no arguments) */
} scicapd_request;

/* Checks 2–4 on one line (without its newline). Returns SCICAPD_OK with *out filled, or an error code with a
 * message in err; out->id is set (possibly null) either way. Free with scicapd_request_clear. */
scicapd_errcode scicapd_request_parse(const char *line, size_t len, scicapd_request *out, sci_error *err);
void scicapd_request_clear(scicapd_request *r);

/* ---- check 5: typed arguments of each command, defaults from the configuration in force ---- */

/* Largest settings struct of a method (recon/solver.h) a spec can hold by value. */
#define SCICAPD_SETTINGS_MAX SOLVER_SETTINGS_MAX

/* A reconstruction fully resolved: method, preset, parameters. Plain data: copied by value through the queues. */
typedef struct scicapd_recon_spec {
    const solver_ops *method;        /* a row of the method table (static) */
    char preset[16];                 /* fast|balanced|best (default|quality as sent), "budget" when chosen by budget */
    double budget_s;                 /* the request's budget (0: none) */
    double predicted_s, expected_db; /* the chosen setting's predicted solver time and mean PSNR on the suite */
    /* the chosen row of the curves ("iters=100 tv_iters=5"); "" when unknown */
    char budget_setting[SCI_CURVE_SETTING_MAX];
    _Alignas(max_align_t) unsigned char settings[SCICAPD_SETTINGS_MAX]; /* the method's params struct */
} scicapd_recon_spec;

/* Method by name (solver_find), preset fast|balanced|best (default and quality: deprecated aliases of balanced and
 * best), then `params` (may be NULL): the method's settings keys (solver_settings_from_json). Errors are positioned
 * in doc at `path`. */
int scicapd_recon_spec_resolve(const char *method, const char *preset, const sci_json_doc *doc,
                               const json_t *params, const char *path, scicapd_recon_spec *out, sci_error *err);
/* The spec as JSON; with a budget, also what was chosen for it (budget_s, predicted_s, expected_psnr_db). */
json_t *scicapd_recon_spec_json(const scicapd_recon_spec *s);
json_t *scicapd_recon_spec_json_plain(const scicapd_recon_spec *s);
/* What a budget chose: {budget_s, method, setting, predicted_s, expected_psnr_db} (setting only when known); NULL
 * without a budget. New reference. */
json_t *scicapd_recon_budget_json(const scicapd_recon_spec *s);

/* A capture id as people type it: "c000042", "c42" and "42" all give "c000042" (the store's names); any other
 * text is copied unchanged (the store then says it has no such capture). out holds n bytes. */
void scicapd_capture_id_normalize(const char *in, char *out, size_t n);

typedef struct scicapd_capture_args {
    scicapd_mask_set mask_set;   /* resolved copy */
    uint32_t pattern_us, dark_us;
    uint32_t exposure_us;        /* 0 = auto: covers latency + sequence */
    enum sync_mode sync;
    int count;                   /* snapshots, 1..1000; each becomes one capture folder */
    int reconstruct;             /* queue a reconstruction of each stored snapshot */
    scicapd_recon_spec recon;
} scicapd_capture_args;

typedef enum scicapd_calib_kind { SCICAPD_CALIB_DARK, SCICAPD_CALIB_MASKS } scicapd_calib_kind;
typedef struct scicapd_calib_args {
    scicapd_calib_kind kind;     /* "dark" or "masks" (each mask shown on a white target and recorded) */
    scicapd_mask_set mask_set;
    uint32_t pattern_us, dark_us, exposure_us;
    int average;                 /* frames averaged per recording, 1..64 */
} scicapd_calib_args;

typedef struct scicapd_recon_args {
    char capture_id[64];
    scicapd_recon_spec spec;
} scicapd_recon_args;

typedef enum scicapd_fault {
    SCICAPD_FAULT_DMD_UNPLUG, SCICAPD_FAULT_DMD_REPLUG, SCICAPD_FAULT_CAMERA_STALL, SCICAPD_FAULT_TRIGGER_MISS,
    SCICAPD_FAULT_ACQUIRE_DELAY,
} scicapd_fault;
typedef struct scicapd_simulate_args {
    scicapd_fault fault;
    long n;                      /* unplug: after n more DMD reports; stall/miss: how many; delay: ms per snapshot */
} scicapd_simulate_args;

int scicapd_args_capture(const scicapd_request *r, const scicapd_config *cfg, scicapd_capture_args *out,
                         sci_error *err);
int scicapd_args_calibrate(const scicapd_request *r, const scicapd_config *cfg, scicapd_calib_args *out,
                           sci_error *err);
int scicapd_args_reconstruct(const scicapd_request *r, const scicapd_config *cfg, scicapd_recon_args *out,
                             sci_error *err);
int scicapd_args_cancel(const scicapd_request *r, uint64_t *job, sci_error *err);
/* captures: `limit` (0..1000000; absent or 0: all) into *limit. */
int scicapd_args_captures(const scicapd_request *r, long *limit, sci_error *err);
int scicapd_args_simulate(const scicapd_request *r, scicapd_simulate_args *out, sci_error *err);
/* Commands without arguments: any key is refused. */
int scicapd_args_none(const scicapd_request *r, sci_error *err);

/* The exposure that covers `n` patterns of (pattern_us + dark_us) started latency_us after the camera: µs. */
uint32_t scicapd_auto_exposure_us(int n, uint32_t pattern_us, uint32_t dark_us, uint32_t latency_us);

/* ---- messages (each a new JSON string with the trailing newline; caller frees) ---- */
char *scicapd_reply_ok(const json_t *id, json_t *result /* stolen, may be NULL */);
/* The error object carries "message" as given; when it is an argument error positioned in the request
 * ("request:1:58: args.method: reason"), also "arg" (the key path under args: "method", "params.iters") and
 * "reason" (the text after the path), so that a client can name its own option instead of a JSON position. */
char *scicapd_reply_error(const json_t *id, scicapd_errcode code, const char *message);
/* An event; `id` is the request id of the job's submitter (may be NULL). `data` stolen. */
char *scicapd_event(const char *name, uint64_t job, const json_t *id, json_t *data);

#endif
