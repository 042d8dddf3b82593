#include "drivers/trigger_gpiod.h"

#include <dirent.h>
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"

#if SCICAP_GPIOD_MAJOR >= 1
#include <gpiod.h>
#endif

#define GPIOD_CONSUMER_DEFAULT "scicap"

__attribute__((unused)) static void gpiod_sleep_us(uint32_t us)
{
    struct timespec ts = {.tv_sec = us / 1000000, .tv_nsec = (long)(us % 1000000) * 1000};
    while (nanosleep(&ts, &ts) < 0 && errno == EINTR)
        ;
}

__attribute__((unused)) static int chip_open_error(const char *chip, int e, sci_error *err)
{
    if (e == ENOENT || e == ENODEV)
        return sci_error_set(err, -ENOENT, "GPIO chip %s: no such chip", chip);
    if (e == EACCES || e == EPERM)
        return sci_error_set(err, -EACCES, "GPIO chip %s: permission denied (udev rule / group?)", chip);
    return sci_error_set(err, -e, "GPIO chip %s: cannot open: %s", chip, sci_strerror(-e));
}

#if SCICAP_GPIOD_MAJOR == 1
/* ------------------------------------------------------------------ libgpiod 1.6 (API v1) */

typedef struct gpiod_trig {
    struct gpiod_chip *chip;
    struct gpiod_line *out;
    struct gpiod_line *in[TRIGGER_ROLE_COUNT];
    uint32_t seqno[TRIGGER_ROLE_COUNT];
    trigger_identity id;
} gpiod_trig;

/* Resolve one line; -ENOENT/-EINVAL with the chip and line named. */
static int v1_line(gpiod_trig *g, const trigger_line_config *lc, const char *role, struct gpiod_line **out,
                   sci_error *err)
{
    struct gpiod_line *l;
    if (lc->offset >= 0) {
        if ((unsigned)lc->offset >= gpiod_chip_num_lines(g->chip))
            return sci_error_set(err, -EINVAL, "GPIO chip %s: %s line %d does not exist (the chip has %u lines)",
                                 g->id.chip, role, lc->offset, gpiod_chip_num_lines(g->chip));
        l = gpiod_chip_get_line(g->chip, (unsigned)lc->offset);
    } else {
        l = gpiod_chip_find_line(g->chip, lc->name);
    }
    if (!l)
        return sci_error_set(err, -ENOENT, "GPIO chip %s: %s line \"%s\" not found", g->id.chip, role,
                             lc->name ? lc->name : "?");
    *out = l;
    return 0;
}

static int v1_busy(gpiod_trig *g, struct gpiod_line *l, const char *role, int e, sci_error *err)
{
    if (e == EBUSY) {
        const char *who = gpiod_line_consumer(l);
        return sci_error_set(err, -EBUSY, "GPIO chip %s: %s line %u is busy (held by \"%s\")", g->id.chip, role,
                             gpiod_line_offset(l), who ? who : "another process");
    }
    return sci_error_set(err, -e, "GPIO chip %s: %s line %u: request failed: %s", g->id.chip, role,
                         gpiod_line_offset(l), sci_strerror(-e));
}

static void gpiod_trig_close(void *state)
{
    gpiod_trig *g = state;
    if (!g)
        return;
    if (g->out)
        gpiod_line_release(g->out);
    for (int r = 0; r < TRIGGER_ROLE_COUNT; r++)
        if (g->in[r])
            gpiod_line_release(g->in[r]);
    gpiod_chip_close(g->chip);
    free(g);
}

static int gpiod_trig_open(void **state, const trigger_config *cfg, sci_error *err)
{
    if (!cfg->chip)
        return sci_error_set(err, -EINVAL, "GPIO trigger: no chip given");
    gpiod_trig *g = calloc(1, sizeof *g);
    if (!g)
        return sci_error_set(err, -ENOMEM, "GPIO trigger: out of memory");
    const char *consumer = cfg->consumer ? cfg->consumer : GPIOD_CONSUMER_DEFAULT;
    int rc;
    errno = 0;
    g->chip = gpiod_chip_open_lookup(cfg->chip); /* path, name, label or number */
    if (!g->chip) {
        rc = chip_open_error(cfg->chip, errno ? errno : ENOENT, err);
        free(g);
        return rc;
    }
    snprintf(g->id.backend, sizeof g->id.backend, "gpiod1");
    snprintf(g->id.chip, sizeof g->id.chip, "%s", gpiod_chip_name(g->chip));
    snprintf(g->id.label, sizeof g->id.label, "%s", gpiod_chip_label(g->chip));
    g->id.output_offset = -1;
    if (cfg->output.offset >= 0 || cfg->output.name) {
        if ((rc = v1_line(g, &cfg->output, "output", &g->out, err)) < 0)
            goto fail;
        int flags = cfg->output.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
        if (gpiod_line_request_output_flags(g->out, consumer, flags, 0) < 0) {
            rc = v1_busy(g, g->out, "output", errno, err);
            g->out = NULL;
            goto fail;
        }
        g->id.output_offset = (int)gpiod_line_offset(g->out);
    }
    for (int r = 0; r < TRIGGER_ROLE_COUNT; r++) {
        g->id.input_offset[r] = -1;
        const trigger_line_config *lc = &cfg->inputs[r];
        if (lc->offset < 0 && !lc->name)
            continue;
        if ((rc = v1_line(g, lc, trigger_role_name((enum trigger_role)r), &g->in[r], err)) < 0)
            goto fail;
        int flags = lc->active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
        if (gpiod_line_request_both_edges_events_flags(g->in[r], consumer, flags) < 0) {
            rc = v1_busy(g, g->in[r], trigger_role_name((enum trigger_role)r), errno, err);
            g->in[r] = NULL;
            goto fail;
        }
        g->id.input_offset[r] = (int)gpiod_line_offset(g->in[r]);
    }
    *state = g;
    return 0;
fail:
    gpiod_trig_close(g);
    return rc;
}

static int gpiod_trig_pulse(void *state, uint32_t width_us, int64_t *t_ns, sci_error *err)
{
    gpiod_trig *g = state;
    int64_t t = sci_clock_mono_ns();
    if (gpiod_line_set_value(g->out, 1) < 0)
        return sci_error_set(err, -errno, "GPIO chip %s: output line %d: set failed: %s", g->id.chip,
                             g->id.output_offset, sci_strerror(-errno));
    gpiod_sleep_us(width_us);
    if (gpiod_line_set_value(g->out, 0) < 0)
        return sci_error_set(err, -errno, "GPIO chip %s: output line %d: reset failed: %s", g->id.chip,
                             g->id.output_offset, sci_strerror(-errno));
    if (t_ns)
        *t_ns = t;
    return 0;
}

/* Read what is pending on every input without waiting; events of the two lines merge in time order later. */
static int v1_drain(gpiod_trig *g, trigger_event *ev, int max, int *count, sci_error *err)
{
    for (int r = 0; r < TRIGGER_ROLE_COUNT && *count < max; r++) {
        if (!g->in[r])
            continue;
        for (;;) {
            struct pollfd pfd = {.fd = gpiod_line_event_get_fd(g->in[r]), .events = POLLIN};
            if (*count >= max || poll(&pfd, 1, 0) <= 0)
                break;
            struct gpiod_line_event e;
            if (gpiod_line_event_read(g->in[r], &e) < 0)
                return sci_error_set(err, -errno, "GPIO chip %s: %s line %d: event read failed: %s", g->id.chip,
                                     trigger_role_name((enum trigger_role)r), g->id.input_offset[r],
                                     sci_strerror(-errno));
            ev[(*count)++] = (trigger_event){.timestamp_ns = (int64_t)e.ts.tv_sec * 1000000000LL + e.ts.tv_nsec,
                                             .role = (enum trigger_role)r,
                                             .rising = e.event_type == GPIOD_LINE_EVENT_RISING_EDGE,
                                             .line_seqno = ++g->seqno[r]};
        }
    }
    return 0;
}

static int cmp_event(const void *a, const void *b)
{
    int64_t x = ((const trigger_event *)a)->timestamp_ns, y = ((const trigger_event *)b)->timestamp_ns;
    return (x > y) - (x < y);
}

static int gpiod_trig_read(void *state, int64_t timeout_ns, trigger_event *ev, int max, int *count, sci_error *err)
{
    gpiod_trig *g = state;
    struct pollfd pfd[TRIGGER_ROLE_COUNT];
    int n = 0;
    for (int r = 0; r < TRIGGER_ROLE_COUNT; r++)
        if (g->in[r])
            pfd[n++] = (struct pollfd){.fd = gpiod_line_event_get_fd(g->in[r]), .events = POLLIN};
    *count = 0;
    if (n == 0)
        return 0;
    struct timespec ts = {.tv_sec = timeout_ns / 1000000000LL, .tv_nsec = timeout_ns % 1000000000LL};
    int r = ppoll(pfd, (nfds_t)n, &ts, NULL);
    if (r < 0 && errno != EINTR)
        return sci_error_set(err, -errno, "GPIO chip %s: poll failed: %s", g->id.chip, sci_strerror(-errno));
    if (r <= 0)
        return 0;
    int rc = v1_drain(g, ev, max, count, err);
    qsort(ev, (size_t)*count, sizeof *ev, cmp_event);
    return rc;
}

static int gpiod_trig_flush(void *state, sci_error *err)
{
    gpiod_trig *g = state;
    trigger_event scratch[64];
    int n;
    do {
        n = 0;
        int rc = v1_drain(g, scratch, 64, &n, err);
        if (rc < 0)
            return rc;
    } while (n == 64);
    return 0;
}

#elif SCICAP_GPIOD_MAJOR >= 2
/* ------------------------------------------------------------------ libgpiod 2.x (API v2) */

typedef struct gpiod_trig {
    struct gpiod_chip *chip;
    struct gpiod_line_request *out_req, *in_req;
    struct gpiod_edge_event_buffer *buf;
    unsigned int out_offset;
    int in_offset[TRIGGER_ROLE_COUNT];
    trigger_identity id;
} gpiod_trig;

/* Open by path, by name under /dev, or by label (scanning /dev/gpiochip*). */
static struct gpiod_chip *v2_chip_open(const char *chip, int *e)
{
    char path[300];
    if (chip[0] == '/')
        snprintf(path, sizeof path, "%s", chip);
    else
        snprintf(path, sizeof path, "/dev/%s", chip);
    struct gpiod_chip *c = gpiod_chip_open(path);
    if (c || chip[0] == '/') {
        *e = errno;
        return c;
    }
    DIR *d = opendir("/dev");
    struct dirent *de;
    while (d && (de = readdir(d))) {
        if (strncmp(de->d_name, "gpiochip", 8) != 0)
            continue;
        snprintf(path, sizeof path, "/dev/%s", de->d_name);
        c = gpiod_chip_open(path);
        if (!c)
            continue;
        struct gpiod_chip_info *info = gpiod_chip_get_info(c);
        int match = info && strcmp(gpiod_chip_info_get_label(info), chip) == 0;
        gpiod_chip_info_free(info);
        if (match) {
            closedir(d);
            return c;
        }
        gpiod_chip_close(c);
    }
    if (d)
        closedir(d);
    *e = ENOENT;
    return NULL;
}

static int v2_offset(gpiod_trig *g, const trigger_line_config *lc, const char *role, unsigned nlines,
                     unsigned *out, sci_error *err)
{
    if (lc->offset >= 0) {
        if ((unsigned)lc->offset >= nlines)
            return sci_error_set(err, -EINVAL, "GPIO chip %s: %s line %d does not exist (the chip has %u lines)",
                                 g->id.chip, role, lc->offset, nlines);
        *out = (unsigned)lc->offset;
        return 0;
    }
    int off = gpiod_chip_get_line_offset_from_name(g->chip, lc->name);
    if (off < 0)
        return sci_error_set(err, -ENOENT, "GPIO chip %s: %s line \"%s\" not found", g->id.chip, role, lc->name);
    *out = (unsigned)off;
    return 0;
}

static int v2_busy(gpiod_trig *g, unsigned off, const char *role, int e, sci_error *err)
{
    if (e == EBUSY) {
        struct gpiod_line_info *li = gpiod_chip_get_line_info(g->chip, off);
        const char *who = li ? gpiod_line_info_get_consumer(li) : NULL;
        int rc = sci_error_set(err, -EBUSY, "GPIO chip %s: %s line %u is busy (held by \"%s\")", g->id.chip, role, off,
                               who ? who : "another process");
        gpiod_line_info_free(li);
        return rc;
    }
    return sci_error_set(err, -e, "GPIO chip %s: %s line %u: request failed: %s", g->id.chip, role, off,
                         sci_strerror(-e));
}

/* Request `n` lines with one settings object; NULL on failure (errno set). */
static struct gpiod_line_request *v2_request(gpiod_trig *g, const unsigned *offs, size_t n,
                                             struct gpiod_line_settings *s, const char *consumer)
{
    struct gpiod_line_config *lc = gpiod_line_config_new();
    struct gpiod_request_config *rc = gpiod_request_config_new();
    struct gpiod_line_request *req = NULL;
    if (lc && rc && gpiod_line_config_add_line_settings(lc, offs, n, s) == 0) {
        gpiod_request_config_set_consumer(rc, consumer);
        gpiod_request_config_set_event_buffer_size(rc, 1024);
        req = gpiod_chip_request_lines(g->chip, rc, lc);
    }
    int e = errno;
    gpiod_request_config_free(rc);
    gpiod_line_config_free(lc);
    errno = e;
    return req;
}

static void gpiod_trig_close(void *state);

static int gpiod_trig_open(void **state, const trigger_config *cfg, sci_error *err)
{
    if (!cfg->chip)
        return sci_error_set(err, -EINVAL, "GPIO trigger: no chip given");
    gpiod_trig *g = calloc(1, sizeof *g);
    if (!g)
        return sci_error_set(err, -ENOMEM, "GPIO trigger: out of memory");
    const char *consumer = cfg->consumer ? cfg->consumer : GPIOD_CONSUMER_DEFAULT;
    int e = 0, rc;
    g->chip = v2_chip_open(cfg->chip, &e);
    if (!g->chip) {
        rc = chip_open_error(cfg->chip, e ? e : ENOENT, err);
        free(g);
        return rc;
    }
    struct gpiod_chip_info *info = gpiod_chip_get_info(g->chip);
    unsigned nlines = info ? (unsigned)gpiod_chip_info_get_num_lines(info) : 0;
    snprintf(g->id.backend, sizeof g->id.backend, "gpiod2");
    snprintf(g->id.chip, sizeof g->id.chip, "%s", info ? gpiod_chip_info_get_name(info) : cfg->chip);
    snprintf(g->id.label, sizeof g->id.label, "%s", info ? gpiod_chip_info_get_label(info) : "");
    gpiod_chip_info_free(info);
    g->id.output_offset = -1;
    struct gpiod_line_settings *s = gpiod_line_settings_new();
    if (!s) {
        rc = sci_error_set(err, -ENOMEM, "GPIO trigger: out of memory");
        goto fail;
    }
    if (cfg->output.offset >= 0 || cfg->output.name) {
        if ((rc = v2_offset(g, &cfg->output, "output", nlines, &g->out_offset, err)) < 0)
            goto fail_settings;
        gpiod_line_settings_set_direction(s, GPIOD_LINE_DIRECTION_OUTPUT);
        gpiod_line_settings_set_output_value(s, GPIOD_LINE_VALUE_INACTIVE);
        gpiod_line_settings_set_active_low(s, cfg->output.active_low != 0);
        g->out_req = v2_request(g, &g->out_offset, 1, s, consumer);
        if (!g->out_req) {
            rc = v2_busy(g, g->out_offset, "output", errno, err);
            goto fail_settings;
        }
        g->id.output_offset = (int)g->out_offset;
    }
    /* Inputs: one request per line, since active_low may differ between them. Simple and rare enough. */
    unsigned offs[TRIGGER_ROLE_COUNT];
    size_t nin = 0;
    int same_polarity = cfg->inputs[TRIGGER_ROLE_DMD].active_low == cfg->inputs[TRIGGER_ROLE_STROBE].active_low;
    for (int r = 0; r < TRIGGER_ROLE_COUNT; r++) {
        g->in_offset[r] = -1;
        g->id.input_offset[r] = -1;
        const trigger_line_config *lc = &cfg->inputs[r];
        if (lc->offset < 0 && !lc->name)
            continue;
        unsigned off;
        if ((rc = v2_offset(g, lc, trigger_role_name((enum trigger_role)r), nlines, &off, err)) < 0)
            goto fail_settings;
        offs[nin++] = off;
        g->in_offset[r] = (int)off;
        g->id.input_offset[r] = (int)off;
    }
    if (nin > 0) {
        if (!same_polarity && nin > 1) {
            rc = sci_error_set(err, -ENOTSUP, "GPIO chip %s: DMD and strobe inputs must share active_low", g->id.chip);
            goto fail_settings;
        }
        gpiod_line_settings_reset(s);
        gpiod_line_settings_set_direction(s, GPIOD_LINE_DIRECTION_INPUT);
        gpiod_line_settings_set_edge_detection(s, GPIOD_LINE_EDGE_BOTH);
        gpiod_line_settings_set_event_clock(s, GPIOD_LINE_CLOCK_MONOTONIC);
        int al = cfg->inputs[TRIGGER_ROLE_DMD].offset >= 0 || cfg->inputs[TRIGGER_ROLE_DMD].name
                     ? cfg->inputs[TRIGGER_ROLE_DMD].active_low
                     : cfg->inputs[TRIGGER_ROLE_STROBE].active_low;
        gpiod_line_settings_set_active_low(s, al != 0);
        g->in_req = v2_request(g, offs, nin, s, consumer);
        if (!g->in_req) {
            rc = v2_busy(g, offs[0], "input", errno, err);
            goto fail_settings;
        }
        g->buf = gpiod_edge_event_buffer_new(64);
        if (!g->buf) {
            rc = sci_error_set(err, -ENOMEM, "GPIO trigger: out of memory");
            goto fail_settings;
        }
    }
    gpiod_line_settings_free(s);
    *state = g;
    return 0;
fail_settings:
    gpiod_line_settings_free(s);
fail:
    gpiod_trig_close(g);
    return rc;
}

static void gpiod_trig_close(void *state)
{
    gpiod_trig *g = state;
    if (!g)
        return;
    if (g->buf)
        gpiod_edge_event_buffer_free(g->buf);
    if (g->in_req)
        gpiod_line_request_release(g->in_req);
    if (g->out_req)
        gpiod_line_request_release(g->out_req);
    if (g->chip)
        gpiod_chip_close(g->chip);
    free(g);
}

static int gpiod_trig_pulse(void *state, uint32_t width_us, int64_t *t_ns, sci_error *err)
{
    gpiod_trig *g = state;
    int64_t t = sci_clock_mono_ns();
    if (gpiod_line_request_set_value(g->out_req, g->out_offset, GPIOD_LINE_VALUE_ACTIVE) < 0)
        return sci_error_set(err, -errno, "GPIO chip %s: output line %u: set failed: %s", g->id.chip, g->out_offset,
                             sci_strerror(-errno));
    gpiod_sleep_us(width_us);
    if (gpiod_line_request_set_value(g->out_req, g->out_offset, GPIOD_LINE_VALUE_INACTIVE) < 0)
        return sci_error_set(err, -errno, "GPIO chip %s: output line %u: reset failed: %s", g->id.chip, g->out_offset,
                             sci_strerror(-errno));
    if (t_ns)
        *t_ns = t;
    return 0;
}

static int v2_read_now(gpiod_trig *g, trigger_event *ev, int max, int *count, sci_error *err)
{
    size_t want = (size_t)max < 64 ? (size_t)max : 64;
    int n = gpiod_line_request_read_edge_events(g->in_req, g->buf, want);
    if (n < 0)
        return sci_error_set(err, -errno, "GPIO chip %s: edge event read failed: %s", g->id.chip, sci_strerror(-errno));
    for (int i = 0; i < n; i++) {
        struct gpiod_edge_event *e = gpiod_edge_event_buffer_get_event(g->buf, (unsigned long)i);
        unsigned off = gpiod_edge_event_get_line_offset(e);
        enum trigger_role role = g->in_offset[TRIGGER_ROLE_DMD] == (int)off ? TRIGGER_ROLE_DMD : TRIGGER_ROLE_STROBE;
        ev[(*count)++] = (trigger_event){.timestamp_ns = (int64_t)gpiod_edge_event_get_timestamp_ns(e),
                                         .role = role,
                                         .rising = gpiod_edge_event_get_event_type(e) == GPIOD_EDGE_EVENT_RISING_EDGE,
                                         .line_seqno = (uint32_t)gpiod_edge_event_get_line_seqno(e)};
    }
    return 0;
}

static int gpiod_trig_read(void *state, int64_t timeout_ns, trigger_event *ev, int max, int *count, sci_error *err)
{
    gpiod_trig *g = state;
    *count = 0;
    if (!g->in_req)
        return 0;
    int r = gpiod_line_request_wait_edge_events(g->in_req, timeout_ns);
    if (r < 0 && errno != EINTR)
        return sci_error_set(err, -errno, "GPIO chip %s: waiting for edges failed: %s", g->id.chip,
                             sci_strerror(-errno));
    if (r <= 0)
        return 0;
    return v2_read_now(g, ev, max, count, err);
}

static int gpiod_trig_flush(void *state, sci_error *err)
{
    gpiod_trig *g = state;
    if (!g->in_req)
        return 0;
    trigger_event scratch[64];
    while (gpiod_line_request_wait_edge_events(g->in_req, 0) > 0) {
        int n = 0;
        int rc = v2_read_now(g, scratch, 64, &n, err);
        if (rc < 0)
            return rc;
    }
    return 0;
}

#else
/* ------------------------------------------------------------------ built without libgpiod */

typedef struct gpiod_trig {
    trigger_identity id;
} gpiod_trig;

static int gpiod_trig_open(void **state, const trigger_config *cfg, sci_error *err)
{
    return sci_error_set(err, -ENOTSUP, "GPIO chip %s: scicap was built without libgpiod",
                         cfg->chip ? cfg->chip : "?");
}
static void gpiod_trig_close(void *state) { free(state); }
static int gpiod_trig_pulse(void *state, uint32_t width_us, int64_t *t_ns, sci_error *err) { return -ENOTSUP; }
static int gpiod_trig_read(void *state, int64_t timeout_ns, trigger_event *ev, int max, int *count, sci_error *err)
{
    return -ENOTSUP;
}
static int gpiod_trig_flush(void *state, sci_error *err) { return -ENOTSUP; }
#endif

static void gpiod_trig_identity(void *state, trigger_identity *out) { *out = ((gpiod_trig *)state)->id; }

const trigger_ops trigger_gpiod_ops = {
    .name = "gpiod",
    .open = gpiod_trig_open,
    .close = gpiod_trig_close,
    .identity = gpiod_trig_identity,
    .pulse = gpiod_trig_pulse,
    .read_events = gpiod_trig_read,
    .flush = gpiod_trig_flush,
};
