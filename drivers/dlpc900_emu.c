#include "drivers/dlpc900_emu.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/dlpc900_image.h"

#define EMU_LUT_MAX 400        /* LUT entries and 1-bit patterns of the DLP6500 (DLPS037) */
#define EMU_IMAGES_MAX 18      /* image index 0 … 17 (DLPU018 range) */
#define EMU_REPLIES_MAX 16
#define EMU_BLOCKS 15          /* DLP6500 reset blocks */
#define EMU_TRIG_OUT_MIN (-20)
#define EMU_TRIG_OUT_MAX 20000
#define EMU_MIN_EXPOSURE_8BIT 4046
#define EMU_ERR_TEXT_MAX 128

/* Minimum 1-bit exposure in µs by number of active blocks 1…15 (DLP6500, DLPU018 rev I). */
static const uint16_t min_exposure_1bit[EMU_BLOCKS + 1] = {0, 24, 45, 45, 45, 48, 54, 60, 66, 72, 78, 84, 90, 96, 101, 105};

struct dlpc900_emu {
    char serial[64];
    int w, h, dmd_type;
    int plugged;
    long unplug_after; /* reports until unplug; < 0 = never */
    dlpc900_assembler as;

    /* fault injection */
    uint16_t fault_cmd;
    int fault_nth, fault, fault_code;

    /* pending reply reports */
    uint8_t reply[EMU_REPLIES_MAX][DLPC900_REPORT_SIZE];
    int reply_len[EMU_REPLIES_MAX];
    int reply_head, reply_count;

    /* device state */
    int mode, running;
    dlpc900_lut_entry lut[EMU_LUT_MAX];
    uint8_t lut_defined[EMU_LUT_MAX];
    int lut_nl;
    uint32_t lut_np;
    int lut_configured;
    uint32_t *image[EMU_IMAGES_MAX];
    int load_index;    /* image being loaded, -1 = none */
    uint32_t load_total, load_have;
    uint8_t *load_buf;
    int block_start, block_count;
    dlpc900_emu_triggers trig;
    int power, idle, led;

    int err_code;
    char err_text[EMU_ERR_TEXT_MAX];
    long messages, refused;
    int warnings;
};

static void emu_reset_state(dlpc900_emu *e)
{
    for (int i = 0; i < EMU_IMAGES_MAX; i++) {
        free(e->image[i]);
        e->image[i] = NULL;
    }
    free(e->load_buf);
    e->load_buf = NULL;
    e->load_index = -1;
    e->load_total = e->load_have = 0;
    memset(e->lut, 0, sizeof e->lut);
    memset(e->lut_defined, 0, sizeof e->lut_defined);
    e->lut_nl = 0;
    e->lut_np = 0;
    e->lut_configured = 0;
    e->mode = DLPC900_MODE_VIDEO;
    e->running = 0;
    e->block_start = 0;
    e->block_count = EMU_BLOCKS;
    e->trig = (dlpc900_emu_triggers){.in1_delay_us = 105};
    e->power = e->idle = 0;
    e->led = 0x08;
    e->err_code = 0;
    e->err_text[0] = 0;
    e->reply_head = e->reply_count = 0;
    dlpc900_assembler_reset(&e->as);
}

int dlpc900_emu_new(dlpc900_emu **out, const dlpc900_emu_config *cfg, sci_error *err)
{
    dlpc900_emu *e = calloc(1, sizeof *e);
    if (!e)
        return sci_error_set(err, -ENOMEM, "DLPC900 emulator: out of memory");
    snprintf(e->serial, sizeof e->serial, "%s", cfg && cfg->serial ? cfg->serial : "EMU0001");
    e->w = cfg && cfg->width > 0 ? cfg->width : 1920;
    e->h = cfg && cfg->height > 0 ? cfg->height : 1080;
    e->dmd_type = cfg && cfg->dmd_type > 0 ? cfg->dmd_type : 1;
    if (e->w > DLPC900_IMAGE_DIM_MAX || e->h > DLPC900_IMAGE_DIM_MAX) {
        free(e);
        return sci_error_set(err, -EINVAL, "DLPC900 emulator: DMD size %d×%d out of range", cfg->width, cfg->height);
    }
    e->plugged = 1;
    e->unplug_after = -1;
    emu_reset_state(e);
    *out = e;
    return 0;
}

void dlpc900_emu_free(dlpc900_emu *e)
{
    if (!e)
        return;
    emu_reset_state(e);
    free(e);
}

/* ---- replies and errors ---- */

static void push_reply(dlpc900_emu *e, uint8_t flags, uint8_t seq, const uint8_t *data, size_t len, int short_reply)
{
    if (e->reply_count == EMU_REPLIES_MAX) { /* host never reads: the oldest is overwritten, as on hardware */
        e->reply_head = (e->reply_head + 1) % EMU_REPLIES_MAX;
        e->reply_count--;
    }
    int slot = (e->reply_head + e->reply_count) % EMU_REPLIES_MAX;
    dlpc900_reply_build(e->reply[slot], flags, seq, data, len);
    e->reply_len[slot] = short_reply ? 3 : DLPC900_REPORT_SIZE;
    e->reply_count++;
}

/* Record a refusal; returns the code so handlers can `return refuse(...)`. */
__attribute__((format(printf, 3, 4))) static int refuse(dlpc900_emu *e, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(e->err_text, sizeof e->err_text, fmt, ap);
    va_end(ap);
    e->err_code = code;
    e->refused++;
    return code;
}

/* ---- command handlers: return 0 or a DLPC900 error code; reads fill data/dlen ---- */

static int need_len(dlpc900_emu *e, const dlpc900_msg *m, int len)
{
    if (m->len != len)
        return refuse(e, DLPC900_ERR_INVALID_PARAM, "%s: payload of %u bytes, expected %d", dlpc900_cmd_name(m->cmd),
                      m->len, len);
    return 0;
}

static int need_stopped_otf(dlpc900_emu *e, const dlpc900_msg *m)
{
    if (e->mode != DLPC900_MODE_OTF && e->mode != DLPC900_MODE_PRESTORED)
        return refuse(e, DLPC900_ERR_NOT_ALLOWED, "%s needs pattern mode (display mode is %d)", dlpc900_cmd_name(m->cmd),
                      e->mode);
    if (e->running)
        return refuse(e, DLPC900_ERR_NOT_ALLOWED, "%s while the sequence runs: stop first", dlpc900_cmd_name(m->cmd));
    return 0;
}

static int min_exposure_us(const dlpc900_emu *e, int depth)
{
    if (depth == 8)
        return EMU_MIN_EXPOSURE_8BIT;
    return min_exposure_1bit[e->block_count];
}

static int do_lut_define(dlpc900_emu *e, const dlpc900_msg *m)
{
    int rc;
    if ((rc = need_len(e, m, 12)) || (rc = need_stopped_otf(e, m)))
        return rc;
    dlpc900_lut_entry le;
    dlpc900_lut_entry_unpack(m->payload, &le);
    if (le.index >= EMU_LUT_MAX)
        return refuse(e, DLPC900_ERR_PATTERN_RANGE, "LUT entry %u out of range 0…%d", le.index, EMU_LUT_MAX - 1);
    if (le.bit_depth > 8)
        return refuse(e, DLPC900_ERR_INVALID_PARAM, "LUT entry %u: extended bit depth %u not emulated", le.index,
                      le.bit_depth);
    if (le.bit_depth == 1 && le.bit_position > 23)
        return refuse(e, DLPC900_ERR_BIT_RANGE, "LUT entry %u: bit position %u out of range 0…23", le.index,
                      le.bit_position);
    if (le.bit_depth > 1 && le.bit_position + le.bit_depth > 24)
        return refuse(e, DLPC900_ERR_BIT_RANGE, "LUT entry %u: %u bits from position %u pass bit 23", le.index,
                      le.bit_depth, le.bit_position);
    if (le.image_index >= EMU_IMAGES_MAX)
        return refuse(e, DLPC900_ERR_IMAGE_ADDR, "LUT entry %u: image index %u out of range 0…%d", le.index,
                      le.image_index, EMU_IMAGES_MAX - 1);
    int minexp = min_exposure_us(e, le.bit_depth);
    if ((int)le.exposure_us < minexp)
        /* Kept under the 59 characters one reply report carries. */
        return refuse(e, DLPC900_ERR_EXPOSURE_RANGE, "entry %u: exposure %u us < min %d us (%u-bit, %d blocks)",
                      le.index, le.exposure_us, minexp, le.bit_depth, e->block_count);
    e->lut[le.index] = le;
    e->lut_defined[le.index] = 1;
    e->lut_configured = 0; /* a definition takes effect at the next LUT configuration (DLPU018) */
    return 0;
}

static int do_lut_config(dlpc900_emu *e, const dlpc900_msg *m, uint8_t *data, size_t *dlen)
{
    if (m->flags & DLPC900_FLAG_READ) {
        dlpc900_put16(data, (uint32_t)e->lut_nl);
        dlpc900_put32(data + 2, e->lut_np);
        *dlen = 6;
        return 0;
    }
    int rc;
    if ((rc = need_len(e, m, 6)) || (rc = need_stopped_otf(e, m)))
        return rc;
    int nl = dlpc900_get16(m->payload) & 0x7FF;
    if (nl < 1 || nl > EMU_LUT_MAX)
        return refuse(e, DLPC900_ERR_PATTERN_RANGE, "LUT configuration: %d entries, allowed 1…%d", nl, EMU_LUT_MAX);
    e->lut_nl = nl;
    e->lut_np = dlpc900_get32(m->payload + 2);
    e->lut_configured = 1;
    return 0;
}

static int do_image_init(dlpc900_emu *e, const dlpc900_msg *m)
{
    int rc;
    if ((rc = need_len(e, m, 6)) || (rc = need_stopped_otf(e, m)))
        return rc;
    int index = dlpc900_get16(m->payload) & 0x1F;
    uint32_t total = dlpc900_get32(m->payload + 2);
    if (index >= EMU_IMAGES_MAX)
        return refuse(e, DLPC900_ERR_IMAGE_ADDR, "image load init: index %d out of range 0…%d", index,
                      EMU_IMAGES_MAX - 1);
    /* Worst case the device would store: header + uncompressed rows, or ERLE's 4 bytes per pixel. */
    size_t cap = DLPC900_IMAGE_HEADER_SIZE + (size_t)e->w * e->h * 4 + 16;
    if (total <= DLPC900_IMAGE_HEADER_SIZE || total > cap)
        return refuse(e, DLPC900_ERR_OUT_OF_RESOURCE, "image load init: size %u bytes outside %d…%zu", total,
                      DLPC900_IMAGE_HEADER_SIZE + 1, cap);
    if (e->load_index >= 0)
        e->warnings++; /* previous load abandoned */
    free(e->load_buf);
    e->load_buf = malloc(total);
    if (!e->load_buf) {
        e->load_index = -1;
        return refuse(e, DLPC900_ERR_OUT_OF_RESOURCE, "image load init: cannot hold %u bytes", total);
    }
    e->load_index = index;
    e->load_total = total;
    e->load_have = 0;
    return 0;
}

static void load_abort(dlpc900_emu *e)
{
    free(e->load_buf);
    e->load_buf = NULL;
    e->load_index = -1;
}

static int do_image_data(dlpc900_emu *e, const dlpc900_msg *m)
{
    if (m->len < 2)
        return refuse(e, DLPC900_ERR_INVALID_PARAM, "image load data: payload of %u bytes has no count", m->len);
    if (e->load_index < 0)
        return refuse(e, DLPC900_ERR_NOT_ALLOWED, "image load data without image load init");
    uint32_t n = dlpc900_get16(m->payload) & 0x3FF;
    if (n > DLPC900_CHUNK_MAX || n != (uint32_t)m->len - 2u) {
        load_abort(e);
        return refuse(e, DLPC900_ERR_INVALID_PARAM, "image load data: count %u with %u data bytes (max %d)", n,
                      m->len - 2u, DLPC900_CHUNK_MAX);
    }
    if (n > e->load_total - e->load_have) {
        load_abort(e);
        return refuse(e, DLPC900_ERR_INVALID_PARAM, "image load data: %u bytes more than the %u declared", n,
                      e->load_total);
    }
    memcpy(e->load_buf + e->load_have, m->payload + 2, n);
    e->load_have += n;
    if (e->load_have < e->load_total)
        return 0;
    /* Complete: decode now, as the controller does when the last chunk lands. */
    int index = e->load_index;
    uint32_t *px = NULL;
    dlpc900_image_info info;
    sci_error derr = {0};
    int rc = dlpc900_image_decode(e->load_buf, e->load_total, &px, &info, &derr);
    load_abort(e);
    if (rc < 0) {
        int code = strstr(derr.msg, "compression") ? DLPC900_ERR_BMP_COMPRESSION : DLPC900_ERR_INVALID_PARAM;
        return refuse(e, code, "image %d: %s", index, derr.msg);
    }
    if (info.header.width != e->w || info.header.height != e->h) {
        free(px);
        return refuse(e, DLPC900_ERR_INVALID_PARAM, "image %d is %u×%u, the DMD is %d×%d", index, info.header.width,
                      info.header.height, e->w, e->h);
    }
    e->warnings += info.warnings;
    free(e->image[index]);
    e->image[index] = px;
    return 0;
}

static int do_start(dlpc900_emu *e, const dlpc900_msg *m)
{
    int rc;
    if ((rc = need_len(e, m, 1)))
        return rc;
    int what = m->payload[0];
    if (what == DLPC900_STOP) {
        e->running = 0;
        return 0;
    }
    if (what == DLPC900_PAUSE) {
        if (e->running)
            e->running = 2;
        return 0;
    }
    if (what != DLPC900_START)
        return refuse(e, DLPC900_ERR_INVALID_PARAM, "pattern start/stop: value %d is not 0, 1 or 2", what);
    if (e->mode != DLPC900_MODE_OTF && e->mode != DLPC900_MODE_PRESTORED)
        return refuse(e, DLPC900_ERR_NOT_ALLOWED, "start needs pattern mode (display mode is %d)", e->mode);
    if (!e->lut_configured)
        return refuse(e, DLPC900_ERR_PATTERN_DEF, "start without a LUT configuration after the last LUT definition");
    for (int i = 0; i < e->lut_nl; i++) {
        if (!e->lut_defined[i])
            return refuse(e, DLPC900_ERR_PATTERN_DEF, "start: LUT entry %d of %d is not defined", i, e->lut_nl);
        if (e->mode == DLPC900_MODE_OTF && !e->image[e->lut[i].image_index])
            return refuse(e, DLPC900_ERR_NOT_PRESENT, "start: LUT entry %d shows image %u, which is not loaded", i,
                          e->lut[i].image_index);
    }
    e->running = 1;
    return 0;
}

static int do_trig_out(dlpc900_emu *e, const dlpc900_msg *m, uint8_t *data, size_t *dlen)
{
    int k = m->cmd == DLPC900_CMD_TRIG_OUT2;
    if (m->flags & DLPC900_FLAG_READ) {
        data[0] = (uint8_t)e->trig.out_invert[k];
        dlpc900_put16(data + 1, (uint16_t)e->trig.out_rising_us[k]);
        dlpc900_put16(data + 3, (uint16_t)e->trig.out_falling_us[k]);
        *dlen = 5;
        return 0;
    }
    int rc;
    if ((rc = need_len(e, m, 5)))
        return rc;
    int16_t r = (int16_t)dlpc900_get16(m->payload + 1), f = (int16_t)dlpc900_get16(m->payload + 3);
    if (r < EMU_TRIG_OUT_MIN || r > EMU_TRIG_OUT_MAX || f < EMU_TRIG_OUT_MIN || f > EMU_TRIG_OUT_MAX)
        return refuse(e, DLPC900_ERR_DELAY_RANGE, "TRIG_OUT_%d: delays %d/%d µs outside %d…%d", k + 1, r, f,
                      EMU_TRIG_OUT_MIN, EMU_TRIG_OUT_MAX);
    e->trig.out_invert[k] = m->payload[0] & 1;
    e->trig.out_rising_us[k] = r;
    e->trig.out_falling_us[k] = f;
    return 0;
}

static int do_trig_in1(dlpc900_emu *e, const dlpc900_msg *m, uint8_t *data, size_t *dlen)
{
    if (m->flags & DLPC900_FLAG_READ) {
        dlpc900_put16(data, e->trig.in1_delay_us);
        data[2] = (uint8_t)e->trig.in1_falling;
        *dlen = 3;
        return 0;
    }
    int rc;
    if ((rc = need_len(e, m, 3)))
        return rc;
    uint16_t d = dlpc900_get16(m->payload);
    int minimum = min_exposure_1bit[e->block_count];
    if (d < minimum)
        return refuse(e, DLPC900_ERR_DELAY_RANGE, "TRIG_IN_1: delay %u µs below the %d µs block-load time", d, minimum);
    e->trig.in1_delay_us = d;
    e->trig.in1_falling = m->payload[2] & 1;
    return 0;
}

static int do_simple_rw(dlpc900_emu *e, const dlpc900_msg *m, int *field, int mask, uint8_t *data, size_t *dlen)
{
    if (m->flags & DLPC900_FLAG_READ) {
        data[0] = (uint8_t)*field;
        *dlen = 1;
        return 0;
    }
    int rc;
    if ((rc = need_len(e, m, 1)))
        return rc;
    *field = m->payload[0] & mask;
    return 0;
}

static int exec(dlpc900_emu *e, const dlpc900_msg *m, uint8_t *data, size_t *dlen)
{
    int rd = (m->flags & DLPC900_FLAG_READ) != 0;
    *dlen = 0;
    if (m->flags & DLPC900_FLAG_DEST_MASK)
        return refuse(e, DLPC900_ERR_INVALID_CMD, "destination %d is not the projector controller (0)",
                      m->flags & DLPC900_FLAG_DEST_MASK);
    switch (m->cmd) {
    case DLPC900_CMD_ERROR_CODE:
    case DLPC900_CMD_ERROR_TEXT:
    case DLPC900_CMD_HW_STATUS:
    case DLPC900_CMD_SYS_STATUS:
    case DLPC900_CMD_MAIN_STATUS:
    case DLPC900_CMD_VERSION:
    case DLPC900_CMD_FW_TYPE:
    case DLPC900_CMD_MIN_EXPOSURE:
        if (!rd) /* the mcSIM pitfall: 0x0100 as a write is refused */
            return refuse(e, DLPC900_ERR_INVALID_CMD, "invalid command number 0x%X (read-only, sent as a write)", m->cmd);
        break;
    case DLPC900_CMD_LUT_DEFINE:
    case DLPC900_CMD_PATTERN_START:
    case DLPC900_CMD_IMAGE_INIT:
    case DLPC900_CMD_IMAGE_DATA:
        if (rd)
            return refuse(e, DLPC900_ERR_INVALID_CMD, "invalid command number 0x%X (write-only, sent as a read)", m->cmd);
        break;
    default:
        break;
    }
    switch (m->cmd) {
    case DLPC900_CMD_ERROR_CODE:
        data[0] = (uint8_t)e->err_code;
        e->err_code = 0; /* emulator choice: reading the code clears it; the text stays */
        *dlen = 1;
        return 0;
    case DLPC900_CMD_ERROR_TEXT: {
        size_t n = strnlen(e->err_text, DLPC900_REPLY_DATA_MAX - 1);
        memcpy(data, e->err_text, n);
        data[n] = 0;
        *dlen = n + 1;
        return 0;
    }
    case DLPC900_CMD_HW_STATUS: data[0] = DLPC900_HW_INIT_OK; *dlen = 1; return 0;
    case DLPC900_CMD_SYS_STATUS: data[0] = 0x01; *dlen = 1; return 0;
    case DLPC900_CMD_MAIN_STATUS:
        data[0] = (uint8_t)((e->running == 1 ? DLPC900_MAIN_RUNNING : 0) | (e->idle ? DLPC900_MAIN_PARKED : 0));
        *dlen = 1;
        return 0;
    case DLPC900_CMD_VERSION:
        dlpc900_put32(data, 6u << 24 | 0u << 16 | 0);     /* application 6.0.0 */
        dlpc900_put32(data + 4, 1u << 24);                /* API */
        dlpc900_put32(data + 8, 1u << 24);                /* software config */
        dlpc900_put32(data + 12, 1u << 24);               /* sequence config */
        *dlen = 16;
        return 0;
    case DLPC900_CMD_FW_TYPE:
        memset(data, 0, 0x21);
        data[0] = (uint8_t)e->dmd_type;
        memcpy(data + 1, "scicap-emulator", 15);
        *dlen = 0x21;
        return 0;
    case DLPC900_CMD_MIN_EXPOSURE:
        memset(data, 0, 32);
        dlpc900_put32(data, min_exposure_1bit[e->block_count]); /* layout UNCONFIRMED: 1-bit minimum first */
        *dlen = 32;
        return 0;
    case DLPC900_CMD_DISPLAY_MODE:
        if (rd) {
            data[0] = (uint8_t)e->mode;
            *dlen = 1;
            return 0;
        } else {
            int rc = need_len(e, m, 1);
            if (rc)
                return rc;
            if (e->running)
                return refuse(e, DLPC900_ERR_NOT_ALLOWED, "display mode change while the sequence runs: stop first");
            e->mode = m->payload[0] & 3;
            return 0;
        }
    case DLPC900_CMD_PATTERN_START: return do_start(e, m);
    case DLPC900_CMD_LUT_DEFINE: return do_lut_define(e, m);
    case DLPC900_CMD_LUT_CONFIG: return do_lut_config(e, m, data, dlen);
    case DLPC900_CMD_IMAGE_INIT: return do_image_init(e, m);
    case DLPC900_CMD_IMAGE_DATA: return do_image_data(e, m);
    case DLPC900_CMD_TRIG_OUT1:
    case DLPC900_CMD_TRIG_OUT2: return do_trig_out(e, m, data, dlen);
    case DLPC900_CMD_TRIG_IN1: return do_trig_in1(e, m, data, dlen);
    case DLPC900_CMD_TRIG_IN2: return do_simple_rw(e, m, &e->trig.in2_inverted, 1, data, dlen);
    case DLPC900_CMD_POWER: return do_simple_rw(e, m, &e->power, 3, data, dlen);
    case DLPC900_CMD_DMD_IDLE: return do_simple_rw(e, m, &e->idle, 1, data, dlen);
    case DLPC900_CMD_LED_ENABLE: return do_simple_rw(e, m, &e->led, 0x0F, data, dlen);
    case DLPC900_CMD_BLOCK_LOAD:
        if (rd) {
            data[0] = (uint8_t)e->block_start;
            data[1] = (uint8_t)e->block_count;
            *dlen = 2;
            return 0;
        } else {
            int rc = need_len(e, m, 2);
            if (rc)
                return rc;
            int s = m->payload[0], c = m->payload[1];
            if (c < 1 || s + c > EMU_BLOCKS)
                return refuse(e, DLPC900_ERR_INVALID_PARAM, "DMD block load: blocks %d+%d outside 0…%d", s, c,
                              EMU_BLOCKS - 1);
            e->block_start = s;
            e->block_count = c;
            return 0;
        }
    default:
        return refuse(e, DLPC900_ERR_INVALID_CMD, "invalid command number 0x%X", m->cmd);
    }
}

static void handle_message(dlpc900_emu *e, const dlpc900_msg *m)
{
    uint8_t data[64];
    size_t dlen = 0;
    int fault = DLPC900_EMU_FAULT_NONE;
    e->messages++;
    if (e->fault != DLPC900_EMU_FAULT_NONE && m->cmd == e->fault_cmd && e->fault_nth-- == 0) {
        fault = e->fault;
        e->fault = DLPC900_EMU_FAULT_NONE;
    }
    int code;
    if (fault == DLPC900_EMU_FAULT_NACK)
        code = refuse(e, e->fault_code, "%s: %s (injected)", dlpc900_cmd_name(m->cmd), dlpc900_errcode_text(e->fault_code));
    else
        code = exec(e, m, data, &dlen);
    int wants_reply = (m->flags & (DLPC900_FLAG_READ | DLPC900_FLAG_REPLY)) != 0;
    if (!wants_reply || fault == DLPC900_EMU_FAULT_SILENT)
        return;
    uint8_t flags = m->flags;
    if (code) {
        flags |= DLPC900_FLAG_ERROR;
        dlen = 0;
    }
    if (!(m->flags & DLPC900_FLAG_READ))
        dlen = 0; /* write ack: flags and sequence, no data (emulator choice; UNCONFIRMED) */
    push_reply(e, flags, m->seq, data, dlen, fault == DLPC900_EMU_FAULT_SHORT);
}

int dlpc900_emu_write(dlpc900_emu *e, const uint8_t *report, size_t n)
{
    if (!e->plugged)
        return -ENODEV;
    uint8_t first_flags = e->as.have == 0 && n > 0 ? report[0] : 0;
    uint8_t first_seq = e->as.have == 0 && n > 1 ? report[1] : 0;
    dlpc900_msg m;
    sci_error perr = {0};
    int rc = dlpc900_assembler_feed(&e->as, report, n, &m, &perr);
    if (rc < 0) {
        /* The command buffer cannot hold it: refuse, and answer if a reply was asked for. */
        e->messages++;
        refuse(e, DLPC900_ERR_OUT_OF_RESOURCE, "%s", perr.msg);
        if (first_flags & (DLPC900_FLAG_READ | DLPC900_FLAG_REPLY))
            push_reply(e, first_flags | DLPC900_FLAG_ERROR, first_seq, NULL, 0, 0);
    } else if (rc == 1) {
        handle_message(e, &m);
    }
    if (e->unplug_after > 0 && --e->unplug_after == 0) {
        e->plugged = 0; /* power loss: the device forgets everything */
        e->unplug_after = -1;
        emu_reset_state(e);
    }
    return 0;
}

int dlpc900_emu_read(dlpc900_emu *e, uint8_t report[DLPC900_REPORT_SIZE])
{
    if (!e->plugged)
        return -ENODEV;
    if (e->reply_count == 0)
        return -ETIMEDOUT;
    int slot = e->reply_head;
    memcpy(report, e->reply[slot], DLPC900_REPORT_SIZE);
    e->reply_head = (e->reply_head + 1) % EMU_REPLIES_MAX;
    e->reply_count--;
    return e->reply_len[slot];
}

static int emu_t_write(void *ctx, const uint8_t report[DLPC900_REPORT_SIZE], int timeout_ms, sci_error *err)
{
    dlpc900_emu *e = ctx;
    int rc = dlpc900_emu_write(e, report, DLPC900_REPORT_SIZE);
    if (rc < 0)
        return sci_error_set(err, rc, "DLPC900 emulator %s: unplugged", e->serial);
    return 0;
}

static int emu_t_read(void *ctx, uint8_t report[DLPC900_REPORT_SIZE], int timeout_ms, sci_error *err)
{
    dlpc900_emu *e = ctx;
    int rc = dlpc900_emu_read(e, report);
    if (rc == -ENODEV)
        return sci_error_set(err, rc, "DLPC900 emulator %s: unplugged", e->serial);
    if (rc == -ETIMEDOUT)
        return sci_error_set(err, rc, "DLPC900 emulator %s: no reply within %d ms", e->serial, timeout_ms);
    return rc;
}

static const dlpc900_transport_ops emu_transport_ops = {
    .name = "emulator",
    .write = emu_t_write,
    .read = emu_t_read,
    .close = NULL, /* the emulator is borrowed */
};

dlpc900_transport dlpc900_emu_transport(dlpc900_emu *e) { return (dlpc900_transport){&emu_transport_ops, e}; }

void dlpc900_emu_inject(dlpc900_emu *e, uint16_t cmd, int nth, enum dlpc900_emu_fault fault, int code)
{
    e->fault_cmd = cmd;
    e->fault_nth = nth;
    e->fault = fault;
    e->fault_code = code;
}

void dlpc900_emu_unplug_after(dlpc900_emu *e, long reports)
{
    if (reports == 0) {
        e->plugged = 0;
        emu_reset_state(e);
        e->unplug_after = -1;
        return;
    }
    e->unplug_after = reports < 0 ? -1 : reports;
}

void dlpc900_emu_replug(dlpc900_emu *e)
{
    emu_reset_state(e);
    e->plugged = 1;
    e->unplug_after = -1;
}

int dlpc900_emu_plugged(const dlpc900_emu *e) { return e->plugged; }
const char *dlpc900_emu_serial(const dlpc900_emu *e) { return e->serial; }
int dlpc900_emu_mode(const dlpc900_emu *e) { return e->mode; }
int dlpc900_emu_running(const dlpc900_emu *e) { return e->running; }

void dlpc900_emu_lut(const dlpc900_emu *e, int *entries, uint32_t *patterns)
{
    *entries = e->lut_configured ? e->lut_nl : 0;
    *patterns = e->lut_np;
}

int dlpc900_emu_lut_entry(const dlpc900_emu *e, int i, dlpc900_lut_entry *le)
{
    if (i < 0 || i >= EMU_LUT_MAX || !e->lut_defined[i])
        return -ERANGE;
    *le = e->lut[i];
    return 0;
}

int dlpc900_emu_mask(const dlpc900_emu *e, int i, uint8_t *out)
{
    if (i < 0 || i >= EMU_LUT_MAX || !e->lut_defined[i])
        return -ERANGE;
    const uint32_t *px = e->image[e->lut[i].image_index];
    if (!px)
        return -ENOENT;
    dlpc900_image_unpack_bit(px, e->w, e->h, e->lut[i].bit_position, out);
    return 0;
}

const uint32_t *dlpc900_emu_image(const dlpc900_emu *e, int index)
{
    return index >= 0 && index < EMU_IMAGES_MAX ? e->image[index] : NULL;
}

void dlpc900_emu_size(const dlpc900_emu *e, int *w, int *h)
{
    *w = e->w;
    *h = e->h;
}

void dlpc900_emu_triggers_get(const dlpc900_emu *e, dlpc900_emu_triggers *t) { *t = e->trig; }

int dlpc900_emu_last_error(const dlpc900_emu *e, const char **text)
{
    if (text)
        *text = e->err_text;
    return e->err_code;
}

long dlpc900_emu_messages(const dlpc900_emu *e) { return e->messages; }
long dlpc900_emu_refused(const dlpc900_emu *e) { return e->refused; }
int dlpc900_emu_warnings(const dlpc900_emu *e) { return e->warnings; }

int dlpc900_emu_displayed_at(const dlpc900_emu *e, int64_t t_ns, long *pass)
{
    if (!e->running || !e->lut_configured || e->lut_nl < 1 || t_ns < 0)
        return -ENODATA;
    int64_t period = 0;
    for (int i = 0; i < e->lut_nl; i++)
        period += ((int64_t)e->lut[i].exposure_us + e->lut[i].dark_us) * 1000;
    if (period <= 0)
        return -ENODATA;
    long p = (long)(t_ns / period);
    int64_t r = t_ns % period;
    if (pass)
        *pass = p;
    for (int i = 0; i < e->lut_nl; i++) {
        int64_t exp = (int64_t)e->lut[i].exposure_us * 1000, dark = (int64_t)e->lut[i].dark_us * 1000;
        if (e->lut_np > 0 && (uint64_t)p * (uint64_t)e->lut_nl + (uint64_t)i >= e->lut_np)
            return -2;
        if (r < exp)
            return i;
        if (r < exp + dark)
            return -1;
        r -= exp + dark;
    }
    return -1;
}
