/* recon/solver.h — the reconstruction methods as one table: every interface (scicap recon, scicap bench, the bench
 * programs, scicapd) finds a method by its name here and drives it through the same calls, so adding a method is
 * one file with its table row (a const solver_ops) plus one line in recon/solver.c.
 *
 *     const solver_ops *m = solver_find("gap-tv");           // NULL: unknown (solver_names_text lists them)
 *     void *s = solver_settings_new(m);                      // the method's defaults
 *     solver_settings_preset(m, s, SOLVER_PRESET_FAST);      // optional
 *     rc = solver_settings_from_json(m, s, params, NULL, "params", &err);  // {"iters": 50, ...}, validated
 *     solver_io io = {.progress = fn, .user = ctx, .cancel = &flag};
 *     sci_result r = {0};
 *     rc = solver_run(m, problem, s, &io, &r);               // 0, SCI_ECANCELED, SCI_EDIVERGED, or an error
 *     json_t *j = solver_settings_to_json(m, s);             // {"method": "gap-tv", "iters": 50, ...}
 *     sci_result_free_contents(&r); solver_settings_free(s);
 *
 * Settings are the method's own params struct (sci_gaptv_params, sci_rayformer_params, ...), handled here as an
 * opaque block of settings_size bytes; the field table (solver_field) names each JSON key, its type, range and
 * place in the struct, so reading, writing and range-checking JSON is written once (recon/solver.c) for every
 * method. Keys are the struct's field names (recipe fields without "recipe."); a few aliases keep the names the
 * bench and its curves file used (rayformer "table", scinerf "rays").
 *
 * One preset vocabulary for every method and interface: fast | balanced | best. The daemon's former names
 * "default" and "quality" are accepted as aliases of balanced and best (deprecated: solver_preset_parse says so).
 * A preset overwrites the method's cost/accuracy fields only; the defaults (no preset) need not equal balanced:
 * gap-tv and admm-tv keep PnP-SCI's 100 iterations as defaults, their presets are points of the measured curve.
 *
 * Errors: 0 or a negative code (-EINVAL for a bad value, SCI_ECONFIG when a JSON document gave it) with a message
 * naming the method, the key and the value. Nothing here prints or exits. The table is const and every function is
 * reentrant; a run blocks its thread (OpenMP inside).
 */
#ifndef SCICAP_RECON_SOLVER_H
#define SCICAP_RECON_SOLVER_H

#include <jansson.h>
#include <stdatomic.h>
#include <stddef.h>

#include "base/error.h"
#include "base/json.h"
#include "recon/problem.h"

typedef enum solver_preset { SOLVER_PRESET_FAST, SOLVER_PRESET_BALANCED, SOLVER_PRESET_BEST } solver_preset;
#define SOLVER_PRESET_COUNT 3

/* "fast", "balanced", "best", NULL: for option lists and enum getters. */
extern const char *const solver_preset_names[SOLVER_PRESET_COUNT + 1];
/* The name, or one of the deprecated aliases "default" (balanced) and "quality" (best); *deprecated (nullable) is
 * set to 1 for an alias. -EINVAL naming the word and the three names. */
int solver_preset_parse(const char *name, solver_preset *out, int *deprecated, sci_error *err);
const char *solver_preset_name(solver_preset p);
/* Member `key` of JSON object obj (at objpath in doc) read as a preset, aliases included: 0 with *out set, 1 when
 * absent, or SCI_ECONFIG positioned in the document ("...: preset: must be fast, balanced or best (got ...)"). */
int solver_preset_get(const sci_json_doc *doc, const json_t *obj, const char *objpath, const char *key,
                      solver_preset *out, sci_error *err);

/* What a method needs or offers (solver_ops.caps). */
enum {
    SOLVER_NEEDS_CAMERA = 1, /* the problem must carry a camera (sci_camera): a static scene seen by a moving camera */
    SOLVER_CHECKPOINTS = 2,  /* honours solver_io's checkpoint hooks and resume blob */
    SOLVER_POSES = 4,        /* can write the final camera poses (solver_io.poses_out) */
    SOLVER_BAYER = 8,        /* reconstructs a Bayer mosaic whole (solver_io.cfa) and hands out RGB frames
                                (solver_io.rgb_out); other methods are run per CFA plane (recon/bayer.h) */
};

typedef enum solver_field_type {
    SOLVER_FIELD_INT,    /* int; JSON integer */
    SOLVER_FIELD_DOUBLE, /* double; JSON number, finite */
    SOLVER_FIELD_BOOL,   /* int 0/1; JSON true/false (or 0/1) */
    SOLVER_FIELD_SEED,   /* unsigned long long; JSON integer >= 0 */
    SOLVER_FIELD_ENUM,   /* an int-sized enum; JSON string among names[] (or its index); value = index */
    SOLVER_FIELD_ACTION, /* no storage: names[] (or an index) passed to the method's action(); not written out */
    SOLVER_FIELD_STRING, /* char[SOLVER_STRING_MAX], NUL-terminated; JSON string (e.g. a file path) */
    SOLVER_FIELD_LIST,   /* solver_values; JSON array of 1..SOLVER_LIST_MAX numbers in [lo, hi], or a string "50,25" */
} solver_field_type;

#define SOLVER_NAME_MAX SCI_METHOD_NAME_MAX /* bytes of a method name (solver_ops.name), the NUL included */
#define SOLVER_STRING_MAX 256 /* bytes of a STRING field, the NUL included */
#define SOLVER_LIST_MAX 8     /* values of a LIST field */
typedef struct solver_values {
    int n;                     /* values in use, 1..SOLVER_LIST_MAX */
    double v[SOLVER_LIST_MAX];
} solver_values;

/* The largest settings struct of any method. Interfaces that hold settings by value (scicapd's spec, whose
 * SCICAPD_SETTINGS_MAX is this) size their buffers by it. Generous on purpose, so a new method needs no edit here:
 * the largest row today holds 712 bytes (two STRING paths of SOLVER_STRING_MAX); a row whose settings_size exceeds
 * it is refused by solver_list_check (tests/unit/test_solver.c; test_cli_recon_opts prints every row's size). */
#define SOLVER_SETTINGS_MAX 2048

enum { SOLVER_FIELD_ALIAS = 1 }; /* solver_field.flags: another name of a field listed before it; not written out */

typedef struct solver_field {
    const char *key;          /* JSON key and --option (with '_' as '-') */
    solver_field_type type;
    size_t offset;            /* in the method's settings struct */
    double lo, hi;            /* inclusive range of the value (INT, DOUBLE, SEED) */
    const char *const *names; /* ENUM, ACTION: NULL-terminated names, value = position */
    int flags;
    const char *help;         /* one line */
} solver_field;

typedef struct solver_fields {
    const solver_field *f;
    int n;
    size_t base; /* added to each field's offset: a field list shared by methods (recon/nerf/nerf_solve.h) */
} solver_fields;

/* A checkpoint handed out by a method with SOLVER_CHECKPOINTS (the same type as nerf_checkpoint_fn): the blob is
 * borrowed for the call; a nonzero return stops the run with that code. */
typedef int (*solver_checkpoint_fn)(const void *blob, size_t bytes, int iter, void *user);

/* What a run is given besides the problem and the settings. Zero-initialise and set what you use. */
typedef struct solver_io {
    sci_progress_fn progress;      /* after every iteration with the newest trace row; nonzero return cancels */
    void *user;
    const atomic_int *cancel;      /* nonzero cancels at the next iteration (another thread may set it); NULL: none */
    solver_checkpoint_fn checkpoint_fn; /* SOLVER_CHECKPOINTS: every checkpoint_every steps, at the end, on cancel */
    void *checkpoint_user;
    int checkpoint_every;          /* 0: only on cancel */
    const void *resume;            /* borrowed checkpoint blob to continue from (same problem and settings) */
    size_t resume_bytes;
    double (*poses_out)[12];       /* SOLVER_POSES: N camera-to-world poses written at the end, or NULL */
    int cfa;                       /* SOLVER_BAYER: a sci_cfa (recon/demosaic.h) when the problem is a raw Bayer
                                      mosaic (frames and truth mosaicked), SCI_CFA_NONE (0) for grey */
    int demosaic;                  /* SOLVER_BAYER: the sci_demosaic_method the method demosaics with */
    sci_cube **rgb_out;            /* SOLVER_BAYER with a cfa: receives the w×h×3N RGB frames (frame f's channel c
                                      is frame 3f + c; caller frees), or NULL */
} solver_io;

typedef struct solver_ops {
    const char *name;    /* "gap-tv": the one spelling used in options, JSON, folders (recon/<name>/) and traces */
    const char *summary; /* one line for help texts */
    unsigned caps;       /* SOLVER_NEEDS_CAMERA | ... */
    size_t settings_size;
    solver_fields fields[2]; /* the method's keys, then (optionally) a shared list; unused: {NULL, 0, 0} */
    void (*defaults)(void *settings);
    /* Overwrite the cost/accuracy fields with a preset. */
    void (*preset)(void *settings, solver_preset p);
    /* ACTION fields: apply value (an index into the field's names) for key. -EINVAL with a message. */
    int (*action)(void *settings, const char *key, int value, sci_error *err);
    /* After solver_settings_from_json applied an object's keys (before: the settings as they were before those
     * keys): rules between keys, e.g. rayformer's "patch" without "patches_per_step" keeps the rays per step.
     * NULL: none. */
    void (*from_json_rules)(void *settings, const void *before, const json_t *obj);
    /* The method's own checks across fields; -EINVAL with a message naming the method and the field. */
    int (*check)(const void *settings, sci_error *err);
    /* Reconstruct: the solver contract of recon/gaptv.h. io is never NULL here (solver_run passes a zeroed one). */
    int (*run)(const sci_problem *p, const void *settings, const solver_io *io, sci_result *result);
    /* `scicap bench`: the points of the method's cost grid as JSON settings objects (NULL-terminated), the quick
     * grid (CI) and the full one. Their keys are the "setting" column of bench/results.csv. */
    const char *const *bench_quick;
    const char *const *bench_full;
} solver_ops;

/* The methods in table order (NULL-terminated); *count (nullable) receives how many. */
const solver_ops *const *solver_list(size_t *count);
/* 0, or -EINVAL naming the first row of the table that breaks a rule every interface relies on (a name shorter
 * than SOLVER_NAME_MAX bytes, or than NERF_CKPT_METHOD_MAX for a method with SOLVER_CHECKPOINTS; settings_size
 * within SOLVER_SETTINGS_MAX, an "iters" field, names unique, presets and bench grids present). */
int solver_list_check(sci_error *err);
/* The same rules on a NULL-terminated table like solver_list's (a test hands it one with a broken row). */
int solver_table_check(const solver_ops *const *list, sci_error *err);
/* The method called `name` in `list` (a NULL-terminated table like solver_list's), or NULL; with err (nullable)
 * set to -EINVAL "unknown method 'x' (the list's names)". Interfaces that take the table as a parameter (the
 * command line, so a test can hand it a table with an extra method) find methods through this. */
const solver_ops *solver_list_find(const solver_ops *const *list, const char *name, sci_error *err);
/* The method called `name`, or NULL. */
const solver_ops *solver_find(const char *name);
/* The method called `name`, or NULL with -EINVAL in err: "unknown method 'x' (gap-tv, admm-tv, ...)". */
const solver_ops *solver_find_err(const char *name, sci_error *err);
/* "gap-tv, admm-tv, rayformer, scinerf" into buf (for usage texts and messages); returns buf. `sep` between. */
char *solver_names_text(char *buf, size_t n, const char *sep);

/* Settings: malloc'd settings_size bytes holding the defaults; NULL on ENOMEM. solver_settings_free(NULL) is fine. */
void *solver_settings_new(const solver_ops *m);
void solver_settings_free(void *settings);
void solver_settings_preset(const solver_ops *m, void *settings, solver_preset p);
/* The field of key `key` (aliases included), or NULL. */
const solver_field *solver_field_find(const solver_ops *m, const char *key, size_t *base);
/* Set one key from a JSON value (type and range checked; ACTION keys run the action). Returns 0, 1 when the method
 * has no such key (nothing changed, no message), or a negative code with a message (`path` names where the value
 * came from, e.g. "params.iters" or "--iters"; doc nullable: with it the message carries file:line:column). */
int solver_settings_set(const solver_ops *m, void *settings, const char *key, const json_t *value,
                        const sci_json_doc *doc, const char *path, sci_error *err);
/* Apply a JSON object: "preset" first when present, then every other key in order, then the method's rules,
 * then solver_settings_check. Unknown keys are refused with the list of the method's keys. "method" is accepted
 * when it names this method (so to_json's output reads back). On error the settings may be partly changed. */
int solver_settings_from_json(const solver_ops *m, void *settings, const json_t *obj, const sci_json_doc *doc,
                              const char *path, sci_error *err);
/* {"method": name, key: value, ...} for every stored field (aliases and actions left out): a new reference, or
 * NULL on ENOMEM. Enums are written as their names, booleans as true/false. */
json_t *solver_settings_to_json(const solver_ops *m, const void *settings);
/* Ranges of every field and the method's own checks. */
int solver_settings_check(const solver_ops *m, const void *settings, sci_error *err);
/* The "iters" field (every method has one): what a progress display expects. */
int solver_settings_iters(const solver_ops *m, const void *settings);

/* Run the method on p: validates the settings (the method refuses a problem it cannot use, e.g. one without a
 * camera for SOLVER_NEEDS_CAMERA), wraps the progress callback to honour io->cancel, and fills result (zeroed by
 * the caller; freed with sci_result_free_contents). io NULL: no callback, no cancel. Returns as the method's run. */
int solver_run(const solver_ops *m, const sci_problem *p, const void *settings, const solver_io *io,
               sci_result *result);

#endif
