/* sim/dmd_sim.h — the simulated DMD: the DLPC900 emulator behind the dmd_ops interface.
 *
 * The "sim" backend runs the real dlpc900 backend (same command order, same checks) against an in-process
 * dlpc900_emu, so the daemon cannot tell it from hardware, and adds what a simulator needs: which mask is on
 * the mirrors at a given time, and the mask itself.
 *
 *     dmd *dev;
 *     dmd_config cfg = dmd_config_default();
 *     cfg.width = 256; cfg.height = 256;          // 0 = 1920×1080
 *     dmd_open(&dev, &dmd_sim_ops, &cfg, &err);
 *     dmd_upload(dev, masks, &err); dmd_start(dev, &err);
 *     int k = dmd_sim_displayed_at(dev, t_ns);    // t_ns after start → mask index, -1 dark, -2 finished
 *
 * Timing model: internal timing (exposure then dark time per pattern, sequence repeated `passes` times or
 * forever). In external-trigger mode the simulator assumes each trigger arrives as the previous pattern's
 * exposure + dark time ends (the camera simulator drives the trigger at that pace).
 * Serial: cfg->serial or "SIM0001". Not thread-safe: one thread per dmd, like every backend.
 */
#ifndef SCICAP_SIM_DMD_SIM_H
#define SCICAP_SIM_DMD_SIM_H

#include <stdint.h>

#include "drivers/dlpc900_emu.h"
#include "drivers/dmd.h"

extern const dmd_ops dmd_sim_ops;

/* The following take a dmd opened with dmd_sim_ops; -EINVAL for any other backend. */

/* Mask index displayed t_ns after the last start (≥ 0), -1 in a dark time, -2 after a finite sequence ended,
 * -ENODATA when not running. */
int dmd_sim_displayed_at(const dmd *d, int64_t t_ns);
/* CLOCK_MONOTONIC time of the last successful start, ns (0 if never started). */
int64_t dmd_sim_started_ns(const dmd *d);
/* Mask `index` as loaded on the (emulated) device, w*h bytes 0/1. -ERANGE / -ENOENT as dlpc900_emu_mask. */
int dmd_sim_mask(const dmd *d, int index, uint8_t *out);
/* The emulator inside (borrowed; lives as long as the dmd): for fault injection in tests. NULL if not sim. */
dlpc900_emu *dmd_sim_emulator(const dmd *d);

#endif
