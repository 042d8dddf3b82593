/* bench_dlpc900 — ERLE encode time for 24 masks at 1920×1080 (random, 4×4 and 8×8 super-pixels) and the upload
 * cost of a mask set: bytes on the wire and estimated upload time, measured by programming the in-process
 * emulator through the real driver (dlpc900_ctl) and counting reports.
 *
 * Upload time model (TI DLPU018's limits, not confirmed on hardware): a full-speed USB HID
 * interrupt OUT endpoint moves one 64-byte report per 1 ms frame, i.e. 8 ms per 512-byte message. The in-process
 * time is the host-side cost (packing, encoding, framing, emulator decode) and is a lower bound.
 * Writes bench/results/dlpc900.md. Timings are wall-clock on a shared machine: noisy.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/rng.h"
#include "base/runtime_env.h"
#include "drivers/dlpc900_ctl.h"
#include "drivers/dlpc900_emu.h"
#include "drivers/dlpc900_erle.h"
#include "drivers/dlpc900_image.h"

enum { W = 1920, H = 1080, RUNS = 5 };
#define MS_PER_REPORT 1.0

/* One packed image of 24 masks: block = 1 random per pixel, else random per block×block super-pixel. */
static void make_image(uint32_t *px, int block, sci_rng *rng)
{
    if (block == 1) {
        for (size_t i = 0; i < (size_t)W * H; i++)
            px[i] = (uint32_t)sci_rng_u64(rng) & 0xFFFFFFu;
        return;
    }
    int bw = (W + block - 1) / block;
    for (int y = 0; y < H; y += block) {
        uint32_t *row = px + (size_t)y * W;
        for (int bx = 0; bx < bw; bx++) {
            uint32_t v = (uint32_t)sci_rng_u64(rng) & 0xFFFFFFu;
            for (int x = bx * block; x < (bx + 1) * block && x < W; x++)
                row[x] = v;
        }
        for (int yy = y + 1; yy < y + block && yy < H; yy++)
            memcpy(px + (size_t)yy * W, row, (size_t)W * sizeof *px);
    }
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

typedef struct row {
    const char *name;
    double enc_ms, enc_min_ms;
    size_t erle_bytes, file_bytes;
    int compression;
    int masks;
    long reports, messages;
    double host_s;
} row;

static int upload_cost(int block, int masks, row *r, sci_error *err)
{
    int nimg = (masks + 23) / 24;
    uint32_t *pix = malloc((size_t)nimg * W * H * sizeof *pix);
    const uint32_t *images[17];
    uint32_t exp[400], dark[400];
    sci_rng rng;
    sci_rng_seed(&rng, 12345, (uint64_t)block);
    for (int i = 0; i < nimg; i++) {
        make_image(pix + (size_t)i * W * H, block, &rng);
        images[i] = pix + (size_t)i * W * H;
    }
    for (int j = 0; j < masks; j++) {
        exp[j] = 500;
        dark[j] = 0;
    }
    dlpc900_emu *emu;
    dlpc900_ctl *ctl;
    int rc = dlpc900_emu_new(&emu, NULL, err);
    if (rc < 0)
        goto out;
    if ((rc = dlpc900_ctl_new(&ctl, dlpc900_emu_transport(emu), "bench", 100, err)) < 0)
        goto out_emu;
    dlpc900_sequence s = {.count = masks, .exposure_us = exp, .dark_us = dark};
    int64_t t0 = sci_clock_mono_ns();
    rc = dlpc900_ctl_program(ctl, images, W, H, &s, err);
    r->host_s = sci_clock_s(t0, sci_clock_mono_ns());
    dlpc900_traffic t;
    dlpc900_ctl_traffic(ctl, &t);
    r->reports = t.reports_out + t.reports_in;
    r->messages = t.messages;
    r->masks = masks;
    dlpc900_ctl_free(ctl);
out_emu:
    dlpc900_emu_free(emu);
out:
    free(pix);
    return rc;
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* the BLAS kernels and OpenMP waiting that scicap and scicapd run with */
    static const struct { const char *name; int block; } kinds[] = {{"random", 1}, {"4×4 super-pixel", 4},
                                                                   {"8×8 super-pixel", 8}};
    uint32_t *px = malloc((size_t)W * H * sizeof *px);
    size_t cap = dlpc900_erle_bound(W, H);
    uint8_t *buf = malloc(cap);
    row rows[3], up[3][2];
    sci_error err = {0};
    printf("bench_dlpc900: 24 masks at %d×%d per image, %d runs each (shared 2-core machine: timings noisy)\n", W, H,
           RUNS);
    for (int k = 0; k < 3; k++) {
        sci_rng rng;
        sci_rng_seed(&rng, 2024, (uint64_t)k);
        make_image(px, kinds[k].block, &rng);
        double t[RUNS];
        long n = 0;
        for (int i = 0; i < RUNS; i++) {
            int64_t t0 = sci_clock_mono_ns();
            n = dlpc900_erle_encode(px, W, H, buf, cap);
            t[i] = sci_clock_s(t0, sci_clock_mono_ns()) * 1e3;
        }
        qsort(t, RUNS, sizeof t[0], cmp_double);
        uint8_t *file;
        size_t len;
        int comp;
        if (n < 0 || dlpc900_image_encode(px, W, H, &file, &len, &comp, &err) < 0) {
            fprintf(stderr, "bench_dlpc900: encode failed: %s\n", err.msg);
            return 1;
        }
        free(file);
        rows[k] = (row){.name = kinds[k].name, .enc_ms = t[RUNS / 2], .enc_min_ms = t[0], .erle_bytes = (size_t)n,
                        .file_bytes = len, .compression = comp};
        printf("  ERLE encode %-16s median %7.2f ms (min %7.2f)  ERLE %9zu B, sent %9zu B (%s)\n", kinds[k].name,
               t[RUNS / 2], t[0], (size_t)n, len, comp == 2 ? "ERLE" : "uncompressed");
        for (int m = 0; m < 2; m++) {
            int masks = m == 0 ? 24 : 400;
            if (upload_cost(kinds[k].block, masks, &up[k][m], &err) < 0) {
                fprintf(stderr, "bench_dlpc900: upload %s ×%d failed: %s\n", kinds[k].name, masks, err.msg);
                return 1;
            }
            up[k][m].name = kinds[k].name;
            printf("  upload %-16s %3d masks: %6ld messages, %7ld reports = %10ld B on the wire, est. %7.1f s at "
                   "1 report/ms; host side %.2f s\n", kinds[k].name, masks, up[k][m].messages, up[k][m].reports,
                   up[k][m].reports * 64, up[k][m].reports * MS_PER_REPORT / 1e3, up[k][m].host_s);
        }
    }
    FILE *f = fopen("bench/results/dlpc900.md", "w");
    if (!f) {
        perror("bench/results/dlpc900.md");
        return 1;
    }
    fprintf(f, "### DLPC900 mask upload (bench_dlpc900)\n\n"
               "24 one-bit masks packed per 24-bit image, 1920×1080. ERLE encode: median of %d runs (shared 2-core "
               "machine, noisy). \"Sent\" is the image file the device receives (48-byte header + ERLE, or "
               "uncompressed rows when ERLE would be larger, as TI's GUI does).\n\n", RUNS);
    fprintf(f, "| masks | ERLE encode (ms) | ERLE bytes | sent bytes | format |\n|---|---:|---:|---:|---|\n");
    for (int k = 0; k < 3; k++)
        fprintf(f, "| %s | %.1f | %zu | %zu | %s |\n", rows[k].name, rows[k].enc_ms, rows[k].erle_bytes,
                rows[k].file_bytes, rows[k].compression == 2 ? "ERLE" : "uncompressed");
    fprintf(f, "\nUpload cost, counted by programming the emulator through the driver (every command of the "
               "sequence, in both directions). Estimated time assumes one 64-byte report per 1 ms USB frame "
               "(8 ms per 512-byte message; real DLPC900 throughput UNCONFIRMED). Host time is the in-process "
               "cost (pack, encode, frame, emulator decode).\n\n");
    fprintf(f, "| masks | N | messages | reports | bytes on the wire | est. upload (s) | host (s) |\n"
               "|---|---:|---:|---:|---:|---:|---:|\n");
    for (int k = 0; k < 3; k++)
        for (int m = 0; m < 2; m++)
            fprintf(f, "| %s | %d | %ld | %ld | %ld | %.1f | %.2f |\n", up[k][m].name, up[k][m].masks,
                    up[k][m].messages, up[k][m].reports, up[k][m].reports * 64,
                    up[k][m].reports * MS_PER_REPORT / 1e3, up[k][m].host_s);
    fclose(f);
    printf("  wrote bench/results/dlpc900.md\n");
    free(buf);
    free(px);
    return 0;
}
