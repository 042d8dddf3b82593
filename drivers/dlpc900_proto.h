/* drivers/dlpc900_proto.h — the DLPC900 USB HID protocol, pure and free of I/O.
 *
 * A *message* is what the DLPC900 calls one command: a 4-byte header (flags, sequence, u16 length), a u16
 * command number and a payload, at most DLPC900_MSG_MAX = 512 bytes in all (the controller's shared command
 * buffer, DLPU018 §1.2.1). On the wire a message travels as 1…8 HID reports of 64 bytes: the first carries the
 * header, later ones are the next 64 raw message bytes, the last zero-padded (TI DLPU018, USB message framing).
 * Multi-byte fields are little-endian.
 *
 *     dlpc900_msg m;
 *     dlpc900_cmd_display_mode(&m, DLPC900_MODE_OTF);         // fill a message (write, no reply)
 *     uint8_t rep[DLPC900_MSG_REPORTS_MAX][DLPC900_REPORT_SIZE];
 *     int n = dlpc900_msg_to_reports(&m, seq, rep);             // 1 report: 00 00 03 00 1B 1A 03 00 ...
 *
 * Device → host: one reply report per read (byte0 = request flags, bit5 set on error; byte1 = echoed sequence;
 * bytes 2–3 = data length; data from byte 4; no command echo). dlpc900_reply_parse checks it.
 * Host side, device side (the emulator) and fuzzers share dlpc900_assembler, which rebuilds a message from
 * reports and rejects everything the controller would (length over 508, a continuation without a start).
 *
 * Everything here is reentrant and allocation-free; no function prints or blocks.
 */
#ifndef SCICAP_DRIVERS_DLPC900_PROTO_H
#define SCICAP_DRIVERS_DLPC900_PROTO_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"

#define DLPC900_VID 0x0451
#define DLPC900_PID 0xC900

#define DLPC900_REPORT_SIZE 64     /* bytes per HID report, without the report-ID byte */
#define DLPC900_MSG_MAX 512        /* command buffer: header + command + payload */
#define DLPC900_LENGTH_MAX 508     /* largest header length field (command + payload) */
#define DLPC900_PAYLOAD_MAX 506    /* largest payload after the 2-byte command */
#define DLPC900_MSG_REPORTS_MAX 8  /* 512 / 64 */
#define DLPC900_CHUNK_MAX 504      /* image bytes per 0x1A2B/0x1A2D message */
#define DLPC900_REPLY_DATA_MAX 60  /* data bytes in one reply report */

/* Flags byte (byte 0). */
#define DLPC900_FLAG_READ 0x80
#define DLPC900_FLAG_REPLY 0x40
#define DLPC900_FLAG_ERROR 0x20
#define DLPC900_FLAG_DEST_MASK 0x07

/* Command numbers used for pattern-on-the-fly (reference §5). */
enum dlpc900_cmd {
    DLPC900_CMD_ERROR_CODE = 0x0100,
    DLPC900_CMD_ERROR_TEXT = 0x0101,
    DLPC900_CMD_POWER = 0x0200,
    DLPC900_CMD_DMD_IDLE = 0x0201,
    DLPC900_CMD_VERSION = 0x0205,
    DLPC900_CMD_FW_TYPE = 0x0206,
    DLPC900_CMD_LED_ENABLE = 0x1A07,
    DLPC900_CMD_HW_STATUS = 0x1A0A,
    DLPC900_CMD_SYS_STATUS = 0x1A0B,
    DLPC900_CMD_MAIN_STATUS = 0x1A0C,
    DLPC900_CMD_DISPLAY_MODE = 0x1A1B,
    DLPC900_CMD_TRIG_OUT1 = 0x1A1D,
    DLPC900_CMD_TRIG_OUT2 = 0x1A1E,
    DLPC900_CMD_PATTERN_START = 0x1A24,
    DLPC900_CMD_IMAGE_INIT = 0x1A2A,
    DLPC900_CMD_IMAGE_DATA = 0x1A2B,
    DLPC900_CMD_IMAGE_INIT2 = 0x1A2C,
    DLPC900_CMD_IMAGE_DATA2 = 0x1A2D,
    DLPC900_CMD_LUT_CONFIG = 0x1A31,
    DLPC900_CMD_LUT_REORDER = 0x1A32,
    DLPC900_CMD_LUT_DEFINE = 0x1A34,
    DLPC900_CMD_TRIG_IN1 = 0x1A35,
    DLPC900_CMD_TRIG_IN2 = 0x1A36,
    DLPC900_CMD_BLOCK_LOAD = 0x1A40,
    DLPC900_CMD_MIN_EXPOSURE = 0x1A42,
};

enum dlpc900_mode { DLPC900_MODE_VIDEO = 0, DLPC900_MODE_PRESTORED = 1, DLPC900_MODE_VIDEO_PATTERN = 2, DLPC900_MODE_OTF = 3 };
enum dlpc900_start { DLPC900_STOP = 0, DLPC900_PAUSE = 1, DLPC900_START = 2 };

/* Main status (0x1A0C) bits; names from mcSIM/DMDConnect (UNCONFIRMED in DLPU018). */
#define DLPC900_MAIN_PARKED 0x01
#define DLPC900_MAIN_RUNNING 0x02
/* Hardware status (0x1A0A): bit0 init OK; bits 1,2,3,6,7 are errors. */
#define DLPC900_HW_INIT_OK 0x01
#define DLPC900_HW_ERROR_BITS 0xCE

/* Device error codes read by 0x0100 (DLPU018 rev I). */
enum dlpc900_errcode {
    DLPC900_ERR_NONE = 0, DLPC900_ERR_BATCH_CHECKSUM = 1, DLPC900_ERR_DEVICE_FAILURE = 2,
    DLPC900_ERR_INVALID_CMD = 3, DLPC900_ERR_INCOMPATIBLE = 4, DLPC900_ERR_NOT_ALLOWED = 5,
    DLPC900_ERR_INVALID_PARAM = 6, DLPC900_ERR_NOT_PRESENT = 7, DLPC900_ERR_OUT_OF_RESOURCE = 8,
    DLPC900_ERR_BMP_COMPRESSION = 9, DLPC900_ERR_BIT_RANGE = 10, DLPC900_ERR_BMP_NOT_IN_FLASH = 11,
    DLPC900_ERR_DARK_RANGE = 12, DLPC900_ERR_DELAY_RANGE = 13, DLPC900_ERR_EXPOSURE_RANGE = 14,
    DLPC900_ERR_PATTERN_RANGE = 15, DLPC900_ERR_PATTERN_DEF = 16, DLPC900_ERR_IMAGE_ADDR = 17,
    DLPC900_ERR_INTERNAL = 255,
};

/* One message. `len` counts payload bytes only (header length field = 2 + len). */
typedef struct dlpc900_msg {
    uint8_t flags;     /* DLPC900_FLAG_* | destination */
    uint8_t seq;       /* echoed in the reply; dlpc900_msg_to_reports overrides it */
    uint16_t cmd;      /* enum dlpc900_cmd */
    uint16_t len;      /* payload bytes, 0 … DLPC900_PAYLOAD_MAX */
    uint8_t payload[DLPC900_PAYLOAD_MAX];
} dlpc900_msg;

/* One parsed reply report. */
typedef struct dlpc900_reply {
    uint8_t flags;    /* request flags as echoed; DLPC900_FLAG_ERROR set when the device refused */
    uint8_t seq;
    uint16_t len;     /* data bytes, 0 … DLPC900_REPLY_DATA_MAX */
    uint8_t data[DLPC900_REPLY_DATA_MAX];
} dlpc900_reply;

/* Human name of a command ("pattern LUT definition"), "unknown command" otherwise. Never NULL. */
const char *dlpc900_cmd_name(uint16_t cmd);
/* Text of a device error code (reference §7), "unknown error code" otherwise. Never NULL. */
const char *dlpc900_errcode_text(int code);

/* Number of reports message `m` needs: ceil((6 + len) / 64), 1 … 8. */
int dlpc900_msg_report_count(const dlpc900_msg *m);
/* Write `m` with sequence `seq` as reports (zero-padded). Returns the report count (1 … 8), or -EINVAL if
 * m->len > DLPC900_PAYLOAD_MAX. `out` must have room for DLPC900_MSG_REPORTS_MAX reports. */
int dlpc900_msg_to_reports(const dlpc900_msg *m, uint8_t seq, uint8_t out[][DLPC900_REPORT_SIZE]);

/* Parse a reply report of `n` bytes (as read, without report ID). Errors: SCI_EPROTO for fewer than 4 bytes or a
 * data length beyond what arrived or beyond 60 bytes; the message says which. Does not judge the error flag. */
int dlpc900_reply_parse(const uint8_t *rep, size_t n, dlpc900_reply *out, sci_error *err);
/* Build a reply report (device side): flags, seq, `len` data bytes (≤ 60). -EINVAL if len > 60. */
int dlpc900_reply_build(uint8_t out[DLPC900_REPORT_SIZE], uint8_t flags, uint8_t seq, const uint8_t *data, size_t len);

/* Message reassembly from reports (device side, also fuzzed). Value type; zero it or call _reset before use. */
typedef struct dlpc900_assembler {
    uint8_t buf[DLPC900_MSG_MAX];
    size_t have;  /* bytes collected of the current message; 0 = waiting for a first report */
    size_t want;  /* 4 + header length of the current message */
} dlpc900_assembler;

void dlpc900_assembler_reset(dlpc900_assembler *a);
/* Feed one report of `n` bytes (n ≤ 64; shorter reports count as zero-padded). Returns 1 and fills `out` when
 * a message is complete, 0 when more reports are needed, SCI_EPROTO when the report starts an impossible message
 * (length field < 2 or > 508); the assembler is then reset and the message names the length. Because a
 * continuation report is indistinguishable from a first report, framing depends on the length field alone, as in
 * the controller. */
int dlpc900_assembler_feed(dlpc900_assembler *a, const uint8_t *rep, size_t n, dlpc900_msg *out, sci_error *err);

/* ---- command builders: each fills `m` for one command (flags set to the value the driver uses) ---- */

/* Reads (flags 0xC0, no payload). */
void dlpc900_cmd_read(dlpc900_msg *m, uint16_t cmd);
/* Display mode 0x1A1B (write with reply). */
void dlpc900_cmd_display_mode(dlpc900_msg *m, enum dlpc900_mode mode);
/* 0x1A24 start/stop/pause (write with reply). */
void dlpc900_cmd_pattern_start(dlpc900_msg *m, enum dlpc900_start what);

/* One pattern LUT entry (0x1A34, reference §6). */
typedef struct dlpc900_lut_entry {
    uint16_t index;        /* LUT entry 0 … NL-1 */
    uint32_t exposure_us;  /* 24 bits */
    uint8_t clear_after;   /* 0/1 */
    uint8_t bit_depth;     /* 1 … 8 */
    uint8_t led;           /* 0 … 7 */
    uint8_t wait_trigger;  /* 0/1: wait for TRIG_IN_1 before this pattern */
    uint32_t dark_us;      /* 24 bits */
    uint8_t trig_out2_off; /* 1 = TRIG_OUT_2 suppressed for this entry (DLPU018 polarity, reference §12) */
    uint16_t image_index;  /* which 24-bit image, 0 … 2047 on the wire (bits 10:0); the device allows far fewer */
    uint8_t bit_position;  /* 0 … 23 */
} dlpc900_lut_entry;

/* -EINVAL when a field does not fit its bits (exposure or dark ≥ 2^24, depth ∉ 1…8, bit ∉ 0…23, led > 7, image > 2047). */
int dlpc900_cmd_lut_define(dlpc900_msg *m, const dlpc900_lut_entry *e);
void dlpc900_lut_entry_unpack(const uint8_t p[12], dlpc900_lut_entry *e);
/* 0x1A31: NL entries (1 … 2047 on the wire), NP patterns to show (0 = forever). Sent with reply. */
void dlpc900_cmd_lut_config(dlpc900_msg *m, uint16_t entries, uint32_t patterns);
/* 0x1A2A image load init: image index, total size in bytes including the 48-byte header. */
void dlpc900_cmd_image_init(dlpc900_msg *m, uint16_t image_index, uint32_t total_bytes);
/* 0x1A2B image data: `n` ≤ 504 bytes. Sent without reply (TI-GUI). -EINVAL if n > 504. */
int dlpc900_cmd_image_data(dlpc900_msg *m, const uint8_t *data, size_t n);
/* 0x1A35 TRIG_IN_1: delay µs (u16), advance on falling edge when `falling`. */
void dlpc900_cmd_trig_in1(dlpc900_msg *m, uint16_t delay_us, int falling);
/* 0x1A36 TRIG_IN_2: polarity bit. */
void dlpc900_cmd_trig_in2(dlpc900_msg *m, int inverted);
/* 0x1A1D/0x1A1E TRIG_OUT_1/2: invert, rising and falling delays in µs (−20 … 20000 on the device). */
void dlpc900_cmd_trig_out(dlpc900_msg *m, int which, int invert, int16_t rising_us, int16_t falling_us);

/* Little-endian helpers. */
static inline uint16_t dlpc900_get16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }
static inline uint32_t dlpc900_get24(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16; }
static inline uint32_t dlpc900_get32(const uint8_t *p) { return dlpc900_get24(p) | (uint32_t)p[3] << 24; }
static inline void dlpc900_put16(uint8_t *p, uint32_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static inline void dlpc900_put24(uint8_t *p, uint32_t v) { dlpc900_put16(p, v); p[2] = (uint8_t)(v >> 16); }
static inline void dlpc900_put32(uint8_t *p, uint32_t v) { dlpc900_put24(p, v); p[3] = (uint8_t)(v >> 24); }

#endif
