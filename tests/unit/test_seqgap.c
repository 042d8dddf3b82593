/* Drop counting from sequence gaps, including the 32-bit wrap, repeats and restarts, and a seeded random
 * stream whose true losses are known. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include <cmocka.h>

#include "base/rng.h"
#include "drivers/seqgap.h"

static uint64_t g_seed;

static void consecutive_frames_lose_nothing(void **state)
{
    (void)state;
    seqgap g;
    seqgap_reset(&g);
    for (uint32_t s = 100; s < 200; s++)
        assert_int_equal(seqgap_push(&g, s), 0);
    assert_int_equal(g.frames, 100);
    assert_int_equal(g.lost, 0);
}

static void gaps_are_counted(void **state)
{
    (void)state;
    seqgap g;
    seqgap_reset(&g);
    assert_int_equal(seqgap_push(&g, 5), 0); /* first frame: nothing known before it */
    assert_int_equal(seqgap_push(&g, 6), 0);
    assert_int_equal(seqgap_push(&g, 9), 2);
    assert_int_equal(seqgap_push(&g, 10), 0);
    assert_int_equal(seqgap_push(&g, 20), 9);
    assert_int_equal(g.lost, 11);
    assert_int_equal(g.gaps, 2);
}

static void wrap_around_is_not_a_loss(void **state)
{
    (void)state;
    seqgap g;
    seqgap_reset(&g);
    seqgap_push(&g, 0xFFFFFFFEu);
    assert_int_equal(seqgap_push(&g, 0xFFFFFFFFu), 0);
    assert_int_equal(seqgap_push(&g, 0u), 0);
    assert_int_equal(seqgap_push(&g, 1u), 0);
    assert_int_equal(g.lost, 0);
    /* a gap that straddles the wrap: 0xFFFFFFFD -> 2 loses FE, FF, 0, 1 */
    seqgap_reset(&g);
    seqgap_push(&g, 0xFFFFFFFDu);
    assert_int_equal(seqgap_push(&g, 2u), 4);
    assert_int_equal(g.resets, 0);
    assert_int_equal(seqgap_between(0xFFFFFFF0u, 0x10u), 0x1F);
}

static void repeats_and_restarts(void **state)
{
    (void)state;
    seqgap g;
    seqgap_reset(&g);
    seqgap_push(&g, 1000);
    assert_int_equal(seqgap_push(&g, 1000), 0);
    assert_int_equal(g.repeats, 1);
    assert_int_equal(seqgap_push(&g, 0), 0); /* the driver restarted its count */
    assert_int_equal(g.resets, 1);
    assert_int_equal(seqgap_push(&g, 2), 1);
    assert_int_equal(g.lost, 1);
    assert_int_equal(seqgap_between(7, 7), 0);
    assert_int_equal(seqgap_between(8, 7), 0);
}

static void random_stream_with_known_losses(void **state)
{
    (void)state;
    sci_rng rng;
    sci_rng_seed(&rng, g_seed, 3);
    for (int trial = 0; trial < 50; trial++) {
        seqgap g;
        seqgap_reset(&g);
        uint32_t s = (uint32_t)sci_rng_u64(&rng);
        if (trial % 5 == 0)
            s = 0xFFFFFFFFu - (uint32_t)sci_rng_below(&rng, 50); /* start just before the wrap */
        uint64_t truth = 0;
        seqgap_push(&g, s);
        for (int i = 0; i < 1000; i++) {
            uint32_t lose = sci_rng_uniform(&rng) < 0.1 ? (uint32_t)sci_rng_below(&rng, 5) : 0;
            s += lose + 1;
            truth += lose;
            assert_int_equal(seqgap_push(&g, s), lose);
        }
        assert_int_equal(g.lost, truth);
        assert_int_equal(g.frames, 1001);
    }
}

int main(void)
{
    const char *e = getenv("SCICAP_TEST_SEED");
    g_seed = e ? strtoull(e, NULL, 0) : 77u;
    printf("test_seqgap: seed %llu (set SCICAP_TEST_SEED to change)\n", (unsigned long long)g_seed);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(consecutive_frames_lose_nothing),
        cmocka_unit_test(gaps_are_counted),
        cmocka_unit_test(wrap_around_is_not_a_loss),
        cmocka_unit_test(repeats_and_restarts),
        cmocka_unit_test(random_stream_with_known_losses),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
