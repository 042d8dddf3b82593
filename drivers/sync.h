/* drivers/sync.h — did the DMD's masks fall inside the camera's exposure? The sync report of one snapshot.
 *
 * Inputs, all times in ns of CLOCK_MONOTONIC:
 *   - the plan: the DMD pattern timeline as commanded (sync_timeline: start of pattern 0, per-pattern display
 *     and dark times in µs, N patterns);
 *   - the observation: the DMD's trigger-output edges (one rising edge per pattern, read from a GPIO input with
 *     kernel timestamps) and the camera's exposure window (from its strobe edges, or estimated from the frame
 *     timestamp and the exposure setting when no strobe is wired).
 * Output (sync_report): for each mask its display interval, how much of it lies inside the exposure (inside,
 * partial, outside), the timing error of each measured pattern start against the plan, and flags; `broken` is
 * set when the snapshot must not be stored as good (docs/architecture.md, Contracts: Acquisition).
 *
 * Matching edges to patterns: with exactly N edges they pair in order (robust to any latency). Otherwise the
 * first edge fixes the offset and each edge pairs with the nearest planned start within half that pattern's
 * period; the rest are flagged missing or extra. Unmatched patterns are placed at their planned start shifted
 * by the mean measured offset (or at the plan when no edge was seen).
 *
 * Pure functions, no allocation, thread-safe. The report is large (SYNC_MAX_PATTERNS entries): heap or static
 * storage, not a small stack.
 */
#ifndef SCICAP_DRIVERS_SYNC_H
#define SCICAP_DRIVERS_SYNC_H

#include <jansson.h>
#include <stdint.h>

#include "base/error.h"

/* DLPC900 sequences hold at most 400 one-bit patterns; 1024 leaves room for other controllers. */
#define SYNC_MAX_PATTERNS 1024

/* Who starts whom (docs/sync.md has a timing diagram for each). */
enum sync_mode {
    SYNC_MODE_DMD_MASTER = 0,  /* host starts the DMD; the DMD's trigger output starts the camera exposure */
    SYNC_MODE_HOST_MASTER,     /* one GPIO output pulse starts both the DMD sequence and the exposure */
    SYNC_MODE_CAMERA_MASTER,   /* the camera exposes (free-run or soft trigger); its strobe starts the DMD */
    SYNC_MODE_COUNT
};
/* "dmd-master", "host-master", "camera-master"; "unknown" otherwise. */
const char *sync_mode_name(enum sync_mode m);
/* Parse the names above; -EINVAL naming the value. */
int sync_mode_from_name(const char *name, enum sync_mode *out, sci_error *err);

/* The DMD pattern timeline as commanded. Pattern i starts at start_ns + Σ_{j<i} (exposure_us[j] + dark_us[j])·1000
 * and is displayed for exposure_us[i]. */
typedef struct sync_timeline {
    int64_t start_ns;                       /* planned start of pattern 0 */
    int count;                              /* N, 1 .. SYNC_MAX_PATTERNS */
    uint32_t exposure_us[SYNC_MAX_PATTERNS]; /* display time of each pattern */
    uint32_t dark_us[SYNC_MAX_PATTERNS];     /* dark time after each pattern */
} sync_timeline;

/* Fill `tl` with `count` equal patterns. -EINVAL if count is out of range or exposure_us is 0. */
int sync_timeline_uniform(sync_timeline *tl, int64_t start_ns, int count, uint32_t exposure_us, uint32_t dark_us,
                          sci_error *err);
/* Planned start of pattern i (0 <= i <= count; i == count gives the end of the last dark time). */
int64_t sync_timeline_pattern_start_ns(const sync_timeline *tl, int i);
/* Planned end of the last pattern's display (not counting its dark time). */
int64_t sync_timeline_end_ns(const sync_timeline *tl);

/* What was measured. Arrays are borrowed for the duration of the call. */
typedef struct sync_observation {
    const int64_t *dmd_edges_ns; /* rising edges of the DMD's per-pattern trigger output, ascending */
    int dmd_edge_count;
    int64_t exposure_start_ns, exposure_end_ns; /* the camera's exposure window, end > start */
    int exposure_measured; /* 1: from strobe edges; 0: estimated (flagged SYNC_FLAG_EXPOSURE_ESTIMATED) */
} sync_observation;

typedef struct sync_tolerance {
    int64_t max_offset_ns;  /* |mean(measured - planned)| above this sets SYNC_FLAG_OFFSET */
    int64_t max_jitter_ns;  /* max |error - mean error| above this sets SYNC_FLAG_JITTER */
    double inside_slack;    /* a mask with overlap >= 1 - inside_slack counts as inside (absorbs edge jitter) */
} sync_tolerance;

/* 50 µs offset, 20 µs jitter, 0.5 % slack. */
sync_tolerance sync_tolerance_default(void);

enum sync_mask_state { SYNC_MASK_INSIDE = 0, SYNC_MASK_PARTIAL, SYNC_MASK_OUTSIDE };

typedef struct sync_mask_result {
    int64_t start_ns, end_ns; /* display interval used: measured start when an edge matched, else estimated */
    int measured;             /* 1 if start_ns came from a DMD edge */
    int64_t error_ns;         /* measured start - planned start; 0 when not measured */
    double overlap;           /* fraction of the display interval inside the exposure, 0 .. 1 */
    enum sync_mask_state state;
} sync_mask_result;

enum sync_flag {
    SYNC_FLAG_NO_DMD_EDGES = 1 << 0,  /* no DMD edge at all: the DMD missed its start, or the line is not wired */
    SYNC_FLAG_MISSING_EDGES = 1 << 1, /* some patterns had no edge */
    SYNC_FLAG_EXTRA_EDGES = 1 << 2,   /* edges that match no pattern */
    SYNC_FLAG_PARTIAL_MASK = 1 << 3,  /* a mask straddles an exposure boundary */
    SYNC_FLAG_MASK_OUTSIDE = 1 << 4,  /* a mask lies wholly outside the exposure */
    SYNC_FLAG_OFFSET = 1 << 5,        /* systematic timing error above tolerance */
    SYNC_FLAG_JITTER = 1 << 6,        /* pattern-to-pattern timing error above tolerance */
    SYNC_FLAG_NO_FRAME = 1 << 7,      /* no exposure to compare with (the camera missed its trigger) */
    SYNC_FLAG_EXPOSURE_ESTIMATED = 1 << 8, /* informational: no strobe, window from timestamp + setting */
};
/* Flags that make a snapshot broken: everything but EXPOSURE_ESTIMATED. */
#define SYNC_FLAGS_BROKEN 0xffu

typedef struct sync_report {
    int mask_count;                   /* N */
    int inside, partial, outside;     /* masks in each state */
    int edges_seen, edges_matched;    /* DMD edges observed, and matched to a pattern */
    int64_t offset_ns;                /* mean(measured - planned) over matched patterns: the latency error */
    int64_t max_abs_error_ns;         /* max |measured - planned| */
    int64_t jitter_ns;                /* max |error - offset| */
    int64_t exposure_start_ns, exposure_end_ns;
    int exposure_measured;
    int64_t lead_ns;                  /* first mask start - exposure start (negative: mask began too early) */
    int64_t trail_ns;                 /* exposure end - last mask end (negative: mask ended too late) */
    unsigned flags;                   /* enum sync_flag bits */
    int broken;                       /* flags & SYNC_FLAGS_BROKEN */
    sync_mask_result masks[SYNC_MAX_PATTERNS];
} sync_report;

/* Compute the report. `obs` may be NULL when no frame came (the report then says NO_FRAME and every mask is
 * outside). -EINVAL (naming the field) for a bad timeline or an exposure window with end <= start. */
int sync_report_compute(const sync_timeline *plan, const sync_observation *obs, const sync_tolerance *tol,
                        sync_report *out, sci_error *err);

/* "partial_mask,jitter" (names of the set flags, comma-separated; "ok" for none). Writes at most n bytes. */
char *sync_flags_describe(unsigned flags, char *buf, size_t n);

/* The report as a JSON object for meta.json (summary fields, flag names, and per-mask arrays of state, overlap
 * and error). New reference owned by the caller; NULL on allocation failure. */
json_t *sync_report_to_json(const sync_report *r);

#endif
