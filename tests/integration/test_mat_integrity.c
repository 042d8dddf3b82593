/* .mat integrity: byte flips inside drop40_cacti.mat (MATLAB v5, every variable compressed)
 * at seeded positions spread over the whole file, plus the places that matter most (header version and byte-order
 * mark, an element tag and size, the zlib header, the adler32 trailer). Every flipped file must either be refused
 * with an error that names the file, or read back bit for bit as the original (a flip in the descriptive header
 * text, say): never a silently different problem. Before the fix 13 of 17 such flips passed silently. Also: a
 * flipped numeric size in an uncompressed v5 variable is refused by the structure check. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>
#include <matio.h>

#include "io/mat_verify.h"
#include "io/matfile.h"
#include "tests/helpers/testdata.h"
#include "tests/helpers/testfiles.h"

static char dir[] = "/tmp/scicap-test-mat-integrity-XXXXXX";

static unsigned char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    *len = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = malloc(*len);
    assert_non_null(b);
    assert_int_equal(fread(b, 1, *len, f), *len);
    fclose(f);
    return b;
}

static void spill(const char *path, const unsigned char *b, size_t len)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(b, 1, len, f), len);
    assert_int_equal(fclose(f), 0);
}

static int same_problems(sci_problem **a, int ka, sci_problem **b, int kb)
{
    if (ka != kb)
        return 0;
    for (int j = 0; j < ka; j++) {
        const sci_cube *ca[3] = {a[j]->mask, a[j]->meas, a[j]->truth}, *cb[3] = {b[j]->mask, b[j]->meas, b[j]->truth};
        for (int i = 0; i < 3; i++) {
            if (!ca[i] != !cb[i])
                return 0;
            if (ca[i] && (!sci_cube_same_shape(ca[i], cb[i]) ||
                          memcmp(ca[i]->data, cb[i]->data, sci_cube_count(ca[i]) * sizeof(float)) != 0))
                return 0;
        }
    }
    return 1;
}

static uint64_t rng_next(uint64_t *s)
{
    *s ^= *s << 13, *s ^= *s >> 7, *s ^= *s << 17; /* xorshift64 */
    return *s;
}

static void test_drop40_flips_refused_or_harmless(void **state)
{
    char src[4096];
    TESTDATA_REQUIRE("drop40_cacti.mat", src);
    size_t len;
    unsigned char *orig = slurp(src, &len);
    sci_problem **ref = NULL;
    int kref = 0;
    sci_error err = {0};
    if (sci_mat_read(src, 255, &ref, &kref, &err) < 0)
        fail_msg("%s", err.msg);
    /* fixed positions: header text, subsystem offset, version, byte-order mark, first tag (type, size), zlib
     * header, inside the first stream, the last 4 bytes (adler32 of the last variable) */
    size_t pos[96];
    int npos = 0;
    const size_t fixed[] = {3, 117, 124, 125, 126, 127, 128, 131, 132, 134, 136, 137, 140, 4000, len - 4, len - 1};
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++)
        pos[npos++] = fixed[i];
    uint64_t seed = 0x5c1ca917ULL;
    print_message("seed 0x%llx, %zu bytes\n", (unsigned long long)seed, len);
    while (npos < (int)(sizeof pos / sizeof pos[0]))
        pos[npos++] = 128 + rng_next(&seed) % (len - 128);
    int refused = 0, harmless = 0;
    char path[512];
    snprintf(path, sizeof path, "%s/flip.mat", dir);
    for (int i = 0; i < npos; i++) {
        unsigned char *b = malloc(len);
        assert_non_null(b);
        memcpy(b, orig, len);
        const unsigned char x = (unsigned char)(1 + rng_next(&seed) % 255);
        b[pos[i]] ^= x;
        spill(path, b, len);
        free(b);
        sci_problem **p = NULL;
        int k = 0;
        sci_error e = {0};
        if (sci_mat_read(path, 255, &p, &k, &e) < 0) {
            if (!strstr(e.msg, path))
                fail_msg("flip of byte %zu (^0x%02x) refused without naming the file: '%s'", pos[i], x, e.msg);
            refused++;
            continue;
        }
        const int same = same_problems(ref, kref, p, k);
        sci_problem_array_free(p, k);
        if (!same)
            fail_msg("flip of byte %zu (^0x%02x) read silently as a different problem", pos[i], x);
        harmless++;
    }
    print_message("%d flips: %d refused, %d read back identical\n", npos, refused, harmless);
    assert_int_equal(refused + harmless, npos);
    assert_true(refused >= npos - 8); /* only the header text and subsystem bytes may be harmless */
    sci_problem_array_free(ref, kref);
    free(orig);
}

/* An uncompressed v5 file (matio, no compression) with its data size byte flipped is refused by the structure
 * check; a flip in its numbers cannot be detected (no checksum in the format) and is documented as such. */
static void test_uncompressed_size_flip_refused(void **state)
{
    char path[512];
    snprintf(path, sizeof path, "%s/plain.mat", dir);
    mat_t *m = Mat_CreateVer(path, NULL, MAT_FT_MAT5);
    assert_non_null(m);
    double d[4 * 4 * 2];
    for (int i = 0; i < 32; i++)
        d[i] = i;
    size_t dims[3] = {4, 4, 2};
    testfiles_mat_put(m, "mask", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, d, MAT_COMPRESSION_NONE);
    size_t dm[2] = {4, 4};
    testfiles_mat_put(m, "meas", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dm, d, MAT_COMPRESSION_NONE);
    Mat_Close(m);
    sci_error err = {0};
    if (sci_mat_verify(path, &err) < 0)
        fail_msg("a clean uncompressed file is refused: %s", err.msg);
    size_t len;
    unsigned char *b = slurp(path, &len);
    /* the first variable's real-part tag: header 128 + matrix tag 8 + flags 16 + dims 8+16 + name "mask" as a
     * small element 8 = 184; its byte count (256) is at 188 */
    assert_int_equal(b[188], 0x00);
    assert_int_equal(b[189], 0x01);
    b[188] ^= 0x08;
    spill(path, b, len);
    free(b);
    sci_problem **p = NULL;
    int k = 0;
    int rc = sci_mat_read(path, 255, &p, &k, &err);
    if (rc == 0)
        sci_problem_array_free(p, k);
    assert_int_equal(rc, SCI_EFORMAT);
    assert_non_null(strstr(err.msg, "plain.mat"));
}

static int setup(void **state) { return mkdtemp(dir) ? 0 : -1; }

static int teardown(void **state)
{
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_drop40_flips_refused_or_harmless),
        cmocka_unit_test(test_uncompressed_size_flip_refused),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
