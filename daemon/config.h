/* daemon/config.h — scicapd's configuration: /etc/scicap/scicapd.json (docs/config.md), validated.
 *
 * Every key has a default, so the daemon runs with no file at all: the simulated bench (DMD, camera and trigger
 * backends "sim") showing the embedded default scene (sim/default_scene.h). A file overrides what it lists;
 * unknown keys are refused (typos), and every error reads "file:line:col: key.path: reason" (SCI_ECONFIG).
 *
 *     scicapd_config *cfg;
 *     if (scicapd_config_load(&cfg, "/etc/scicap/scicapd.json", &err) < 0) ... err.msg ...
 *     scicapd_config_free(cfg);
 *
 * Reload (SIGHUP, `scicap reload`): load a new object, and swap it in only when it loaded cleanly; the old one
 * stays in force otherwise. scicapd_config_restart_keys names the sections whose change needs a restart.
 * Units: times in µs, sizes in bytes or pixels as named. Objects are immutable after loading; not thread-safe
 * to modify, safe to read from several threads.
 */
#ifndef SCICAP_DAEMON_CONFIG_H
#define SCICAP_DAEMON_CONFIG_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "drivers/sync.h"
#include "recon/solver.h"
#include "sim/masks.h"

#define SCICAPD_CONFIG_DEFAULT_PATH "/etc/scicap/scicapd.json"
#define SCICAPD_NAME_MAX 64
#define SCICAPD_PATH_MAX 1024
#define SCICAPD_MAX_MASK_SETS 64

/* A named set of N binary masks, made at the DMD's size when first used (sim/masks.h kinds). */
typedef struct scicapd_mask_set {
    char name[SCICAPD_NAME_MAX];
    int frames;             /* N, 1..400 */
    uint64_t seed;          /* random kinds */
    sim_mask_spec spec;     /* kind, density, block, step, direction, path; mapped = 0 (DMD = sensor) */
} scicapd_mask_set;

typedef struct scicapd_config {
    char path[SCICAPD_PATH_MAX];          /* file it came from; "" = built-in defaults */
    /* control */
    char socket_path[SCICAPD_PATH_MAX];   /* /run/scicapd/control.sock */
    unsigned socket_mode;                 /* 0660 */
    char socket_group[SCICAPD_NAME_MAX];  /* "scicap"; "" = keep the process's group */
    int max_clients;                      /* 32: connections at once, admin_slots included */
    int admin_slots;                      /* 2: of max_clients, kept for admin peers (root, the daemon's user,
                                             admin_group), so a flood of connections never locks admins out */
    int request_timeout_ms;               /* 10000: a request line must be complete this long after its first
                                             byte (for the first request: after connect); else the connection
                                             is answered "timeout" and closed */
    int idle_timeout_ms;                  /* 300000: a connection that is not watching and has no unfinished job
                                             is closed this long after its last request; 0 = never */
    size_t max_line_bytes;                /* 65536: longest request line */
    int max_per_uid;                      /* 8: connections of one ordinary uid at once; 0 = no cap */
    int stall_timeout_ms;                 /* 60000: a connection whose output waits this long unread is closed;
                                             0 = never */
    char admin_group[SCICAPD_NAME_MAX];   /* "scicap-admin": members may reload, shutdown, simulate and cancel
                                             any job (besides root and the daemon's user); "" or a group that does
                                             not exist: only those two */
    /* storage */
    char storage_root[SCICAPD_PATH_MAX];  /* /var/lib/scicapd */
    char runtime_dir[SCICAPD_PATH_MAX];   /* /run/scicapd */
    int fsync;                            /* 1: fsync files and folders before a capture is announced */
    int writers;                          /* storage writer threads, 1..16 (capture folders written in parallel) */
    int previews;                         /* 1: 8-bit PNG/GIF previews in each capture folder */
    /* devices: backend names ("sim", "dlpc900", "v4l2", "aravis", "gpiod") and their own config objects
     * (owned copies) */
    char dmd_backend[16], camera_backend[16], trigger_backend[16];
    char dmd_serial[SCICAPD_NAME_MAX];    /* "" = first found */
    int dmd_emulator;                     /* dlpc900 only: drive the in-process DLPC900 emulator instead of USB */
    int dmd_timeout_ms;                   /* dlpc900: per reply; 0 = the backend's 1000 */
    uint32_t dmd_trigger_delay_us;        /* dlpc900: TRIG_IN_1 edge to pattern (external trigger); 0 = 105 */
    int dmd_trigger_falling;              /* dlpc900: advance on the falling edge of TRIG_IN_1 */
    uint32_t camera_readout_us;           /* exposure end to frame timestamp (window estimate without a strobe) */
    char camera_usb_vendor[8], camera_usb_product[8], camera_usb_serial[SCICAPD_NAME_MAX]; /* "camera.usb":
                                             USB ids for `scicapd --udev-rules`; "" = not given */
    json_t *camera_json, *trigger_json;   /* the "camera" / "trigger" objects minus the daemon's own keys
                                             ("backend", "readout_us", "usb"): what camera_config_from_json /
                                             trigger_config_from_json read; may be NULL */
    /* simulator (used when a backend is "sim") */
    char scene_path[SCICAPD_PATH_MAX];    /* "" = the embedded default scene */
    double sim_counts_per_unit;           /* sensor counts for a full-on mirror on a white target */
    double sim_dark_counts;               /* dark level, counts */
    double sim_read_noise;                /* read noise sigma, counts */
    uint64_t sim_seed;
    uint32_t sim_dmd_latency_us;          /* trigger to first pattern */
    /* mask sets */
    scicapd_mask_set mask_sets[SCICAPD_MAX_MASK_SETS];
    int mask_set_count;
    /* capture defaults */
    char capture_mask_set[SCICAPD_NAME_MAX];
    uint32_t pattern_us, dark_us;         /* per mask */
    uint32_t exposure_us;                 /* camera exposure; 0 = cover the sequence (auto) */
    enum sync_mode sync_mode;
    double counts_per_unit;               /* uncalibrated scale: counts for "white" (0 = simulator's value) */
    /* reconstruction defaults */
    char recon_method[SOLVER_NAME_MAX];   /* a method of recon/solver.h (default: the table's first) */
    char recon_preset[16];                /* "balanced" (fast|balanced|best; default|quality: aliases) */
    char recon_curves[SCICAPD_PATH_MAX];  /* measured accuracy-against-time curves (scicap bench CSV) used to
                                             honour a reconstruct request's budget_s; default
                                             $SCICAP_DATADIR/results.csv when that variable is set, else
                                             SCICAP_DATADIR/results.csv (installed by make install), else, from a
                                             build tree, <exe dir>/../bench/results.csv */
    int recon_auto;                       /* reconstruct every capture unless the request says otherwise */
    int workers;                          /* reconstruction workers, 1..16 (default 2) */
    int recon_threads;                    /* OpenMP threads per worker; 0 = the process's CPUs / workers, >= 1 */
    int recon_checkpoint_every;           /* methods with checkpoints (NeRF): save one every this many steps, so
                                             a run resumes after a crash (default 100; 0: only when the daemon
                                             stops in order) */
    /* queues */
    int capture_queue, recon_queue;       /* bounded job queues: a full queue answers "busy" */
    /* web view (daemon/web.h, docs/web.md): off unless the "web" section is present */
    int web_enabled;                      /* 1 when the file has a "web" section (web.enabled may say 0) */
    char web_host[64];                    /* "127.0.0.1": a numeric IPv4 or IPv6 address, never a name */
    int web_port;                         /* 8080; 0 = any free port (the log says which) */
    int web_control;                      /* 0: read-only; 1: capture/reconstruct/cancel behind the token */
    char web_token_file[SCICAPD_PATH_MAX];/* "" = RUNTIME_DIR/web.token (mode 0640, group control.group) */
    int web_max_connections;              /* 64: HTTP connections at once (SSE streams included) */
    int web_timeout_s;                    /* 10: an HTTP connection silent this long is closed */
} scicapd_config;

/* Built-in defaults (no file). -ENOMEM only. */
int scicapd_config_default(scicapd_config **out, sci_error *err);
/* Load and validate `path`. A missing file is an error (-ENOENT naming it): pass NULL for the defaults. */
int scicapd_config_load(scicapd_config **out, const char *path, sci_error *err);
/* Same from text (`name` stands for the file name in messages). */
int scicapd_config_load_string(scicapd_config **out, const char *name, const char *text, sci_error *err);
void scicapd_config_free(scicapd_config *c);
/* A deep copy (for the acquisition thread, which keeps the device settings it opened with). -ENOMEM. */
int scicapd_config_copy(scicapd_config **out, const scicapd_config *c, sci_error *err);
/* 1 when a and b open the devices differently (devices or simulator sections). */
int scicapd_config_devices_differ(const scicapd_config *a, const scicapd_config *b);
/* The scale of a snapshot without measured masks: capture.counts_per_unit, or the simulator's when that is 0;
 * the dark level without a dark calibration: the simulator's dark_counts (counts). */
void scicapd_config_uncalibrated_scale(const scicapd_config *c, double *counts_per_unit, double *dark_level);

/* The mask set called `name`, or NULL. Borrowed from c. */
const scicapd_mask_set *scicapd_config_mask_set(const scicapd_config *c, const char *name);
/* Sections that differ between a and b and only take effect at restart (socket, storage, devices, workers),
 * as a new JSON array of strings (empty when none). */
json_t *scicapd_config_restart_keys(const scicapd_config *a, const scicapd_config *b);
/* The configuration in force as JSON (for `status`). New reference. */
json_t *scicapd_config_to_json(const scicapd_config *c);

#endif
