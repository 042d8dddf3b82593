/* base/json_fields: a table reads typed, range-checked members with the getters' positioned messages. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "base/json_fields.h"

typedef struct opts {
    int count;
    uint32_t us;
    size_t bytes;
    long long offset;
    uint64_t seed;
    double gain;
    int on;
    int mode;
    char name[8];
} opts;

static const char *const modes[] = {"fast", "slow", NULL};

static const sci_json_field rows[] = {
    {"count", SCI_JSON_INT, offsetof(opts, count), 1, 10, .required = 1, .help = "how many"},
    {"us", SCI_JSON_U32, offsetof(opts, us), 0, 4e9, .help = "microseconds"},
    {"bytes", SCI_JSON_SIZE, offsetof(opts, bytes), 1024, 1 << 24, .help = "bytes"},
    {"offset", SCI_JSON_LLONG, offsetof(opts, offset), -1e12, 1e12, .help = "signed"},
    {"seed", SCI_JSON_U64, offsetof(opts, seed), 0, 9007199254740992.0, .help = "seed"},
    {"gain", SCI_JSON_DOUBLE, offsetof(opts, gain), 0, 2, .help = "multiplier"},
    {"on", SCI_JSON_BOOL, offsetof(opts, on), .help = "switch"},
    {"mode", SCI_JSON_ENUM, offsetof(opts, mode), .names = modes, .help = "speed"},
    {"name", SCI_JSON_STRING, offsetof(opts, name), .size = 8, .help = "short name"},
};

/* Reads `text` into *o (preset to defaults); returns the reader's code, the message in err. */
static int read_text(const char *text, opts *o, sci_error *err)
{
    sci_json_doc *doc;
    *o = (opts){.count = 3, .us = 7, .bytes = 4096, .gain = 1, .mode = 1};
    snprintf(o->name, sizeof o->name, "dflt");
    int rc = sci_json_doc_load_string(&doc, "t.json", text, strlen(text), err);
    if (rc < 0)
        return rc;
    json_t *root = sci_json_doc_root(doc);
    rc = sci_json_fields_read(doc, json_object_get(root, "o"), "o", rows, SCI_JSON_FIELDS_COUNT(rows), o, err);
    sci_json_doc_free(doc);
    return rc;
}

static void test_every_type_stored(void **state)
{
    opts o;
    sci_error err = {0};
    const char *text = "{\"o\": {\"count\": 9, \"us\": 4000000000, \"bytes\": 65536, \"offset\": -5, "
                       "\"seed\": 9007199254740992, \"gain\": 0.5, \"on\": true, \"mode\": \"fast\", "
                       "\"name\": \"abc\"}}";
    assert_int_equal(read_text(text, &o, &err), 0);
    assert_int_equal(o.count, 9);
    assert_true(o.us == 4000000000u);
    assert_int_equal(o.bytes, 65536);
    assert_int_equal(o.offset, -5);
    assert_true(o.seed == 9007199254740992ull);
    assert_true(o.gain == 0.5);
    assert_int_equal(o.on, 1);
    assert_int_equal(o.mode, 0);
    assert_string_equal(o.name, "abc");
}

static void test_absent_keeps_defaults(void **state)
{
    opts o;
    sci_error err = {0};
    assert_int_equal(read_text("{\"o\": {\"count\": 2}}", &o, &err), 0);
    assert_int_equal(o.us, 7);
    assert_int_equal(o.bytes, 4096);
    assert_true(o.gain == 1);
    assert_int_equal(o.mode, 1);
    assert_string_equal(o.name, "dflt");
}

/* The messages are the typed getters' (base/json.h), positioned at the key. */
static void test_messages(void **state)
{
    static const struct {
        const char *text, *msg;
    } cases[] = {
        {"{\"o\": {}}", "t.json:1:2: o.count: required key is missing"},
        {"{\"o\": {\"count\": 11}}", "t.json:1:8: o.count: must be in [1, 10] (got 11)"},
        {"{\"o\": {\"count\": 1, \"bytes\": 10}}", "t.json:1:20: o.bytes: must be in [1024, 16777216] (got 10)"},
        {"{\"o\": {\"count\": 1, \"gain\": 3}}", "t.json:1:20: o.gain: must be in [0, 2] (got 3)"},
        {"{\"o\": {\"count\": 1, \"name\": \"toolongname\"}}", "t.json:1:20: o.name: longer than 7 bytes"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        opts o;
        sci_error err = {0};
        assert_int_equal(read_text(cases[i].text, &o, &err), SCI_ECONFIG);
        assert_string_equal(err.msg, cases[i].msg);
    }
    /* enum and bool refusals name the key and the value */
    opts o;
    sci_error err = {0};
    assert_int_equal(read_text("{\"o\": {\"count\": 1, \"mode\": \"warp\"}}", &o, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "o.mode"));
    assert_non_null(strstr(err.msg, "warp"));
    assert_int_equal(read_text("{\"o\": {\"count\": 1, \"on\": 3}}", &o, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "o.on"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_type_stored),
        cmocka_unit_test(test_absent_keeps_defaults),
        cmocka_unit_test(test_messages),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
