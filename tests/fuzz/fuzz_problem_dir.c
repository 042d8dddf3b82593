/* libFuzzer target: the problem-folder reader (io/problem_dir.h, io/image.h's stack sidecars) and its limits.
 *
 * A folder is made once with valid 8×8 frames (mask_000.exr, mask_001.exr, meas_000.exr, truth_000/001.exr); each
 * input supplies the JSON: problem.json, mask.json, meas.json and truth.json, separated by lines "--" (missing
 * parts keep their valid originals). So the fuzzer explores manifests and sidecars that lie about sizes, counts,
 * names and types, against real image files. The limits are lowered to 64 MB. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "io/limits.h"
#include "io/problem_dir.h"

static char dir[64];
static const char *const parts[4] = {"problem.json", "mask.json", "meas.json", "truth.json"};
static char *orig[4];

static char *slurp(const char *p)
{
    FILE *f = fopen(p, "rb");
    if (!f)
        abort();
    char *b = calloc(1, 1 << 16);
    size_t n = fread(b, 1, (1 << 16) - 1, f);
    b[n] = 0;
    fclose(f);
    return b;
}

static void make_folder(void)
{
    snprintf(dir, sizeof dir, "/tmp/scicap-fuzz-dir-XXXXXX");
    if (!mkdtemp(dir))
        abort();
    sci_problem *p = calloc(1, sizeof *p);
    sci_error err = {0};
    if (!p || sci_cube_new(&p->mask, 8, 8, 2, &err) < 0 || sci_cube_new(&p->meas, 8, 8, 1, &err) < 0 ||
        sci_cube_new(&p->truth, 8, 8, 2, &err) < 0)
        abort();
    for (int i = 0; i < 128; i++)
        p->mask->data[i] = (float)(i & 1), p->truth->data[i] = (float)(i % 13) / 13;
    p->peak = 1;
    snprintf(p->name, sizeof p->name, "fuzz");
    char sub[128];
    snprintf(sub, sizeof sub, "%s/p", dir);
    if (sci_problem_dir_write_opt(sub, &p, 1, NULL, 1, 0, &err) < 0)
        abort();
    sci_problem_free(p);
    for (int i = 0; i < 4; i++) {
        char path[192];
        snprintf(path, sizeof path, "%s/p/%s", dir, parts[i]);
        orig[i] = slurp(path);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!dir[0])
        make_folder();
    const char *text[4] = {orig[0], orig[1], orig[2], orig[3]};
    size_t len[4] = {strlen(orig[0]), strlen(orig[1]), strlen(orig[2]), strlen(orig[3])};
    const char *s = (const char *)data, *end = s + size;
    for (int i = 0; i < 4 && s <= end; i++) {
        const char *sep = memmem(s, (size_t)(end - s), "\n--\n", 4);
        const char *stop = sep ? sep : end;
        text[i] = s, len[i] = (size_t)(stop - s);
        if (!sep)
            break;
        s = sep + 4;
    }
    for (int i = 0; i < 4; i++) {
        char path[192];
        snprintf(path, sizeof path, "%s/p/%s", dir, parts[i]);
        FILE *f = fopen(path, "wb");
        if (!f || fwrite(text[i], 1, len[i], f) != len[i] || fclose(f) != 0)
            abort();
    }
    sci_io_limits lim = {.input_bytes = 64u << 20, .output_bytes = 64u << 20, .output_files = 1000};
    sci_error err = {0};
    sci_problem **p = NULL;
    int k = 0;
    char sub[128];
    snprintf(sub, sizeof sub, "%s/p", dir);
    if (sci_problem_dir_read_opts(sub, &lim, &p, &k, &err) == 0)
        sci_problem_array_free(p, k);
    int cfa = 0, kc = 0;
    sci_cube **rgb = NULL;
    if (sci_problem_dir_read_color(sub, &cfa, &rgb, &kc, &err) == 0 && rgb) {
        for (int j = 0; j < kc; j++)
            sci_cube_free(rgb[j]);
        free(rgb);
    }
    return 0;
}
