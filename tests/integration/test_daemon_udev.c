/* udev rules: the packaged systemd/70-scicap.rules gives group scicap the DLPC900 and the uhid node
 * only — no rule for every video4linux node (webcams) or every GPIO chip — and `scicapd --udev-rules` prints
 * rules that match exactly the devices a configuration names: the V4L2 camera by its /dev/v4l/by-id name
 * (ID_SERIAL and index) or by-path name, a USB camera by devices.camera.usb, the GPIO chip by name, the DMD's
 * serial when set, the emulator's uhid node. A device that cannot be matched narrowly (camera "/dev/video0", a
 * chip named by label) is refused with the key to change, never widened. Every rule line is checked for udev's
 * syntax: comma-separated KEY=="value" matches and KEY="value" / KEY+="value" assignments. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "tests/helpers/cli_child.h"

static char dir[] = "/tmp/scicap-test-udev-XXXXXX";
static char scicapd[1024];

/* One rule line: tokens KEY{attr}?OP"value" joined by ", ". Returns the number of match tokens (==), fails the
 * test on anything else. */
static int check_rule(const char *line)
{
    int matches = 0, assigns = 0;
    const char *p = line;
    while (*p) {
        const char *op = strpbrk(p, "=+!");
        if (!op || op == p)
            fail_msg("no key before an operator in: %s", line);
        for (const char *k = p; k < op; k++)
            if (!strchr("ABCDEFGHIJKLMNOPQRSTUVWXYZ_{}abcdefghijklmnopqrstuvwxyz0123456789", *k))
                fail_msg("bad key character '%c' in: %s", *k, line);
        int is_match = !strncmp(op, "==", 2) || !strncmp(op, "!=", 2);
        const char *v = is_match || !strncmp(op, "+=", 2) ? op + 2 : op + 1;
        if (*v != '"')
            fail_msg("value not quoted in: %s", line);
        const char *end = strchr(v + 1, '"');
        if (!end)
            fail_msg("unterminated value in: %s", line);
        if (end == v + 1)
            fail_msg("empty value in: %s", line);
        matches += is_match;
        assigns += !is_match;
        p = end + 1;
        if (!strncmp(p, ", ", 2))
            p += 2;
        else if (*p)
            fail_msg("tokens not separated by \", \" in: %s", line);
    }
    if (!assigns || !strstr(line, "GROUP=\"scicap\""))
        fail_msg("rule gives nothing to group scicap: %s", line);
    return matches;
}

/* Each rule of `text`: well-formed, and narrower than its subsystem alone (some match besides SUBSYSTEM, KERNEL
 * being a match only when it names one node). Returns the number of rules. */
static int check_rules(const char *text)
{
    int rules = 0;
    char *copy = strdup(text), *save = NULL;
    for (char *l = strtok_r(copy, "\n", &save); l; l = strtok_r(NULL, "\n", &save)) {
        if (l[0] == '#' || !l[0])
            continue;
        int m = check_rule(l);
        int wide = !strncmp(l, "SUBSYSTEM==\"video4linux\", GROUP", 31) ||
                   !strncmp(l, "SUBSYSTEM==\"gpio\", KERNEL==\"gpiochip*\"", 37) || strstr(l, "==\"*\"");
        if (wide || (m < 2 && strncmp(l, "KERNEL==\"uhid\"", 14) != 0))
            fail_msg("rule matches a whole class of devices: %s", l);
        rules++;
    }
    free(copy);
    return rules;
}

static void rules_for(const char *config_text, cli_child *c)
{
    char path[300];
    snprintf(path, sizeof path, "%s/scicapd.json", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(config_text, f);
    fclose(f);
    cli_child_run(c, scicapd, (const char *const[]){"--udev-rules", "--config", path, NULL}, dir);
}

static void test_shipped_rule_is_narrow(void **state)
{
    FILE *f = fopen("systemd/70-scicap.rules", "r");
    assert_non_null(f);
    char text[8192];
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    assert_int_equal(check_rules(text), 4);
    assert_null(strstr(text, "SUBSYSTEM==\"video4linux\""));
    assert_null(strstr(text, "SUBSYSTEM==\"gpio\""));
    assert_non_null(strstr(text, "ATTRS{idVendor}==\"0451\", ATTRS{idProduct}==\"c900\""));
    assert_non_null(strstr(text, "KERNEL==\"uhid\""));
    assert_non_null(strstr(text, "scicapd --udev-rules")); /* says how to get the rest */
}

static void test_example_configs(void **state)
{
    cli_child c;
    cli_child_run(&c, scicapd, (const char *const[]){"--udev-rules", "--config", "etc/scicapd-v4l2.json", NULL}, dir);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d: %s", cli_child_exit_code(&c), c.err);
    assert_int_equal(check_rules(c.out), 4);
    assert_non_null(strstr(c.out, "SUBSYSTEM==\"video4linux\", ENV{ID_SERIAL}==\"The_Imaging_Source_Europe_GmbH_DMK_"
                                  "37BUX287_12345678\", ATTR{index}==\"0\""));
    assert_non_null(strstr(c.out, "SUBSYSTEM==\"gpio\", KERNEL==\"gpiochip0\""));
    print_message("  etc/scicapd-v4l2.json:\n%s", c.out);
    cli_child_run(&c, scicapd, (const char *const[]){"--udev-rules", "--config", "etc/scicapd-aravis.json", NULL}, dir);
    assert_int_equal(cli_child_exit_code(&c), 0);
    assert_int_equal(check_rules(c.out), 3); /* a GigE camera needs no node: DMD (2) and GPIO */
    assert_non_null(strstr(c.out, "GigE Vision camera needs no device node"));
    cli_child_run(&c, scicapd, (const char *const[]){"--udev-rules", "--no-config", NULL}, dir);
    assert_int_equal(cli_child_exit_code(&c), 0);
    assert_int_equal(check_rules(c.out), 0); /* the simulator: nothing */
}

#define CFG_V4L2(dev, extra)                                                                                  \
    "{\"devices\": {\"dmd\": {\"backend\": \"dlpc900\", \"serial\": \"DLPC-123\"}, \"camera\": {\"backend\": " \
    "\"v4l2\", \"device\": \"" dev "\"" extra "}, \"trigger\": {\"backend\": \"gpiod\", \"chip\": "            \
    "\"/dev/gpiochip3\", \"output\": 17}}}"

static void test_narrow_matches(void **state)
{
    cli_child c;
    rules_for(CFG_V4L2("/dev/v4l/by-path/pci-0000:00:14.0-usb-0:2:1.0-video-index1", ""), &c);
    if (cli_child_exit_code(&c) != 0)
        fail_msg("exit %d: %s", cli_child_exit_code(&c), c.err);
    check_rules(c.out);
    assert_non_null(strstr(c.out, "ENV{ID_PATH}==\"pci-0000:00:14.0-usb-0:2:1.0\", ATTR{index}==\"1\""));
    assert_non_null(strstr(c.out, "ATTRS{serial}==\"DLPC-123\""));
    assert_non_null(strstr(c.out, "KERNEL==\"gpiochip3\""));
    /* USB ids instead of the name; upper-case hex accepted, written as udev compares it */
    rules_for(CFG_V4L2("/dev/video0", ", \"usb\": {\"vendor\": \"199E\", \"product\": \"9207\", \"serial\": "
                                      "\"27810000\"}"),
              &c);
    assert_int_equal(cli_child_exit_code(&c), 0);
    check_rules(c.out);
    assert_non_null(strstr(c.out, "SUBSYSTEM==\"video4linux\", ATTRS{idVendor}==\"199e\", ATTRS{idProduct}==\"9207\", "
                                  "ATTRS{serial}==\"27810000\""));
    /* the emulated DMD: its uhid node */
    rules_for("{\"devices\": {\"dmd\": {\"backend\": \"dlpc900\", \"emulator\": true}}}", &c);
    assert_int_equal(cli_child_exit_code(&c), 0);
    assert_int_equal(check_rules(c.out), 2);
    assert_non_null(strstr(c.out, "KERNEL==\"uhid\""));
}

static void test_refuses_to_widen(void **state)
{
    cli_child c;
    rules_for(CFG_V4L2("/dev/video0", ""), &c);
    assert_int_equal(cli_child_exit_code(&c), 1);
    assert_non_null(strstr(c.err, "devices.camera.device"));
    assert_non_null(strstr(c.err, "/dev/v4l/by-id"));
    assert_null(strstr(c.out, "video4linux"));
    rules_for(CFG_V4L2("/dev/v4l/by-id/usb-Cam*-video-index0", ""), &c);
    assert_int_equal(cli_child_exit_code(&c), 1); /* a glob would match other cameras */
    rules_for(CFG_V4L2("/dev/video0", ", \"usb\": {\"vendor\": \"19\", \"product\": \"9207\"}"), &c);
    assert_int_equal(cli_child_exit_code(&c), 1);
    assert_non_null(strstr(c.err, "devices.camera.usb"));
    rules_for("{\"devices\": {\"camera\": {\"backend\": \"aravis\", \"device\": \"Basler-1\"}, \"trigger\": "
              "{\"backend\": \"gpiod\", \"chip\": \"pinctrl-bcm2711\", \"output\": 17}}}",
              &c);
    assert_int_equal(cli_child_exit_code(&c), 1);
    assert_non_null(strstr(c.err, "devices.trigger.chip"));
}

static int setup(void **state) { return cli_child_setup(scicapd, sizeof scicapd, "scicapd", dir); }
static int teardown(void **state) { return cli_child_remove_dir(dir); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_shipped_rule_is_narrow),
        cmocka_unit_test(test_example_configs),
        cmocka_unit_test(test_narrow_matches),
        cmocka_unit_test(test_refuses_to_widen),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
