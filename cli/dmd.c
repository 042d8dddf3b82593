/* cli/dmd.c — `scicap dmd`: list DLPC900 devices, show status, upload masks, start, stop.
 *
 * Commands run in the order given on one open device, so a whole session fits one line — necessary with
 * --emulate, whose in-process emulator lives only as long as the command:
 *     scicap dmd --emulate --exposure-us 500 generate blocky8:48 upload status start status stop
 * Mask files: binary netpbm (P4 bitmap or P5 greymap, several images concatenated in one file; in P5 a value
 * above maxval/2 is "on"), a scicap stack sidecar (.json, io/image.h), or any image io/image.h reads (a
 * multi-page TIFF gives one mask per page; a value above half the bit depth's maximum is "on").
 */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/log.h"
#include "base/rng.h"
#include "cli/commands.h"
#include "drivers/dlpc900_emu.h"
#include "drivers/dlpc900_hid.h"
#include "drivers/dmd.h"
#include "io/image.h"

static void usage(FILE *f)
{
    fputs("usage: scicap dmd [options] command [command ...]\n"
          "Drive a TI DLPC900 (DLP LightCrafter 6500) in pattern-on-the-fly mode. Commands run in order on one\n"
          "open device.\n\n"
          "commands:\n"
          "  list                  DLPC900 devices on USB (serial, hidraw path, interface)\n"
          "  status                identity, running state, device error code and text\n"
          "  upload FILE           upload masks from FILE (.pbm/.pgm netpbm stack, .json stack sidecar, or an\n"
          "                        image/multi-page TIFF readable by io/image)\n"
          "  generate KIND:N       upload N generated masks; KIND = random, blocky4, blocky8, zeros, ones\n"
          "  start                 start the sequence (needs an upload)\n"
          "  stop                  stop the sequence\n\n"
          "options:\n"
          "  --emulate             use the in-process DLPC900 emulator instead of USB\n"
          "  --serial S            the device with USB serial S (default: the first one)\n"
          "  --exposure-us N       exposure per pattern, µs (default 1000; ≥ 105 on a DLP6500)\n"
          "  --dark-us N           dark time after each pattern, µs (default 0)\n"
          "  --trigger MODE        internal (default) or external (each pattern waits for TRIG_IN_1)\n"
          "  --passes N            times the sequence is shown per start, 0 = until stop (default 0)\n"
          "  --timeout-ms N        reply timeout (default 1000)\n"
          "  --seed N              seed for generate (default 1)\n"
          "  -h, --help            this text\n",
          f);
}

/* ---- netpbm mask stacks ---- */

static int pnm_token(FILE *f, long *v)
{
    int c;
    do {
        c = fgetc(f);
        if (c == '#')
            while (c != '\n' && c != EOF)
                c = fgetc(f);
    } while (c == ' ' || c == '\t' || c == '\n' || c == '\r');
    if (c < '0' || c > '9')
        return -1;
    long x = 0;
    while (c >= '0' && c <= '9') {
        x = x * 10 + (c - '0');
        if (x > 1 << 20)
            return -1;
        c = fgetc(f);
    }
    *v = x; /* the single whitespace after the last header token is consumed here */
    return 0;
}

static int read_pnm(const char *path, sci_cube **out, sci_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return sci_error_set(err, -errno, "%s: %s", path, strerror(errno));
    int w = 0, h = 0, n = 0, cap = 0, rc = 0;
    float *data = NULL;
    for (;;) {
        int c0 = fgetc(f), c1 = fgetc(f);
        if (c0 == EOF)
            break;
        long iw, ih, maxv = 1;
        int pbm = c0 == 'P' && c1 == '4', pgm = c0 == 'P' && c1 == '5';
        if ((!pbm && !pgm) || pnm_token(f, &iw) < 0 || pnm_token(f, &ih) < 0 || (pgm && pnm_token(f, &maxv) < 0) ||
            iw < 1 || ih < 1 || maxv < 1 || maxv > 255) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s: image %d: not a binary PBM (P4) or 8-bit PGM (P5)", path, n);
            goto out;
        }
        if (n == 0) {
            w = (int)iw;
            h = (int)ih;
        } else if (iw != w || ih != h) {
            rc = sci_error_set(err, SCI_ESHAPE, "%s: image %d is %ld×%ld, the first is %d×%d", path, n, iw, ih, w, h);
            goto out;
        }
        if (n == cap) {
            cap = cap ? 2 * cap : 8;
            float *nd = realloc(data, (size_t)cap * w * h * sizeof *nd);
            if (!nd) {
                rc = sci_error_set(err, -ENOMEM, "%s: out of memory at image %d", path, n);
                goto out;
            }
            data = nd;
        }
        float *fr = data + (size_t)n * w * h;
        size_t rowbytes = pbm ? ((size_t)w + 7) / 8 : (size_t)w;
        unsigned char *row = malloc(rowbytes);
        for (int y = 0; y < h && rc == 0; y++) {
            if (fread(row, 1, rowbytes, f) != rowbytes) {
                rc = sci_error_set(err, SCI_EFORMAT, "%s: image %d truncated at row %d", path, n, y);
                break;
            }
            for (int x = 0; x < w; x++)
                fr[(size_t)y * w + x] = pbm ? (float)((row[x / 8] >> (7 - x % 8)) & 1) : (float)(row[x] * 2 > maxv);
        }
        free(row);
        if (rc)
            goto out;
        n++;
    }
    if (n == 0) {
        rc = sci_error_set(err, SCI_EFORMAT, "%s: no images", path);
        goto out;
    }
    if ((rc = sci_cube_new(out, w, h, n, err)) == 0)
        memcpy((*out)->data, data, (size_t)n * w * h * sizeof *data);
out:
    free(data);
    fclose(f);
    return rc;
}

static int read_masks(const char *path, sci_cube **out, sci_error *err)
{
    const char *dot = strrchr(path, '.');
    if (dot && (!strcmp(dot, ".pbm") || !strcmp(dot, ".pgm") || !strcmp(dot, ".pnm")))
        return read_pnm(path, out, err);
    if (dot && !strcmp(dot, ".json"))
        return sci_stack_read(path, out, NULL, err);
    int bits = 8;
    int rc = sci_image_read(path, out, &bits, err);
    if (rc < 0)
        return rc;
    /* Stored values 0…2^bits−1 (float files as they are): "on" above half the range. */
    float half = bits >= 32 ? 0.5f : (float)((1u << bits) - 1) / 2.0f;
    for (size_t i = 0; i < sci_cube_count(*out); i++)
        (*out)->data[i] = (*out)->data[i] > half ? 1.0f : 0.0f;
    return 0;
}

static int generate_masks(const char *spec, int w, int h, uint64_t seed, sci_cube **out, sci_error *err)
{
    char kind[32];
    int n = 0;
    const char *colon = strchr(spec, ':');
    if (!colon || colon - spec >= (long)sizeof kind || sscanf(colon + 1, "%d", &n) != 1 || n < 1 || n > 400)
        return sci_error_set(err, -EINVAL, "generate %s: expected KIND:N with 1 ≤ N ≤ 400", spec);
    memcpy(kind, spec, (size_t)(colon - spec));
    kind[colon - spec] = 0;
    int block = !strcmp(kind, "random") ? 1 : !strcmp(kind, "blocky4") ? 4 : !strcmp(kind, "blocky8") ? 8 : 0;
    int fill = !strcmp(kind, "ones") ? 1 : !strcmp(kind, "zeros") ? 0 : -1;
    if (!block && fill < 0)
        return sci_error_set(err, -EINVAL, "generate: unknown kind \"%s\" (random, blocky4, blocky8, zeros, ones)", kind);
    int rc = sci_cube_new(out, w, h, n, err);
    if (rc < 0)
        return rc;
    sci_rng rng;
    sci_rng_seed(&rng, seed, 0);
    for (int k = 0; k < n; k++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                float v = (float)fill;
                if (block) {
                    /* one random bit per block, drawn when the block's top-left pixel is reached */
                    float *fr = sci_cube_frame(*out, k);
                    if (x % block == 0 && y % block == 0)
                        v = (float)(sci_rng_u64(&rng) & 1);
                    else
                        v = fr[(size_t)(y - y % block) * w + (x - x % block)];
                }
                sci_cube_frame(*out, k)[(size_t)y * w + x] = v;
            }
    return 0;
}

static void on_event(void *user, dmd_event ev, const char *serial)
{
    printf("dmd: DLPC900 %s %s\n", serial, ev == DMD_EVENT_CONNECTED ? "connected" : "disconnected");
}

static int cmd_list(void)
{
    dlpc900_hid_info info[16];
    int n = 0;
    sci_error err = {0};
    if (dlpc900_hid_list(info, 16, &n, &err) < 0) {
        fprintf(stderr, "scicap dmd: %s\n", err.msg);
        return 1;
    }
    printf("%d DLPC900 HID interface(s)\n", n);
    for (int i = 0; i < n && i < 16; i++)
        printf("  serial %-16s %s  interface %d  %s\n", info[i].serial[0] ? info[i].serial : "(none)", info[i].path,
               info[i].interface_number, info[i].product);
    return 0;
}

static void print_status(dmd *dev)
{
    dmd_identity id;
    dmd_status st;
    sci_error err = {0};
    if (dmd_identify(dev, &id, &err) == 0)
        printf("%s %s serial %s firmware %s, %d×%d mirrors, up to %d masks, min exposure %d µs\n", id.backend,
               id.model, id.serial, id.firmware, id.width, id.height, id.max_masks, id.min_exposure_us);
    if (dmd_status_get(dev, &st, &err) < 0) {
        printf("status: %s\n", err.msg);
        return;
    }
    printf("status: %s, %s, %d masks loaded, %s\n", st.connected ? "connected" : "disconnected",
           st.running ? "running" : "stopped", st.loaded_masks, st.error_code || st.error_text[0] ? st.error_text : "no error");
}

typedef struct opts {
    int emulate, timeout_ms;
    const char *serial;
    dmd_timing timing;
    uint64_t seed;
} opts;

static int parse_uint(const char *opt, const char *s, unsigned long max, unsigned long *v)
{
    char *end;
    errno = 0;
    unsigned long x = strtoul(s ? s : "", &end, 10);
    if (!s || !*s || *end || errno || x > max || s[0] == '-') {
        fprintf(stderr, "scicap dmd: %s needs an integer 0…%lu (got \"%s\")\n", opt, max, s ? s : "");
        return -1;
    }
    *v = x;
    return 0;
}

/* Parses the options before the first command into o. Returns -1 to go on, else the exit code (0 after --help, 2
 * on a bad option). */
static int cli_dmd_opts_parse(opts *o, int argc, char **argv)
{
    unsigned long v;
    /* "+": options end at the first command word (commands take their own arguments, e.g. upload FILE). */
    enum { D_EMULATE = 300, D_SERIAL, D_EXPOSURE, D_DARK, D_PASSES, D_TIMEOUT, D_SEED, D_TRIGGER };
    static const struct option dmd_opts[] = {
        {"emulate", no_argument, 0, D_EMULATE},         {"serial", required_argument, 0, D_SERIAL},
        {"exposure-us", required_argument, 0, D_EXPOSURE}, {"dark-us", required_argument, 0, D_DARK},
        {"passes", required_argument, 0, D_PASSES},     {"timeout-ms", required_argument, 0, D_TIMEOUT},
        {"seed", required_argument, 0, D_SEED},         {"trigger", required_argument, 0, D_TRIGGER},
        {"help", no_argument, 0, 'h'},                  {0, 0, 0, 0},
    };
    optind = 1;
    int oc, li = 0;
    while ((oc = getopt_long(argc, argv, "+h", dmd_opts, &li)) != -1) {
        char a[48];
        snprintf(a, sizeof a, "--%s", dmd_opts[li].name);
        switch (oc) {
        case 'h': usage(stdout); return 0;
        case D_EMULATE: o->emulate = 1; break;
        case D_SERIAL: o->serial = optarg; break;
        case D_EXPOSURE:
            if (parse_uint(a, optarg, 16777215, &v) < 0)
                return 2;
            o->timing.exposure_us = (uint32_t)v;
            break;
        case D_DARK:
            if (parse_uint(a, optarg, 16777215, &v) < 0)
                return 2;
            o->timing.dark_us = (uint32_t)v;
            break;
        case D_PASSES:
            if (parse_uint(a, optarg, 1000000, &v) < 0)
                return 2;
            o->timing.passes = (uint32_t)v;
            break;
        case D_TIMEOUT:
            if (parse_uint(a, optarg, 60000, &v) < 0 || v == 0)
                return 2;
            o->timeout_ms = (int)v;
            break;
        case D_SEED:
            if (parse_uint(a, optarg, 0xFFFFFFFFul, &v) < 0)
                return 2;
            o->seed = v;
            break;
        case D_TRIGGER:
            if (!strcmp(optarg, "internal"))
                o->timing.trigger = DMD_TRIGGER_INTERNAL;
            else if (!strcmp(optarg, "external"))
                o->timing.trigger = DMD_TRIGGER_EXTERNAL;
            else {
                fprintf(stderr, "scicap dmd: --trigger is internal or external (got \"%s\")\n", optarg);
                return 2;
            }
            break;
        default: fprintf(stderr, "scicap dmd: see --help\n"); return 2;
        }
    }
    return -1;
}

/* Checks the commands argv[first..argc) before a device is touched. Returns 0, or 2 after a message. */
static int cli_dmd_commands_check(int argc, char **argv, int first)
{
    for (int i = first; i < argc; i++) {
        const char *c = argv[i];
        if (!strcmp(c, "upload") || !strcmp(c, "generate")) {
            if (i + 1 >= argc) {
                fprintf(stderr, "scicap dmd: %s needs an argument\n", c);
                return 2;
            }
            i++;
        } else if (strcmp(c, "list") && strcmp(c, "status") && strcmp(c, "start") && strcmp(c, "stop")) {
            fprintf(stderr, "scicap dmd: unknown command \"%s\" (see --help)\n", c);
            return 2;
        }
    }
    return 0;
}

/* upload FILE or generate KIND:N, sized to the device. Returns 0 or -errno with err filled. */
static int cli_dmd_upload(dmd *dev, const char *c, const char *arg, uint64_t seed, sci_error *err)
{
    sci_cube *masks = NULL;
    dmd_identity id;
    int rc;
    if ((rc = dmd_identify(dev, &id, err)) == 0)
        rc = !strcmp(c, "upload") ? read_masks(arg, &masks, err)
                                  : generate_masks(arg, id.width, id.height, seed, &masks, err);
    if (rc == 0) {
        rc = dmd_upload(dev, masks, err);
        if (rc == 0)
            printf("uploaded %d masks (%d×%d)\n", masks->n, masks->w, masks->h);
    }
    sci_cube_free(masks);
    return rc;
}

/* Runs argv[*i] (and its argument, moving *i past it) on the open device. Returns the command's result (< 0:
 * -errno with err filled); *listed_bad is set when listing the USB devices failed (its message is printed). */
static int cli_dmd_command_run(dmd *dev, dlpc900_emu *emu, const opts *o, char **argv, int *i, int *listed_bad,
                               sci_error *err)
{
    const char *c = argv[*i];
    int rc = 0;
    if (!strcmp(c, "list")) {
        if (o->emulate)
            printf("1 DLPC900 (emulated): serial %s\n", dlpc900_emu_serial(emu));
        else if (cmd_list())
            *listed_bad = 1;
    } else if (!strcmp(c, "status")) {
        print_status(dev);
    } else if (!strcmp(c, "start")) {
        if ((rc = dmd_start(dev, err)) == 0)
            printf("started\n");
    } else if (!strcmp(c, "stop")) {
        if ((rc = dmd_stop(dev, err)) == 0)
            printf("stopped\n");
    } else {
        rc = cli_dmd_upload(dev, c, argv[*i + 1], o->seed, err);
        ++*i;
    }
    return rc;
}

int cli_dmd_main(int argc, char **argv)
{
    opts o = {.timeout_ms = 1000, .timing = {.exposure_us = 1000, .trigger = DMD_TRIGGER_INTERNAL}, .seed = 1};
    int rc = cli_dmd_opts_parse(&o, argc, argv);
    if (rc >= 0)
        return rc;
    const int first_cmd = optind;
    if (first_cmd == argc) {
        usage(stderr);
        return 2;
    }
    if (cli_dmd_commands_check(argc, argv, first_cmd) != 0)
        return 2;
    if (argc - first_cmd == 1 && !strcmp(argv[first_cmd], "list") && !o.emulate)
        return cmd_list();

    sci_log log = {.fd = 2, .level = SCI_LOG_NOTICE, .tag = "scicap dmd"};
    sci_error err = {0};
    dlpc900_emu *emu = NULL;
    dmd *dev = NULL;
    int status = 1;
    if (o.emulate && dlpc900_emu_new(&emu, &(dlpc900_emu_config){.serial = o.serial ? o.serial : "EMU0001"}, &err) < 0)
        goto fail;
    dmd_config cfg = dmd_config_default();
    cfg.serial = o.serial;
    cfg.timeout_ms = o.timeout_ms;
    cfg.on_event = on_event;
    cfg.log = &log;
    cfg.emulator = emu;
    if (dmd_open(&dev, &dmd_dlpc900_ops, &cfg, &err) < 0 || dmd_set_timing(dev, &o.timing, &err) < 0)
        goto fail;
    for (int i = first_cmd; i < argc; i++) {
        int listed_bad = 0;
        rc = cli_dmd_command_run(dev, emu, &o, argv, &i, &listed_bad, &err);
        if (listed_bad)
            goto out;
        if (rc < 0)
            goto fail;
    }
    status = 0;
    goto out;
fail:
    fprintf(stderr, "scicap dmd: %s\n", err.msg);
out:
    dmd_close(dev);
    dlpc900_emu_free(emu);
    return status;
}
