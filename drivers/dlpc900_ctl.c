#include "drivers/dlpc900_ctl.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/dlpc900_image.h"

#define CTL_STALE_MAX 4 /* replies with a foreign sequence number skipped before giving up */

struct dlpc900_ctl {
    dlpc900_transport t;
    char name[96];
    int timeout_ms;
    uint8_t seq;
    dlpc900_traffic traffic;
};

int dlpc900_ctl_new(dlpc900_ctl **out, dlpc900_transport t, const char *name, int timeout_ms, sci_error *err)
{
    dlpc900_ctl *c = calloc(1, sizeof *c);
    if (!c) {
        dlpc900_transport_close(&t);
        return sci_error_set(err, -ENOMEM, "%s: out of memory", name ? name : "DLPC900");
    }
    c->t = t;
    snprintf(c->name, sizeof c->name, "%s", name ? name : "DLPC900");
    c->timeout_ms = timeout_ms > 0 ? timeout_ms : 1000;
    *out = c;
    return 0;
}

void dlpc900_ctl_free(dlpc900_ctl *c)
{
    if (!c)
        return;
    dlpc900_transport_close(&c->t);
    free(c);
}

void dlpc900_ctl_traffic(const dlpc900_ctl *c, dlpc900_traffic *t) { *t = c->traffic; }

static int send_msg(dlpc900_ctl *c, const dlpc900_msg *m, uint8_t *seq_out, sci_error *err)
{
    uint8_t rep[DLPC900_MSG_REPORTS_MAX][DLPC900_REPORT_SIZE];
    uint8_t seq = ++c->seq;
    int n = dlpc900_msg_to_reports(m, seq, rep);
    if (n < 0)
        return sci_error_set(err, -EINVAL, "%s: %s (0x%04X): payload of %u bytes exceeds %d", c->name,
                             dlpc900_cmd_name(m->cmd), m->cmd, m->len, DLPC900_PAYLOAD_MAX);
    if (!c->t.ops)
        return sci_error_set(err, -ENODEV, "%s: not connected", c->name);
    for (int i = 0; i < n; i++) {
        int rc = c->t.ops->write(c->t.ctx, rep[i], c->timeout_ms, err);
        if (rc < 0)
            return sci_error_prefix(err, "%s: %s (0x%04X): ", c->name, dlpc900_cmd_name(m->cmd), m->cmd);
        c->traffic.reports_out++;
    }
    c->traffic.messages++;
    *seq_out = seq;
    return 0;
}

/* Wait for the reply carrying `seq`; replies of earlier, abandoned commands are skipped. */
static int recv_reply(dlpc900_ctl *c, const dlpc900_msg *m, uint8_t seq, dlpc900_reply *r, sci_error *err)
{
    for (int tries = 0; tries <= CTL_STALE_MAX; tries++) {
        uint8_t rep[DLPC900_REPORT_SIZE];
        int n = c->t.ops->read(c->t.ctx, rep, c->timeout_ms, err);
        if (n == -ETIMEDOUT)
            return sci_error_set(err, -ETIMEDOUT, "%s: %s (0x%04X): no reply within %d ms", c->name,
                                 dlpc900_cmd_name(m->cmd), m->cmd, c->timeout_ms);
        if (n < 0)
            return sci_error_prefix(err, "%s: %s (0x%04X): ", c->name, dlpc900_cmd_name(m->cmd), m->cmd);
        c->traffic.reports_in++;
        int rc = dlpc900_reply_parse(rep, (size_t)n, r, err);
        if (rc < 0)
            return sci_error_prefix(err, "%s: %s (0x%04X): ", c->name, dlpc900_cmd_name(m->cmd), m->cmd);
        if (r->seq == seq)
            return 0;
    }
    return sci_error_set(err, SCI_EPROTO, "%s: %s (0x%04X): replies carry other sequence numbers than %u", c->name,
                         dlpc900_cmd_name(m->cmd), m->cmd, seq);
}

/* After a NACK: fetch code and text and build the one message the user sees. */
static int device_refused(dlpc900_ctl *c, const dlpc900_msg *m, sci_error *err)
{
    /* A refused read of the error registers would recurse: report it as is. */
    if ((m->flags & DLPC900_FLAG_READ) && (m->cmd == DLPC900_CMD_ERROR_CODE || m->cmd == DLPC900_CMD_ERROR_TEXT))
        return sci_error_set(err, SCI_EDEVICE, "%s: %s (0x%04X) refused", c->name, dlpc900_cmd_name(m->cmd), m->cmd);
    int code = -1;
    char text[64] = "";
    sci_error e2 = {0};
    if (dlpc900_ctl_last_error(c, &code, text, sizeof text, &e2) < 0)
        return sci_error_set(err, SCI_EDEVICE, "%s: %s (0x%04X) refused; reading the error code failed too: %s",
                             c->name, dlpc900_cmd_name(m->cmd), m->cmd, e2.msg);
    return sci_error_set(err, SCI_EDEVICE, "%s: %s (0x%04X) refused: error %d (%s)%s%s", c->name,
                         dlpc900_cmd_name(m->cmd), m->cmd, code, dlpc900_errcode_text(code), text[0] ? ": " : "", text);
}

int dlpc900_ctl_write(dlpc900_ctl *c, const dlpc900_msg *m, sci_error *err)
{
    uint8_t seq;
    int rc = send_msg(c, m, &seq, err);
    if (rc < 0 || !(m->flags & (DLPC900_FLAG_REPLY | DLPC900_FLAG_READ)))
        return rc;
    dlpc900_reply r;
    if ((rc = recv_reply(c, m, seq, &r, err)) < 0)
        return rc;
    if (r.flags & DLPC900_FLAG_ERROR)
        return device_refused(c, m, err);
    return 0;
}

int dlpc900_ctl_read(dlpc900_ctl *c, uint16_t cmd, uint8_t *data, size_t cap, size_t min_len, size_t *len,
                     sci_error *err)
{
    dlpc900_msg m;
    dlpc900_cmd_read(&m, cmd);
    uint8_t seq;
    int rc = send_msg(c, &m, &seq, err);
    if (rc < 0)
        return rc;
    dlpc900_reply r;
    if ((rc = recv_reply(c, &m, seq, &r, err)) < 0)
        return rc;
    if (r.flags & DLPC900_FLAG_ERROR)
        return device_refused(c, &m, err);
    if (r.len < min_len)
        return sci_error_set(err, SCI_EPROTO, "%s: %s (0x%04X): short reply, %u data bytes where %zu are needed",
                             c->name, dlpc900_cmd_name(cmd), cmd, r.len, min_len);
    memcpy(data, r.data, r.len < cap ? r.len : cap);
    if (len)
        *len = r.len;
    return 0;
}

int dlpc900_ctl_last_error(dlpc900_ctl *c, int *code, char *text, size_t n, sci_error *err)
{
    uint8_t d[DLPC900_REPLY_DATA_MAX + 1];
    size_t len;
    int rc = dlpc900_ctl_read(c, DLPC900_CMD_ERROR_CODE, d, sizeof d, 1, NULL, err);
    if (rc < 0)
        return rc;
    *code = d[0];
    if (n)
        text[0] = 0;
    if (*code == 0 || n == 0)
        return 0;
    if ((rc = dlpc900_ctl_read(c, DLPC900_CMD_ERROR_TEXT, d, DLPC900_REPLY_DATA_MAX, 0, &len, err)) < 0)
        return rc;
    /* The text is NUL-terminated and may carry a stale tail (mcSIM): stop at the first NUL. */
    d[len < DLPC900_REPLY_DATA_MAX ? len : DLPC900_REPLY_DATA_MAX] = 0;
    snprintf(text, n, "%s", (const char *)d);
    return 0;
}

/* Read the error code after steps whose commands carry no reply; a set code fails the step. */
static int check_error_code(dlpc900_ctl *c, const char *step, sci_error *err)
{
    int code;
    char text[64];
    int rc = dlpc900_ctl_last_error(c, &code, text, sizeof text, err);
    if (rc < 0)
        return rc;
    if (code)
        return sci_error_set(err, SCI_EDEVICE, "%s: %s failed: error %d (%s)%s%s", c->name, step, code,
                             dlpc900_errcode_text(code), text[0] ? ": " : "", text);
    return 0;
}

/* Read and drop an error code left by earlier commands, so the checks below see only this sequence's errors.
 * (Whether the firmware clears the code on read is UNCONFIRMED; the emulator does.) */
static int clear_error_code(dlpc900_ctl *c, sci_error *err)
{
    uint8_t code;
    return dlpc900_ctl_read(c, DLPC900_CMD_ERROR_CODE, &code, 1, 1, NULL, err);
}

int dlpc900_ctl_status(dlpc900_ctl *c, dlpc900_status *st, sci_error *err)
{
    memset(st, 0, sizeof *st);
    int rc;
    if ((rc = dlpc900_ctl_read(c, DLPC900_CMD_HW_STATUS, &st->hw, 1, 1, NULL, err)) < 0 ||
        (rc = dlpc900_ctl_read(c, DLPC900_CMD_SYS_STATUS, &st->sys, 1, 1, NULL, err)) < 0 ||
        (rc = dlpc900_ctl_read(c, DLPC900_CMD_MAIN_STATUS, &st->main, 1, 1, NULL, err)) < 0 ||
        (rc = dlpc900_ctl_last_error(c, &st->error_code, st->error_text, sizeof st->error_text, err)) < 0)
        return rc;
    st->running = (st->main & DLPC900_MAIN_RUNNING) != 0;
    return 0;
}

const char *dlpc900_dmd_type_name(int type)
{
    static const char *const names[] = {[1] = "DLP6500", [2] = "DLP9000", [3] = "DLP670S", [4] = "DLP500YX",
                                        [5] = "DLP5500"};
    return type >= 1 && type <= 5 ? names[type] : "unknown DMD";
}

int dlpc900_ctl_identify(dlpc900_ctl *c, dlpc900_identity *id, sci_error *err)
{
    uint8_t d[DLPC900_REPLY_DATA_MAX + 1] = {0};
    size_t len;
    memset(id, 0, sizeof *id);
    int rc = dlpc900_ctl_read(c, DLPC900_CMD_VERSION, d, sizeof d, 16, NULL, err);
    if (rc < 0)
        return rc;
    id->app_version = dlpc900_get32(d);
    id->api_version = dlpc900_get32(d + 4);
    memset(d, 0, sizeof d);
    if ((rc = dlpc900_ctl_read(c, DLPC900_CMD_FW_TYPE, d, DLPC900_REPLY_DATA_MAX, 1, &len, err)) < 0)
        return rc;
    id->dmd_type = d[0];
    snprintf(id->fw_tag, sizeof id->fw_tag, "%s", (const char *)d + 1);
    return 0;
}

/* Insert context after the leading "<name>: " of a message: "<name>: <context>: <rest>". */
__attribute__((format(printf, 3, 4))) static void add_context(dlpc900_ctl *c, sci_error *err, const char *fmt, ...)
{
    if (!err)
        return;
    char ctx[128], rest[SCI_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(ctx, sizeof ctx, fmt, ap);
    va_end(ap);
    size_t nl = strlen(c->name);
    const char *tail = err->msg;
    if (strncmp(tail, c->name, nl) == 0 && tail[nl] == ':' && tail[nl + 1] == ' ')
        tail += nl + 2;
    snprintf(rest, sizeof rest, "%s", tail);
    snprintf(err->msg, sizeof err->msg, "%s: %s: %s", c->name, ctx, rest);
}

static int simple_write(dlpc900_ctl *c, dlpc900_msg *m, sci_error *err) { return dlpc900_ctl_write(c, m, err); }

int dlpc900_ctl_stop(dlpc900_ctl *c, sci_error *err)
{
    dlpc900_msg m;
    dlpc900_cmd_pattern_start(&m, DLPC900_STOP);
    return simple_write(c, &m, err);
}

/* Best effort after a failure: the caller's error stays the one reported. */
static void stop_quietly(dlpc900_ctl *c)
{
    sci_error ignored = {0};
    dlpc900_ctl_stop(c, &ignored);
}

/* A failed programming step: leave the sequencer stopped (unless the device is gone) and pass rc on. */
static int failed_stopped(dlpc900_ctl *c, int rc)
{
    if (rc != -ENODEV)
        stop_quietly(c);
    return rc;
}

static int check_sequence(dlpc900_ctl *c, const dlpc900_sequence *s, sci_error *err)
{
    if (s->count < 1 || s->count > 400)
        return sci_error_set(err, -EINVAL, "%s: %d masks, the DLPC900 holds 1…400 1-bit patterns", c->name, s->count);
    if (!s->exposure_us || !s->dark_us)
        return sci_error_set(err, -EINVAL, "%s: exposure and dark time arrays are required", c->name);
    for (int j = 0; j < s->count; j++)
        if (s->exposure_us[j] >= 1u << 24 || s->dark_us[j] >= 1u << 24)
            return sci_error_set(err, -EINVAL, "%s: pattern %d: exposure %u µs or dark time %u µs exceeds 24 bits",
                                 c->name, j, s->exposure_us[j], s->dark_us[j]);
    return 0;
}

static int define_lut(dlpc900_ctl *c, const dlpc900_sequence *s, sci_error *err)
{
    dlpc900_msg m;
    int rc;
    if (s->external_trigger) {
        dlpc900_cmd_trig_in1(&m, s->trig_in1_delay_us, s->trig_in1_falling);
        if ((rc = simple_write(c, &m, err)) < 0)
            return rc;
    }
    for (int j = 0; j < s->count; j++) {
        dlpc900_lut_entry e = {
            .index = (uint16_t)j,
            .exposure_us = s->exposure_us[j],
            .clear_after = 1,
            .bit_depth = 1,
            .led = 7,
            .wait_trigger = s->external_trigger ? 1 : 0,
            .dark_us = s->dark_us[j],
            .trig_out2_off = j != 0, /* TRIG_OUT_2 marks the sequence start only (DLPU018 polarity) */
            .image_index = (uint16_t)(j / DLPC900_MASKS_PER_IMAGE),
            .bit_position = (uint8_t)(j % DLPC900_MASKS_PER_IMAGE),
        };
        dlpc900_cmd_lut_define(&m, &e);
        if ((rc = simple_write(c, &m, err)) < 0) {
            add_context(c, err, "pattern %d", j);
            return rc;
        }
    }
    dlpc900_cmd_lut_config(&m, (uint16_t)s->count, s->patterns);
    return simple_write(c, &m, err);
}

static int enter_otf(dlpc900_ctl *c, sci_error *err)
{
    dlpc900_msg m;
    int rc;
    /* Stop, mode, stop again: a mode change while running locks the controller up (mcSIM). */
    dlpc900_cmd_pattern_start(&m, DLPC900_STOP);
    if ((rc = simple_write(c, &m, err)) < 0)
        return rc;
    dlpc900_cmd_display_mode(&m, DLPC900_MODE_OTF);
    if ((rc = simple_write(c, &m, err)) < 0)
        return rc;
    dlpc900_cmd_pattern_start(&m, DLPC900_STOP);
    if ((rc = simple_write(c, &m, err)) < 0)
        return rc;
    uint8_t hw;
    if ((rc = dlpc900_ctl_read(c, DLPC900_CMD_HW_STATUS, &hw, 1, 1, NULL, err)) < 0)
        return rc;
    if (hw & DLPC900_HW_ERROR_BITS || !(hw & DLPC900_HW_INIT_OK))
        return sci_error_set(err, SCI_EDEVICE, "%s: hardware status 0x%02X after the mode change (bit1 incompatible "
                             "DMD/firmware, bit2 reset controller, bit3 forced swap, bit6 sequencer abort, bit7 "
                             "sequencer error, bit0 must be set)", c->name, hw);
    return 0;
}

static int upload_image(dlpc900_ctl *c, int index, const uint32_t *px, int w, int h, sci_error *err)
{
    uint8_t *file;
    size_t len;
    int rc = dlpc900_image_encode(px, w, h, &file, &len, NULL, err);
    if (rc < 0)
        return rc;
    dlpc900_msg m;
    dlpc900_cmd_image_init(&m, (uint16_t)index, (uint32_t)len);
    if ((rc = simple_write(c, &m, err)) < 0)
        goto out_free;
    /* ceil(len / 504) chunks: never an empty trailing chunk (pycrafter's bug when len % 504 == 0). */
    for (size_t off = 0; off < len; off += DLPC900_CHUNK_MAX) {
        size_t n = len - off < DLPC900_CHUNK_MAX ? len - off : DLPC900_CHUNK_MAX;
        dlpc900_cmd_image_data(&m, file + off, n);
        if ((rc = simple_write(c, &m, err)) < 0) {
            add_context(c, err, "image %d, byte %zu of %zu", index, off, len);
            goto out_free;
        }
    }
    char step[64];
    snprintf(step, sizeof step, "image %d upload (%zu bytes)", index, len);
    rc = check_error_code(c, step, err);
out_free:
    free(file);
    return rc;
}

int dlpc900_ctl_program(dlpc900_ctl *c, const uint32_t *const *images, int w, int h, const dlpc900_sequence *s,
                        sci_error *err)
{
    int rc = check_sequence(c, s, err);
    if (rc < 0)
        return rc;
    int nimg = (s->count + DLPC900_MASKS_PER_IMAGE - 1) / DLPC900_MASKS_PER_IMAGE;
    if ((rc = enter_otf(c, err)) < 0 || (rc = clear_error_code(c, err)) < 0 || (rc = define_lut(c, s, err)) < 0)
        goto fail;
    for (int i = nimg - 1; i >= 0; i--) /* reverse index order (DLPU018) */
        if ((rc = upload_image(c, i, images[i], w, h, err)) < 0)
            goto fail;
    dlpc900_msg m;
    dlpc900_cmd_lut_config(&m, (uint16_t)s->count, s->patterns); /* again after the images (mcSIM) */
    if ((rc = simple_write(c, &m, err)) < 0 || (rc = check_error_code(c, "pattern programming", err)) < 0)
        goto fail;
    return 0;
fail:
    return failed_stopped(c, rc);
}

int dlpc900_ctl_program_lut(dlpc900_ctl *c, const dlpc900_sequence *s, sci_error *err)
{
    int rc = check_sequence(c, s, err);
    if (rc < 0)
        return rc;
    dlpc900_msg m;
    dlpc900_cmd_pattern_start(&m, DLPC900_STOP);
    if ((rc = simple_write(c, &m, err)) < 0 || (rc = clear_error_code(c, err)) < 0 || (rc = define_lut(c, s, err)) < 0 ||
        (rc = check_error_code(c, "LUT programming", err)) < 0)
        return failed_stopped(c, rc);
    return 0;
}

int dlpc900_ctl_start(dlpc900_ctl *c, sci_error *err)
{
    dlpc900_msg m;
    int rc;
    uint8_t st;
    dlpc900_cmd_pattern_start(&m, DLPC900_STOP);
    if ((rc = simple_write(c, &m, err)) < 0)
        goto fail;
    if ((rc = clear_error_code(c, err)) < 0)
        goto fail;
    dlpc900_cmd_pattern_start(&m, DLPC900_START);
    if ((rc = simple_write(c, &m, err)) < 0 ||
        (rc = dlpc900_ctl_read(c, DLPC900_CMD_MAIN_STATUS, &st, 1, 1, NULL, err)) < 0)
        goto fail;
    if (!(st & DLPC900_MAIN_RUNNING)) {
        int code = 0;
        char text[64] = "";
        sci_error e2 = {0};
        dlpc900_ctl_last_error(c, &code, text, sizeof text, &e2);
        rc = sci_error_set(err, SCI_EDEVICE, "%s: sequence did not start (main status 0x%02X): error %d (%s)%s%s",
                           c->name, st, code, dlpc900_errcode_text(code), text[0] ? ": " : "", text);
        goto fail;
    }
    if ((rc = check_error_code(c, "start", err)) < 0)
        goto fail;
    return 0;
fail:
    return failed_stopped(c, rc);
}
