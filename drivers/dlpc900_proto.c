#include "drivers/dlpc900_proto.h"

#include <errno.h>
#include <string.h>

const char *dlpc900_cmd_name(uint16_t cmd)
{
    switch (cmd) {
    case DLPC900_CMD_ERROR_CODE: return "error code";
    case DLPC900_CMD_ERROR_TEXT: return "error text";
    case DLPC900_CMD_POWER: return "power control";
    case DLPC900_CMD_DMD_IDLE: return "DMD idle";
    case DLPC900_CMD_VERSION: return "version";
    case DLPC900_CMD_FW_TYPE: return "firmware type";
    case DLPC900_CMD_LED_ENABLE: return "LED enable";
    case DLPC900_CMD_HW_STATUS: return "hardware status";
    case DLPC900_CMD_SYS_STATUS: return "system status";
    case DLPC900_CMD_MAIN_STATUS: return "main status";
    case DLPC900_CMD_DISPLAY_MODE: return "display mode";
    case DLPC900_CMD_TRIG_OUT1: return "TRIG_OUT_1";
    case DLPC900_CMD_TRIG_OUT2: return "TRIG_OUT_2";
    case DLPC900_CMD_PATTERN_START: return "pattern start/stop";
    case DLPC900_CMD_IMAGE_INIT: return "image load init";
    case DLPC900_CMD_IMAGE_DATA: return "image load data";
    case DLPC900_CMD_IMAGE_INIT2: return "image load init (secondary)";
    case DLPC900_CMD_IMAGE_DATA2: return "image load data (secondary)";
    case DLPC900_CMD_LUT_CONFIG: return "pattern LUT configuration";
    case DLPC900_CMD_LUT_REORDER: return "pattern LUT reorder";
    case DLPC900_CMD_LUT_DEFINE: return "pattern LUT definition";
    case DLPC900_CMD_TRIG_IN1: return "TRIG_IN_1";
    case DLPC900_CMD_TRIG_IN2: return "TRIG_IN_2";
    case DLPC900_CMD_BLOCK_LOAD: return "DMD block load";
    case DLPC900_CMD_MIN_EXPOSURE: return "minimum exposure";
    default: return "unknown command";
    }
}

const char *dlpc900_errcode_text(int code)
{
    static const char *const text[] = {
        [0] = "no error", [1] = "batch file checksum error", [2] = "device failure",
        [3] = "invalid command number", [4] = "incompatible controller or DMD",
        [5] = "command not allowed in current mode", [6] = "invalid command parameter",
        [7] = "item referred by the parameter is not present", [8] = "out of resource (RAM or flash)",
        [9] = "invalid BMP compression type", [10] = "pattern bit number out of range",
        [11] = "pattern BMP not present in flash", [12] = "pattern dark time out of range",
        [13] = "signal delay parameter out of range", [14] = "pattern exposure time out of range",
        [15] = "pattern number out of range", [16] = "invalid pattern definition",
        [17] = "pattern image memory address out of range",
    };
    if (code == 255)
        return "internal error";
    if (code >= 0 && code < (int)(sizeof text / sizeof text[0]))
        return text[code];
    return "unknown error code";
}

int dlpc900_msg_report_count(const dlpc900_msg *m)
{
    size_t total = 6 + (size_t)m->len;
    return (int)((total + DLPC900_REPORT_SIZE - 1) / DLPC900_REPORT_SIZE);
}

int dlpc900_msg_to_reports(const dlpc900_msg *m, uint8_t seq, uint8_t out[][DLPC900_REPORT_SIZE])
{
    if (m->len > DLPC900_PAYLOAD_MAX)
        return -EINVAL;
    uint8_t flat[DLPC900_MSG_MAX];
    int nrep = dlpc900_msg_report_count(m);
    memset(flat, 0, (size_t)nrep * DLPC900_REPORT_SIZE);
    flat[0] = m->flags;
    flat[1] = seq;
    dlpc900_put16(flat + 2, 2u + m->len);
    dlpc900_put16(flat + 4, m->cmd);
    memcpy(flat + 6, m->payload, m->len);
    for (int i = 0; i < nrep; i++)
        memcpy(out[i], flat + (size_t)i * DLPC900_REPORT_SIZE, DLPC900_REPORT_SIZE);
    return nrep;
}

int dlpc900_reply_parse(const uint8_t *rep, size_t n, dlpc900_reply *out, sci_error *err)
{
    if (n < 4)
        return sci_error_set(err, SCI_EPROTO, "short reply: %zu bytes, a reply header needs 4", n);
    if (n > DLPC900_REPORT_SIZE)
        n = DLPC900_REPORT_SIZE;
    uint16_t len = dlpc900_get16(rep + 2);
    if (len > DLPC900_REPLY_DATA_MAX)
        return sci_error_set(err, SCI_EPROTO, "reply length %u exceeds the %d data bytes of one report", len,
                             DLPC900_REPLY_DATA_MAX);
    if ((size_t)len + 4 > n)
        return sci_error_set(err, SCI_EPROTO, "short reply: length field says %u data bytes, %zu arrived", len,
                             n - 4);
    out->flags = rep[0];
    out->seq = rep[1];
    out->len = len;
    memcpy(out->data, rep + 4, len);
    return 0;
}

int dlpc900_reply_build(uint8_t out[DLPC900_REPORT_SIZE], uint8_t flags, uint8_t seq, const uint8_t *data, size_t len)
{
    if (len > DLPC900_REPLY_DATA_MAX)
        return -EINVAL;
    memset(out, 0, DLPC900_REPORT_SIZE);
    out[0] = flags;
    out[1] = seq;
    dlpc900_put16(out + 2, (uint32_t)len);
    if (len)
        memcpy(out + 4, data, len);
    return 0;
}

void dlpc900_assembler_reset(dlpc900_assembler *a)
{
    a->have = 0;
    a->want = 0;
}

int dlpc900_assembler_feed(dlpc900_assembler *a, const uint8_t *rep, size_t n, dlpc900_msg *out, sci_error *err)
{
    if (n > DLPC900_REPORT_SIZE)
        n = DLPC900_REPORT_SIZE;
    if (a->have == 0) {
        uint16_t len = n >= 4 ? dlpc900_get16(rep + 2) : 0;
        if (n < 4 || len < 2 || len > DLPC900_LENGTH_MAX) {
            dlpc900_assembler_reset(a);
            return sci_error_set(err, SCI_EPROTO, "report starts a message of length %u (allowed 2 … %d)", len,
                                 DLPC900_LENGTH_MAX);
        }
        a->want = 4u + len;
    }
    /* Reports are fixed 64 bytes on the wire; a short one is treated as zero-padded. */
    size_t take = a->want - a->have < DLPC900_REPORT_SIZE ? a->want - a->have : DLPC900_REPORT_SIZE;
    size_t copy = take < n ? take : n;
    memcpy(a->buf + a->have, rep, copy);
    memset(a->buf + a->have + copy, 0, take - copy);
    a->have += take;
    if (a->have < a->want)
        return 0;
    out->flags = a->buf[0];
    out->seq = a->buf[1];
    out->cmd = dlpc900_get16(a->buf + 4);
    out->len = (uint16_t)(a->want - 6);
    memcpy(out->payload, a->buf + 6, out->len);
    dlpc900_assembler_reset(a);
    return 1;
}

static void msg_init(dlpc900_msg *m, uint8_t flags, uint16_t cmd, uint16_t len)
{
    m->flags = flags;
    m->seq = 0;
    m->cmd = cmd;
    m->len = len;
    memset(m->payload, 0, len);
}

void dlpc900_cmd_read(dlpc900_msg *m, uint16_t cmd) { msg_init(m, DLPC900_FLAG_READ | DLPC900_FLAG_REPLY, cmd, 0); }

void dlpc900_cmd_display_mode(dlpc900_msg *m, enum dlpc900_mode mode)
{
    msg_init(m, DLPC900_FLAG_REPLY, DLPC900_CMD_DISPLAY_MODE, 1);
    m->payload[0] = (uint8_t)(mode & 3);
}

void dlpc900_cmd_pattern_start(dlpc900_msg *m, enum dlpc900_start what)
{
    msg_init(m, DLPC900_FLAG_REPLY, DLPC900_CMD_PATTERN_START, 1);
    m->payload[0] = (uint8_t)what;
}

int dlpc900_cmd_lut_define(dlpc900_msg *m, const dlpc900_lut_entry *e)
{
    if (e->exposure_us >= 1u << 24 || e->dark_us >= 1u << 24 || e->bit_depth < 1 || e->bit_depth > 8 ||
        e->bit_position > 23 || e->led > 7 || e->image_index > 0x7FF)
        return -EINVAL;
    msg_init(m, DLPC900_FLAG_REPLY, DLPC900_CMD_LUT_DEFINE, 12);
    uint8_t *p = m->payload;
    dlpc900_put16(p, e->index);
    dlpc900_put24(p + 2, e->exposure_us);
    p[5] = (uint8_t)((e->clear_after & 1) | (e->bit_depth - 1) << 1 | (e->led & 7) << 4 | (e->wait_trigger & 1) << 7);
    dlpc900_put24(p + 6, e->dark_us);
    p[9] = (uint8_t)(e->trig_out2_off & 1);
    dlpc900_put16(p + 10, (uint32_t)e->image_index | (uint32_t)e->bit_position << 11);
    return 0;
}

void dlpc900_lut_entry_unpack(const uint8_t p[12], dlpc900_lut_entry *e)
{
    e->index = dlpc900_get16(p);
    e->exposure_us = dlpc900_get24(p + 2);
    e->clear_after = p[5] & 1;
    e->bit_depth = (uint8_t)(((p[5] >> 1) & 7) + 1 + ((p[9] >> 1) & 1) * 8);
    e->led = (p[5] >> 4) & 7;
    e->wait_trigger = p[5] >> 7;
    e->dark_us = dlpc900_get24(p + 6);
    e->trig_out2_off = p[9] & 1;
    uint16_t w = dlpc900_get16(p + 10);
    e->image_index = w & 0x7FF;
    e->bit_position = (uint8_t)(w >> 11);
}

void dlpc900_cmd_lut_config(dlpc900_msg *m, uint16_t entries, uint32_t patterns)
{
    msg_init(m, DLPC900_FLAG_REPLY, DLPC900_CMD_LUT_CONFIG, 6);
    dlpc900_put16(m->payload, entries & 0x7FF);
    dlpc900_put32(m->payload + 2, patterns);
}

void dlpc900_cmd_image_init(dlpc900_msg *m, uint16_t image_index, uint32_t total_bytes)
{
    msg_init(m, DLPC900_FLAG_REPLY, DLPC900_CMD_IMAGE_INIT, 6);
    dlpc900_put16(m->payload, image_index);
    dlpc900_put32(m->payload + 2, total_bytes);
}

int dlpc900_cmd_image_data(dlpc900_msg *m, const uint8_t *data, size_t n)
{
    if (n > DLPC900_CHUNK_MAX)
        return -EINVAL;
    /* No reply for image data (TI-GUI): an ack per 504 bytes would double the upload time. */
    msg_init(m, 0, DLPC900_CMD_IMAGE_DATA, (uint16_t)(2 + n));
    dlpc900_put16(m->payload, (uint32_t)n);
    memcpy(m->payload + 2, data, n);
    return 0;
}

void dlpc900_cmd_trig_in1(dlpc900_msg *m, uint16_t delay_us, int falling)
{
    msg_init(m, DLPC900_FLAG_REPLY, DLPC900_CMD_TRIG_IN1, 3);
    dlpc900_put16(m->payload, delay_us);
    m->payload[2] = falling ? 1 : 0;
}

void dlpc900_cmd_trig_in2(dlpc900_msg *m, int inverted)
{
    msg_init(m, DLPC900_FLAG_REPLY, DLPC900_CMD_TRIG_IN2, 1);
    m->payload[0] = inverted ? 1 : 0;
}

void dlpc900_cmd_trig_out(dlpc900_msg *m, int which, int invert, int16_t rising_us, int16_t falling_us)
{
    msg_init(m, DLPC900_FLAG_REPLY, which == 2 ? DLPC900_CMD_TRIG_OUT2 : DLPC900_CMD_TRIG_OUT1, 5);
    m->payload[0] = invert ? 1 : 0;
    dlpc900_put16(m->payload + 1, (uint16_t)rising_us);
    dlpc900_put16(m->payload + 3, (uint16_t)falling_us);
}
