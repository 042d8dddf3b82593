/* drivers/dlpc900_emu.h — a byte-exact DLPC900 emulator (pattern-on-the-fly subset).
 *
 * It takes the same 64-byte reports the hardware takes, keeps the device state (display mode, pattern LUT, LUT
 * configuration, images decoded from their ERLE/RLE/raw files, trigger settings, block load, running/paused),
 * answers reads with reply reports, sets the error bit (0x20) on bad commands and records the DLPU018 error code
 * and text (read back with 0x0100/0x0101), and enforces the documented limits: mask count (400 1-bit patterns,
 * 400 LUT entries, image index 0…17), minimum exposure for the active DMD blocks, dark time 24-bit, TRIG_IN_1
 * delay ≥ minimum block-load time, TRIG_OUT delays −20…20000 µs, messages ≤ 512 bytes, chunks ≤ 504 bytes,
 * image data matching what image load init declared, no mode change or upload while running, start only with a
 * configured LUT whose images are all loaded. Choices where the hardware's behaviour is UNCONFIRMED are listed
 * in docs/dlpc900.md; they lean strict, so code that passes the emulator is conservative on hardware.
 *
 *     dlpc900_emu *emu;
 *     dlpc900_emu_new(&emu, &(dlpc900_emu_config){.serial = "EMU0001"}, &err);
 *     dlpc900_transport t = dlpc900_emu_transport(emu);       // borrowed; plug into dlpc900_ctl
 *     ... drive it ...
 *     dlpc900_emu_lut(emu, &nl, &np);  dlpc900_emu_mask(emu, j, buf);  // what it would display
 *     dlpc900_emu_free(emu);
 *
 * Fault injection for tests: NACK a command, answer it short, drop its reply (timeout), or unplug after k
 * reports. Unplugging is a power loss: state returns to reset values, as on hardware after re-enumeration.
 *
 * Time: the emulator has no clock of its own; "what is displayed at t" is computed from the LUT timing given
 * the time since start (dlpc900_emu_displayed_at).
 * Not thread-safe: one thread at a time (the simulated DMD serialises calls).
 */
#ifndef SCICAP_DRIVERS_DLPC900_EMU_H
#define SCICAP_DRIVERS_DLPC900_EMU_H

#include <stddef.h>
#include <stdint.h>

#include "base/error.h"
#include "drivers/dlpc900_proto.h"
#include "drivers/dlpc900_transport.h"

typedef struct dlpc900_emu dlpc900_emu;

typedef struct dlpc900_emu_config {
    const char *serial;  /* copied; NULL = "EMU0001" */
    int width, height;   /* DMD size; 0 = 1920×1080 (DLP6500) */
    int dmd_type;        /* 0x0206 byte 0: 1 DLP6500 (default), 2 DLP9000 */
} dlpc900_emu_config;

int dlpc900_emu_new(dlpc900_emu **out, const dlpc900_emu_config *cfg, sci_error *err);
void dlpc900_emu_free(dlpc900_emu *emu);

/* Host → device: one report (n ≤ 64 bytes, without report ID). Returns 0, or -ENODEV when unplugged.
 * Protocol errors never fail this call: they set the error state, as the device would. */
int dlpc900_emu_write(dlpc900_emu *emu, const uint8_t *report, size_t n);
/* Device → host: the oldest pending reply report. Returns its size (64, or less when a short reply was
 * injected), -ETIMEDOUT when none is pending (the emulator answers at once, so waiting would not help), or
 * -ENODEV when unplugged. */
int dlpc900_emu_read(dlpc900_emu *emu, uint8_t report[DLPC900_REPORT_SIZE]);

/* A transport whose ctx is `emu` (borrowed: free the emulator after the last use of the transport). */
dlpc900_transport dlpc900_emu_transport(dlpc900_emu *emu);

/* ---- fault injection ---- */
enum dlpc900_emu_fault {
    DLPC900_EMU_FAULT_NONE = 0,
    DLPC900_EMU_FAULT_NACK,     /* refuse the command: error bit, error code `code` */
    DLPC900_EMU_FAULT_SHORT,    /* reply with only 3 bytes */
    DLPC900_EMU_FAULT_SILENT,   /* execute, but send no reply (host times out) */
};
/* Apply `fault` to the `nth` (0 = next) future message carrying command `cmd`; one fault at a time. */
void dlpc900_emu_inject(dlpc900_emu *emu, uint16_t cmd, int nth, enum dlpc900_emu_fault fault, int code);
/* Unplug after `reports` more host reports have been accepted (0 = now). Negative cancels. */
void dlpc900_emu_unplug_after(dlpc900_emu *emu, long reports);
/* Plug back in (state at power-on defaults). */
void dlpc900_emu_replug(dlpc900_emu *emu);
int dlpc900_emu_plugged(const dlpc900_emu *emu);

/* ---- inspection: what the device holds and would display ---- */
const char *dlpc900_emu_serial(const dlpc900_emu *emu);
int dlpc900_emu_mode(const dlpc900_emu *emu);
int dlpc900_emu_running(const dlpc900_emu *emu);  /* 1 running, 2 paused, 0 stopped */
/* Configured LUT size NL and pattern count NP (0 = forever); 0 entries when not configured. */
void dlpc900_emu_lut(const dlpc900_emu *emu, int *entries, uint32_t *patterns);
/* LUT entry i as defined (-ERANGE if i ≥ 400 or undefined). */
int dlpc900_emu_lut_entry(const dlpc900_emu *emu, int i, dlpc900_lut_entry *e);
/* The 1-bit mask that LUT entry i shows, as w*h bytes 0/1 (the entry's image and bit position).
 * -ERANGE for an undefined entry, -ENOENT when its image was never loaded. */
int dlpc900_emu_mask(const dlpc900_emu *emu, int i, uint8_t *out);
/* The packed 24-bit image `index` (borrowed, NULL if not loaded) and the DMD size. */
const uint32_t *dlpc900_emu_image(const dlpc900_emu *emu, int index);
void dlpc900_emu_size(const dlpc900_emu *emu, int *w, int *h);
/* Trigger settings as last written. */
typedef struct dlpc900_emu_triggers {
    uint16_t in1_delay_us; int in1_falling; int in2_inverted;
    int out_invert[2]; int16_t out_rising_us[2], out_falling_us[2];
} dlpc900_emu_triggers;
void dlpc900_emu_triggers_get(const dlpc900_emu *emu, dlpc900_emu_triggers *t);
/* Last error code and text (also what 0x0100/0x0101 return); counts of messages and of refused ones. */
int dlpc900_emu_last_error(const dlpc900_emu *emu, const char **text);
long dlpc900_emu_messages(const dlpc900_emu *emu);
long dlpc900_emu_refused(const dlpc900_emu *emu);
/* Tolerated oddities seen while decoding images (see dlpc900_image_info.warnings). */
int dlpc900_emu_warnings(const dlpc900_emu *emu);

/* Which LUT entry is displayed `t_ns` after start under internal timing (exposure, then dark; entries that wait
 * for TRIG_IN_1 are treated as triggered at once). Returns the entry (≥ 0), -1 during a dark time, -2 after a
 * finite sequence ended, -ENODATA when not running. *pass (may be NULL) receives the pass number. */
int dlpc900_emu_displayed_at(const dlpc900_emu *emu, int64_t t_ns, long *pass);

#endif
