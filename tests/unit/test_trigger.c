/* The trigger interface: the simulated trigger's latency, jitter (seeded), missed pulses, time-ordered inputs,
 * overflow seen as line_seqno gaps; the libgpiod backend's errors for a chip that does not exist; the config. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include <errno.h>

#include "base/clock.h"
#include "drivers/trigger_gpiod.h"
#include "sim/trigger_sim.h"

static uint64_t g_seed;

typedef struct seen {
    int n;
    int64_t t[16];
} seen;

static void on_output(void *arg, int64_t t, uint32_t w)
{
    seen *s = arg;
    (void)w;
    if (s->n < 16)
        s->t[s->n++] = t;
}

static trigger *open_sim(trigger_sim_options *opt, int wire_strobe)
{
    trigger_config tc = trigger_config_default();
    tc.output.offset = 3;
    tc.inputs[TRIGGER_ROLE_DMD].offset = 4;
    if (wire_strobe)
        tc.inputs[TRIGGER_ROLE_STROBE].offset = 5;
    tc.backend_options = opt;
    trigger *t = NULL;
    sci_error err = {0};
    if (trigger_open(&t, &trigger_sim_ops, &tc, &err) < 0)
        fail_msg("%s", err.msg);
    return t;
}

static void sim_latency_jitter_and_misses(void **state)
{
    (void)state;
    seen s = {0};
    trigger_sim_options opt = {.seed = g_seed, .latency_ns = 40000, .jitter_ns = 3000, .on_output = on_output,
                               .on_output_arg = &s};
    trigger *t = open_sim(&opt, 1);
    sci_error err = {0};
    int64_t t0, t0_first = 0;
    for (int i = 0; i < 8; i++) {
        if (i == 5)
            trigger_sim_miss_next(trigger_sim_from(t), 1);
        assert_int_equal(trigger_pulse(t, 5, &t0, &err), 0);
        if (i == 0)
            t0_first = t0;
        if (i != 5) {
            int64_t d = s.t[s.n - 1] - t0;
            assert_true(d >= 40000 && d <= 43000);
        }
    }
    assert_int_equal(s.n, 7); /* one missed */
    trigger_sim_counters c;
    trigger_sim_counters_get(trigger_sim_from(t), &c);
    assert_int_equal(c.missed, 1);
    trigger_stats st;
    trigger_stats_get(t, &st);
    assert_int_equal(st.pulses, 8);
    trigger_close(t);

    /* same seed, same delays */
    int64_t first = s.t[0] - t0_first;
    seen s2 = {0};
    opt.on_output_arg = &s2;
    t = open_sim(&opt, 1);
    int64_t t1;
    assert_int_equal(trigger_pulse(t, 5, &t1, &err), 0);
    assert_int_equal(s2.t[0] - t1, first);
    trigger_close(t);
}

static void sim_inputs_in_time_order(void **state)
{
    (void)state;
    trigger_sim_options opt = {.seed = g_seed, .queue_size = 4};
    trigger *t = open_sim(&opt, 0);
    trigger_sim *ts = trigger_sim_from(t);
    int64_t now = sci_clock_mono_ns();
    assert_int_equal(trigger_sim_inject(ts, TRIGGER_ROLE_DMD, now - 3000, 1), 0);
    assert_int_equal(trigger_sim_inject(ts, TRIGGER_ROLE_DMD, now - 5000, 1), 0); /* injected out of order */
    assert_int_equal(trigger_sim_inject(ts, TRIGGER_ROLE_STROBE, now, 1), -ENOTCONN); /* strobe not wired */
    assert_int_equal(trigger_sim_inject(ts, TRIGGER_ROLE_DMD, now + 20000000, 0), 0); /* 20 ms in the future */
    trigger_event ev[8];
    int n;
    sci_error err = {0};
    assert_int_equal(trigger_read_events(t, 0, ev, 8, &n, &err), 0);
    assert_int_equal(n, 2); /* the future edge is not visible yet */
    assert_true(ev[0].timestamp_ns == now - 5000 && ev[1].timestamp_ns == now - 3000);
    assert_int_equal(trigger_read_events(t, 100000000, ev, 8, &n, &err), 0);
    assert_int_equal(n, 1);
    assert_false(ev[0].rising);
    assert_true(sci_clock_mono_ns() >= now + 20000000);
    /* overflow: the 5th edge is lost and the next one shows the gap in line_seqno */
    for (int i = 0; i < 4; i++)
        assert_int_equal(trigger_sim_inject(ts, TRIGGER_ROLE_DMD, now + i, 1), 0);
    assert_int_equal(trigger_sim_inject(ts, TRIGGER_ROLE_DMD, now + 10, 1), -ENOSPC);
    assert_int_equal(trigger_read_events(t, 0, ev, 8, &n, &err), 0);
    assert_int_equal(n, 4);
    assert_int_equal(trigger_sim_inject(ts, TRIGGER_ROLE_DMD, now + 11, 1), 0);
    assert_int_equal(trigger_read_events(t, 0, ev, 8, &n, &err), 0);
    trigger_stats st;
    trigger_stats_get(t, &st);
    assert_int_equal(st.lost_events, 1);
    /* no output wired */
    trigger_close(t);
    trigger_config tc = trigger_config_default();
    tc.backend_options = &opt;
    assert_int_equal(trigger_open(&t, &trigger_sim_ops, &tc, &err), 0);
    int64_t tp;
    assert_int_equal(trigger_pulse(t, 5, &tp, &err), -ENOTCONN);
    assert_non_null(strstr(err.msg, "no trigger output line"));
    trigger_close(t);
}

static void gpiod_missing_chip_is_named(void **state)
{
    (void)state;
    printf("test_trigger: libgpiod API %d\n", SCICAP_GPIOD_MAJOR);
    trigger_config tc = trigger_config_default();
    tc.chip = "/dev/gpiochip-scicap-none";
    tc.output.offset = 0;
    trigger *t = NULL;
    sci_error err = {0};
    int rc = trigger_open(&t, &trigger_gpiod_ops, &tc, &err);
    assert_null(t);
#if SCICAP_GPIOD_MAJOR >= 1
    assert_int_equal(rc, -ENOENT);
    assert_string_equal(err.msg, "GPIO chip /dev/gpiochip-scicap-none: no such chip");
    tc.chip = "scicap-no-such-label";
    assert_int_equal(trigger_open(&t, &trigger_gpiod_ops, &tc, &err), -ENOENT);
    assert_non_null(strstr(err.msg, "scicap-no-such-label"));
#else
    assert_int_equal(rc, -ENOTSUP);
#endif
}

static void config_from_json(void **state)
{
    (void)state;
    json_error_t je;
    json_t *j = json_loads("{\"chip\": \"gpiochip0\", \"output\": 17, \"dmd_input\": \"DMD_TRIG_OUT1\","
                           " \"strobe_input\": {\"line\": 27, \"active_low\": true}}", 0, &je);
    trigger_config c;
    sci_error err = {0};
    assert_int_equal(trigger_config_from_json(j, "trigger", &c, &err), 0);
    assert_int_equal(c.output.offset, 17);
    assert_int_equal(c.inputs[TRIGGER_ROLE_DMD].offset, -1);
    assert_string_equal(c.inputs[TRIGGER_ROLE_DMD].name, "DMD_TRIG_OUT1");
    assert_int_equal(c.inputs[TRIGGER_ROLE_STROBE].offset, 27);
    assert_true(c.inputs[TRIGGER_ROLE_STROBE].active_low);
    json_decref(j);
    j = json_loads("{\"chip\": \"gpiochip0\", \"output\": -2}", 0, &je);
    assert_int_equal(trigger_config_from_json(j, "trigger", &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "trigger.output:"));
    json_decref(j);
    j = json_loads("{\"output\": 1}", 0, &je);
    assert_int_equal(trigger_config_from_json(j, "trigger", &c, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "trigger.chip: required"));
    json_decref(j);
}

int main(void)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    g_seed = s ? strtoull(s, NULL, 0) : 3u;
    printf("test_trigger: seed %llu (set SCICAP_TEST_SEED to change)\n", (unsigned long long)g_seed);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(sim_latency_jitter_and_misses),
        cmocka_unit_test(sim_inputs_in_time_order),
        cmocka_unit_test(gpiod_missing_chip_is_named),
        cmocka_unit_test(config_from_json),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
