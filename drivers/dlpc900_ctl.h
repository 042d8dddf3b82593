/* drivers/dlpc900_ctl.h — talking to one DLPC900 over a transport: commands with acknowledgement, reads,
 * device errors turned into messages, and the pattern-on-the-fly sequence in the order that works.
 *
 *     dlpc900_ctl *c;
 *     dlpc900_ctl_new(&c, transport, "DLPC900 A1B2", 1000, &err);   // takes the transport
 *     dlpc900_ctl_program(c, images, w, h, &seq, &err);               // stop, mode 3, LUT, images, LUT config
 *     dlpc900_ctl_start(c, &err);                                     // start, then check running and error code
 *     dlpc900_ctl_stop(c, &err);
 *     dlpc900_ctl_free(c);
 *
 * Command order (TI DLPU018 and mcSIM's sniff of the TI GUI; docs/dlpc900.md, "Command order"):
 *   stop → display mode 3 (on-the-fly) → stop → hardware status check → TRIG_IN_1 (external trigger only) →
 *   one LUT definition per mask → LUT configuration → per image, highest index first: image load init + 504-byte
 *   chunks (no reply), then error-code read → LUT configuration again → error-code read.
 *   Start: stop → start → main status must show the sequencer running → error-code read.
 * Writes go with the reply bit (0x40) and their acknowledgement is checked, except image data (no reply, as
 * TI's GUI does; an ack per 504 bytes would double the upload time). Reads use 0xC0.
 * Device errors: a NACK (reply bit5) is followed by reading 0x0100 (code) and 0x0101 (text); the call returns
 * SCI_EDEVICE with "<name>: <command> (0xNNNN) refused: error <code> (<meaning>): <device text>".
 * Other errors: -ETIMEDOUT (no reply in timeout_ms), SCI_EPROTO (short or mismatched reply), -ENODEV (unplugged).
 * Every failure inside program/start sends a best-effort stop, so the device is left stopped (an unplugged one
 * has lost power and is stopped by definition).
 *
 * Not thread-safe: one thread drives one ctl (the DMD backend serialises callers).
 */
#ifndef SCICAP_DRIVERS_DLPC900_CTL_H
#define SCICAP_DRIVERS_DLPC900_CTL_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "drivers/dlpc900_proto.h"
#include "drivers/dlpc900_transport.h"

typedef struct dlpc900_ctl dlpc900_ctl;

/* Takes ownership of `t` (closed by _free, also on error). `name` (copied) prefixes every message.
 * timeout_ms: how long a read waits for a reply (> 0). */
int dlpc900_ctl_new(dlpc900_ctl **out, dlpc900_transport t, const char *name, int timeout_ms, sci_error *err);
void dlpc900_ctl_free(dlpc900_ctl *c);

/* Send `m` (its seq is replaced by the next sequence number). With the reply bit set, waits for and checks
 * the acknowledgement as described above. */
int dlpc900_ctl_write(dlpc900_ctl *c, const dlpc900_msg *m, sci_error *err);
/* Read command `cmd` (0xC0): copies up to `cap` data bytes to `data`; *len (may be NULL) receives the data
 * length. A reply with fewer than `min_len` data bytes is SCI_EPROTO (TI-GUI: length 0 is a failed read). */
int dlpc900_ctl_read(dlpc900_ctl *c, uint16_t cmd, uint8_t *data, size_t cap, size_t min_len, size_t *len,
                     sci_error *err);
/* The device's last error code (0x0100) and text (0x0101, NUL-terminated into text[n]). */
int dlpc900_ctl_last_error(dlpc900_ctl *c, int *code, char *text, size_t n, sci_error *err);

typedef struct dlpc900_status {
    uint8_t hw, sys, main;  /* 0x1A0A, 0x1A0B, 0x1A0C */
    int running;            /* main bit1 */
    int error_code;         /* 0x0100 */
    char error_text[64];    /* 0x0101 when error_code != 0, else "" */
} dlpc900_status;
int dlpc900_ctl_status(dlpc900_ctl *c, dlpc900_status *st, sci_error *err);

typedef struct dlpc900_identity {
    uint32_t app_version, api_version;  /* bits 31:24 major, 23:16 minor, 15:0 patch */
    int dmd_type;                       /* 1 DLP6500, 2 DLP9000, ... */
    char fw_tag[32];
} dlpc900_identity;
int dlpc900_ctl_identify(dlpc900_ctl *c, dlpc900_identity *id, sci_error *err);
/* "DLP6500" etc. for a 0x0206 DMD type; "unknown DMD" otherwise. */
const char *dlpc900_dmd_type_name(int type);

/* A 1-bit pattern sequence: mask j is image j/24, bit j%24. */
typedef struct dlpc900_sequence {
    int count;                    /* masks, 1 … 400 */
    const uint32_t *exposure_us;  /* count values (borrowed) */
    const uint32_t *dark_us;      /* count values (borrowed) */
    int external_trigger;         /* 1: each pattern waits for TRIG_IN_1 */
    uint16_t trig_in1_delay_us;   /* external only; ≥ 105 on a full-array DLP6500 */
    int trig_in1_falling;
    uint32_t patterns;            /* NP: patterns to show, 0 = repeat forever */
} dlpc900_sequence;

/* Program the sequence and upload `images` (ceil(count/24) packed w×h images, see dlpc900_image.h).
 * Leaves the device stopped and configured. */
int dlpc900_ctl_program(dlpc900_ctl *c, const uint32_t *const *images, int w, int h, const dlpc900_sequence *seq,
                        sci_error *err);
/* Re-define only the LUT (exposure, dark time, trigger) for images already uploaded with the same count. */
int dlpc900_ctl_program_lut(dlpc900_ctl *c, const dlpc900_sequence *seq, sci_error *err);
int dlpc900_ctl_start(dlpc900_ctl *c, sci_error *err);
int dlpc900_ctl_stop(dlpc900_ctl *c, sci_error *err);

/* Traffic so far (for upload cost): reports written and messages sent. */
typedef struct dlpc900_traffic {
    long reports_out, reports_in, messages;
} dlpc900_traffic;
void dlpc900_ctl_traffic(const dlpc900_ctl *c, dlpc900_traffic *t);

#endif
