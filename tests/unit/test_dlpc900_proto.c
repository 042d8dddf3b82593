/* Tests for drivers/dlpc900_proto: report framing against the reference's example byte strings (golden),
 * continuation reports, the 512-byte limit, reply parsing, LUT entry packing. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "drivers/dlpc900_proto.h"

/* Compare the first report of `m` sent with `seq` to `want` (the rest of the 64 bytes must be zero). */
static void expect_report(const dlpc900_msg *m, uint8_t seq, const uint8_t *want, size_t n)
{
    uint8_t rep[DLPC900_MSG_REPORTS_MAX][DLPC900_REPORT_SIZE];
    assert_int_equal(dlpc900_msg_to_reports(m, seq, rep), 1);
    assert_memory_equal(rep[0], want, n);
    for (size_t i = n; i < DLPC900_REPORT_SIZE; i++)
        assert_int_equal(rep[0][i], 0);
}

/* reference §4, "set OTF mode (0x1A1B = 3), no reply": 00 | 00 00 03 00 1B 1A 03 */
static void test_golden_display_mode(void **state)
{
    dlpc900_msg m;
    dlpc900_cmd_display_mode(&m, DLPC900_MODE_OTF);
    assert_int_equal(m.flags, 0x40); /* the driver asks for an ack */
    m.flags = 0x00;
    expect_report(&m, 0x00, (const uint8_t[]){0x00, 0x00, 0x03, 0x00, 0x1B, 0x1A, 0x03}, 7);
}

/* "start (0x1A24 = 2), reply, seq 5": 40 05 03 00 24 1A 02 */
static void test_golden_start(void **state)
{
    dlpc900_msg m;
    dlpc900_cmd_pattern_start(&m, DLPC900_START);
    expect_report(&m, 0x05, (const uint8_t[]){0x40, 0x05, 0x03, 0x00, 0x24, 0x1A, 0x02}, 7);
}

/* "read main status (0x1A0C)": C0 11 02 00 0C 1A; "read error code (0x0100)": C0 12 02 00 00 01 */
static void test_golden_reads(void **state)
{
    dlpc900_msg m;
    dlpc900_cmd_read(&m, DLPC900_CMD_MAIN_STATUS);
    expect_report(&m, 0x11, (const uint8_t[]){0xC0, 0x11, 0x02, 0x00, 0x0C, 0x1A}, 6);
    dlpc900_cmd_read(&m, DLPC900_CMD_ERROR_CODE);
    expect_report(&m, 0x12, (const uint8_t[]){0xC0, 0x12, 0x02, 0x00, 0x00, 0x01}, 6);
    dlpc900_cmd_read(&m, 0x1100); /* curtain colour, DLPU018 */
    expect_report(&m, 0x11, (const uint8_t[]){0xC0, 0x11, 0x02, 0x00, 0x00, 0x11}, 6);
}

/* "TRIG_IN_1: delay 105 µs, rising": 00 00 05 00 35 1A 69 00 00;
 * "TRIG_OUT_1: no invert, 0/0 µs": 00 00 07 00 1D 1A 00 00 00 00 00 */
static void test_golden_triggers(void **state)
{
    dlpc900_msg m;
    dlpc900_cmd_trig_in1(&m, 105, 0);
    m.flags = 0;
    expect_report(&m, 0, (const uint8_t[]){0x00, 0x00, 0x05, 0x00, 0x35, 0x1A, 0x69, 0x00, 0x00}, 9);
    dlpc900_cmd_trig_out(&m, 1, 0, 0, 0);
    m.flags = 0;
    expect_report(&m, 0, (const uint8_t[]){0x00, 0x00, 0x07, 0x00, 0x1D, 0x1A, 0x00, 0x00, 0x00, 0x00, 0x00}, 11);
}

/* "write curtain colour (0x1100)": 00 12 08 00 00 11 FF 01 FF 01 FF 01 — a generic write. */
static void test_golden_curtain_write(void **state)
{
    dlpc900_msg m = {.flags = 0, .cmd = 0x1100, .len = 6, .payload = {0xFF, 0x01, 0xFF, 0x01, 0xFF, 0x01}};
    expect_report(&m, 0x12,
                  (const uint8_t[]){0x00, 0x12, 0x08, 0x00, 0x00, 0x11, 0xFF, 0x01, 0xFF, 0x01, 0xFF, 0x01}, 12);
}

/* Curtain reply "C0 11 06 00 FF 01 FF 01 FF 01" (Linux: no report-ID byte). */
static void test_reply_parse(void **state)
{
    uint8_t rep[64] = {0xC0, 0x11, 0x06, 0x00, 0xFF, 0x01, 0xFF, 0x01, 0xFF, 0x01};
    dlpc900_reply r;
    sci_error err = {0};
    assert_int_equal(dlpc900_reply_parse(rep, 64, &r, &err), 0);
    assert_int_equal(r.flags, 0xC0);
    assert_int_equal(r.seq, 0x11);
    assert_int_equal(r.len, 6);
    assert_memory_equal(r.data, rep + 4, 6);
    /* short: 3 bytes */
    assert_int_equal(dlpc900_reply_parse(rep, 3, &r, &err), SCI_EPROTO);
    assert_non_null(strstr(err.msg, "short reply"));
    /* length beyond what arrived */
    assert_int_equal(dlpc900_reply_parse(rep, 8, &r, &err), SCI_EPROTO);
    /* length beyond one report */
    rep[2] = 61;
    assert_int_equal(dlpc900_reply_parse(rep, 64, &r, &err), SCI_EPROTO);
    /* build ↔ parse */
    uint8_t out[64];
    assert_int_equal(dlpc900_reply_build(out, 0xE0, 7, NULL, 0), 0);
    assert_int_equal(dlpc900_reply_parse(out, 64, &r, &err), 0);
    assert_true(r.flags & DLPC900_FLAG_ERROR);
    assert_int_equal(dlpc900_reply_build(out, 0xC0, 7, rep, 61), -22);
}

/* DLPU018 fig. 1-5: a 76-byte message travels in two reports; the image chunk fills 8. */
static void test_continuation_reports(void **state)
{
    dlpc900_msg m = {.flags = 0, .cmd = 0x1234, .len = 70};
    for (int i = 0; i < 70; i++)
        m.payload[i] = (uint8_t)(i + 1);
    uint8_t rep[8][64];
    assert_int_equal(dlpc900_msg_to_reports(&m, 3, rep), 2);
    assert_int_equal(rep[0][2], 72);
    assert_int_equal(rep[0][6], 1);
    assert_int_equal(rep[0][63], 58);  /* payload byte 57 */
    assert_int_equal(rep[1][0], 59);   /* continuation: raw message bytes, no header */
    assert_int_equal(rep[1][11], 70);
    assert_int_equal(rep[1][12], 0);   /* zero padding */

    uint8_t chunk[DLPC900_CHUNK_MAX];
    for (int i = 0; i < DLPC900_CHUNK_MAX; i++)
        chunk[i] = (uint8_t)(i * 7);
    assert_int_equal(dlpc900_cmd_image_data(&m, chunk, sizeof chunk), 0);
    assert_int_equal(dlpc900_msg_to_reports(&m, 0, rep), 8);
    assert_int_equal(dlpc900_get16(rep[0] + 2), 508);          /* length field 508: 512-byte message */
    assert_int_equal(dlpc900_get16(rep[0] + 6), 504);          /* count */
    assert_int_equal(rep[0][8], chunk[0]);                     /* data bytes 0–55 in report 0 */
    assert_int_equal(rep[1][0], chunk[56]);                    /* 56–503 in reports 1–7 */
    assert_int_equal(rep[7][63], chunk[503]);
    assert_int_equal(dlpc900_cmd_image_data(&m, chunk, 505), -22);
    /* A final 9-byte chunk (DLPU018's example): length 4 + 9 = 13, one report. */
    dlpc900_cmd_image_data(&m, chunk, 9);
    assert_int_equal(dlpc900_msg_to_reports(&m, 0, rep), 1);
    assert_int_equal(rep[0][2], 13);

    /* The assembler puts it back together. */
    dlpc900_cmd_image_data(&m, chunk, 504);
    int n = dlpc900_msg_to_reports(&m, 9, rep);
    dlpc900_assembler as = {0};
    dlpc900_msg back;
    sci_error err = {0};
    for (int i = 0; i < n; i++)
        assert_int_equal(dlpc900_assembler_feed(&as, rep[i], 64, &back, &err), i == n - 1 ? 1 : 0);
    assert_int_equal(back.cmd, DLPC900_CMD_IMAGE_DATA);
    assert_int_equal(back.seq, 9);
    assert_int_equal(back.len, 506);
    assert_memory_equal(back.payload, m.payload, 506);
}

static void test_assembler_limits(void **state)
{
    uint8_t rep[64] = {0x40, 1, 0, 0};
    dlpc900_assembler as = {0};
    dlpc900_msg m;
    sci_error err = {0};
    dlpc900_put16(rep + 2, 509); /* one byte over the 512-byte command buffer */
    assert_int_equal(dlpc900_assembler_feed(&as, rep, 64, &m, &err), SCI_EPROTO);
    assert_non_null(strstr(err.msg, "509"));
    dlpc900_put16(rep + 2, 1); /* no room for the command */
    assert_int_equal(dlpc900_assembler_feed(&as, rep, 64, &m, &err), SCI_EPROTO);
    dlpc900_put16(rep + 2, 2);
    dlpc900_put16(rep + 4, 0x1A0C);
    assert_int_equal(dlpc900_assembler_feed(&as, rep, 64, &m, &err), 1);
    assert_int_equal(m.cmd, 0x1A0C);
    assert_int_equal(m.len, 0);
    /* message too long for the builder */
    m.len = DLPC900_PAYLOAD_MAX + 1;
    uint8_t out[8][64];
    assert_int_equal(dlpc900_msg_to_reports(&m, 0, out), -22);
}

static void test_lut_entry(void **state)
{
    dlpc900_lut_entry e = {.index = 37, .exposure_us = 0x0123AB, .clear_after = 1, .bit_depth = 1, .led = 7,
                           .wait_trigger = 1, .dark_us = 0x00FF01, .trig_out2_off = 1, .image_index = 1,
                           .bit_position = 13};
    dlpc900_msg m;
    assert_int_equal(dlpc900_cmd_lut_define(&m, &e), 0);
    assert_int_equal(m.cmd, 0x1A34);
    assert_int_equal(m.len, 12);
    const uint8_t want[12] = {37, 0, 0xAB, 0x23, 0x01, 0x01 | 0 << 1 | 7 << 4 | 0x80, 0x01, 0xFF, 0x00, 0x01,
                              (uint8_t)(1 | (13 << 11)), (uint8_t)((1 | (13 << 11)) >> 8)};
    assert_memory_equal(m.payload, want, 12);
    dlpc900_lut_entry back;
    memset(&back, 0xA5, sizeof back); /* unpack must set every field; its padding stays 0xA5 */
    dlpc900_lut_entry_unpack(m.payload, &back);
    /* field by field: memcmp over the struct would compare its padding, which unpack need not write */
    assert_int_equal(back.index, e.index);
    assert_int_equal(back.exposure_us, e.exposure_us);
    assert_int_equal(back.clear_after, e.clear_after);
    assert_int_equal(back.bit_depth, e.bit_depth);
    assert_int_equal(back.led, e.led);
    assert_int_equal(back.wait_trigger, e.wait_trigger);
    assert_int_equal(back.dark_us, e.dark_us);
    assert_int_equal(back.trig_out2_off, e.trig_out2_off);
    assert_int_equal(back.image_index, e.image_index);
    assert_int_equal(back.bit_position, e.bit_position);
    e.bit_position = 24;
    assert_int_equal(dlpc900_cmd_lut_define(&m, &e), -22);
    e.bit_position = 0;
    e.exposure_us = 1u << 24;
    assert_int_equal(dlpc900_cmd_lut_define(&m, &e), -22);

    dlpc900_cmd_lut_config(&m, 48, 0);
    const uint8_t cfg[6] = {48, 0, 0, 0, 0, 0};
    assert_memory_equal(m.payload, cfg, 6);
    dlpc900_cmd_image_init(&m, 1, 6057); /* DLPU018's example: 6009 + 48 */
    const uint8_t init[6] = {1, 0, 0xA9, 0x17, 0, 0};
    assert_memory_equal(m.payload, init, 6);
}

static void test_names(void **state)
{
    assert_string_equal(dlpc900_errcode_text(14), "pattern exposure time out of range");
    assert_string_equal(dlpc900_errcode_text(255), "internal error");
    assert_string_equal(dlpc900_errcode_text(99), "unknown error code");
    assert_string_equal(dlpc900_cmd_name(0x1A34), "pattern LUT definition");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_golden_display_mode), cmocka_unit_test(test_golden_start),
        cmocka_unit_test(test_golden_reads),        cmocka_unit_test(test_golden_triggers),
        cmocka_unit_test(test_golden_curtain_write), cmocka_unit_test(test_reply_parse),
        cmocka_unit_test(test_continuation_reports), cmocka_unit_test(test_assembler_limits),
        cmocka_unit_test(test_lut_entry),           cmocka_unit_test(test_names),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
