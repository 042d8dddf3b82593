/* base/: positioned JSON errors, RNG streams, cube allocation limits, error strings. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "base/cube.h"
#include "base/json.h"
#include "base/rng.h"

static const char scene[] = "{\n"
                            "  \"width\": 256,\n"
                            "  \"effects\": [\n"
                            "    {\"kind\": \"blur\", \"sigma\": -1},\n"
                            "    {\"kind\": \"shot\"}\n"
                            "  ],\n"
                            "  \"name\": \"x\"\n"
                            "}\n";

static void test_json_positions(void **state)
{
    sci_json_doc *doc;
    sci_error err = {0};
    assert_int_equal(sci_json_doc_load_string(&doc, "scene.json", scene, strlen(scene), &err), 0);
    int line, col;
    assert_int_equal(sci_json_doc_where(doc, "effects[0].sigma", &line, &col), 0);
    assert_int_equal(line, 4);
    assert_int_equal(col, 22); /* the key's position */
    json_t *root = sci_json_doc_root(doc);
    json_t *e0 = json_array_get(json_object_get(root, "effects"), 0);
    double sigma = 1;
    assert_int_equal(sci_json_get_double(doc, e0, "effects[0]", "sigma", 1, 0, 100, &sigma, &err), SCI_ECONFIG);
    assert_string_equal(err.msg, "scene.json:4:22: effects[0].sigma: must be in [0, 100] (got -1)");
    /* A missing required key points at its object. */
    json_t *e1 = json_array_get(json_object_get(root, "effects"), 1);
    assert_int_equal(sci_json_get_double(doc, e1, "effects[1]", "photons", 1, 0, 1e9, &sigma, &err), SCI_ECONFIG);
    assert_string_equal(err.msg, "scene.json:5:5: effects[1].photons: required key is missing");
    /* An absent optional key leaves the default. */
    assert_int_equal(sci_json_get_double(doc, e1, "effects[1]", "photons", 0, 0, 1e9, &sigma, &err), 1);
    assert_true(sigma == 1);
    long long wv;
    assert_int_equal(sci_json_get_int(doc, root, "", "width", 1, 1, 65535, &wv, &err), 0);
    assert_int_equal(wv, 256);
    static const char *const allowed[] = {"width", "effects", NULL};
    assert_int_equal(sci_json_check_keys(doc, root, "", allowed, &err), SCI_ECONFIG);
    assert_string_equal(err.msg, "scene.json:7:3: name: unknown key");
    static const char *const kinds[] = {"shot", "read", NULL};
    int idx;
    assert_int_equal(sci_json_get_enum(doc, e0, "effects[0]", "kind", 1, kinds, &idx, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "unknown value \"blur\""));
    sci_json_doc_free(doc);
    /* Syntax errors carry jansson's position. */
    assert_int_equal(sci_json_doc_load_string(&doc, "bad.json", "{\n  \"a\": [1, 2,\n}", 16, &err), SCI_ECONFIG);
    assert_non_null(strstr(err.msg, "bad.json:3:"));
    assert_int_equal(sci_json_doc_load_file(&doc, "/nonexistent.json", &err), -ENOENT);
}

/* KEY=VALUE as `--set` reads it: JSON when it parses, else the text; malformed arguments leave the object as it was. */
static void test_json_set_kv(void **state)
{
    (void)state;
    json_t *o = json_object();
    assert_int_equal(sci_json_set_kv(o, "iters=30"), 0);
    assert_int_equal(sci_json_set_kv(o, "gain=0.5"), 0);
    assert_int_equal(sci_json_set_kv(o, "on=true"), 0);
    assert_int_equal(sci_json_set_kv(o, "mode=fast"), 0);
    assert_int_equal(sci_json_set_kv(o, "list=[1, 2]"), 0);
    assert_int_equal(sci_json_set_kv(o, "expr=a=b"), 0); /* the first '=' splits */
    assert_int_equal(sci_json_set_kv(o, "empty="), 0);
    assert_int_equal(json_integer_value(json_object_get(o, "iters")), 30);
    assert_true(json_real_value(json_object_get(o, "gain")) == 0.5);
    assert_true(json_is_true(json_object_get(o, "on")));
    assert_string_equal(json_string_value(json_object_get(o, "mode")), "fast");
    assert_int_equal(json_array_size(json_object_get(o, "list")), 2);
    assert_string_equal(json_string_value(json_object_get(o, "expr")), "a=b");
    assert_string_equal(json_string_value(json_object_get(o, "empty")), "");
    assert_int_equal(sci_json_set_kv(o, "iters=40"), 0); /* the last one given wins */
    assert_int_equal(json_integer_value(json_object_get(o, "iters")), 40);
    char longkey[200];
    memset(longkey, 'k', 128);
    strcpy(longkey + 128, "=1");
    assert_int_equal(sci_json_set_kv(o, longkey), -EINVAL);
    assert_int_equal(sci_json_set_kv(o, longkey + 1), 0); /* 127 bytes: the longest key */
    assert_int_equal(sci_json_set_kv(o, "noequals"), -EINVAL);
    assert_int_equal(sci_json_set_kv(o, "=5"), -EINVAL);
    assert_int_equal(sci_json_set_kv(o, "bad=\xff"), -EINVAL);
    assert_int_equal(json_object_size(o), 8);
    json_decref(o);
}

static void test_rng_streams(void **state)
{
    sci_rng a, b, c;
    sci_rng_seed(&a, 42, 1);
    sci_rng_seed(&b, 42, 1);
    sci_rng_seed(&c, 42, 2);
    int same = 0;
    for (int i = 0; i < 1000; i++) {
        uint64_t x = sci_rng_u64(&a), y = sci_rng_u64(&b), z = sci_rng_u64(&c);
        assert_true(x == y);
        same += x == z;
    }
    assert_true(same == 0);
    /* Poisson: mean and variance both equal λ, for the inversion and the PTRS branch. */
    const double lams[] = {0.5, 4, 30, 1000};
    for (size_t l = 0; l < 4; l++) {
        double s = 0, s2 = 0;
        const int n = 200000;
        for (int i = 0; i < n; i++) {
            double v = sci_rng_poisson(&a, lams[l]);
            s += v;
            s2 += v * v;
        }
        double mean = s / n, var = s2 / n - mean * mean;
        printf("poisson(%g): mean %.4f var %.4f\n", lams[l], mean, var);
        assert_true(fabs(mean - lams[l]) < 5 * sqrt(lams[l] / n));
        assert_true(fabs(var / lams[l] - 1) < 0.03);
    }
    double s = 0, s2 = 0;
    for (int i = 0; i < 200000; i++) {
        double v = sci_rng_normal(&a);
        s += v;
        s2 += v * v;
    }
    assert_true(fabs(s / 200000) < 0.01 && fabs(s2 / 200000 - 1) < 0.02);
    for (int i = 0; i < 1000; i++)
        assert_true(sci_rng_below(&a, 7) < 7);
}

static void test_cube_limits(void **state)
{
    sci_cube *c;
    sci_error err = {0};
    assert_int_equal(sci_cube_new(&c, 0, 5, 5, &err), -EINVAL);
    assert_null(c);
    assert_int_equal(sci_cube_new(&c, 1 << 20, 1 << 20, 1 << 10, &err), -EINVAL);
    assert_non_null(strstr(err.msg, "too large"));
    assert_int_equal(sci_cube_new(&c, 3, 2, 2, &err), 0);
    c->data[7] = NAN;
    assert_int_equal(sci_cube_check_finite(c, "thing", &err), SCI_ENONFINITE);
    assert_string_equal(err.msg, "thing: non-finite value nan at x=1 y=0 frame=1");
    sci_cube_free(c);
    sci_cube_free(NULL);
    assert_string_equal(sci_strerror(SCI_EDIVERGED), "solver diverged");
    assert_string_equal(sci_strerror(-ENOENT), "No such file or directory");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_json_positions),
        cmocka_unit_test(test_json_set_kv),
        cmocka_unit_test(test_rng_streams),
        cmocka_unit_test(test_cube_limits),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
