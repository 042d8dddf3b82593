/* tests/helpers/nerf_scene.c — see nerf_scene.h. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "tests/helpers/nerf_scene.h"
#include "recon/metrics.h"
#include "recon/sci_ops.h"
#include "sim/simulate.h"

unsigned long long test_seed_env(unsigned long long dflt)
{
    const char *s = getenv("SCICAP_TEST_SEED");
    unsigned long long seed = s ? strtoull(s, NULL, 0) : dflt;
    printf("seed %llu (set SCICAP_TEST_SEED to change)\n", seed);
    return seed;
}

sci_problem *nerf_tiny_problem(int w, unsigned long long seed)
{
    char text[2048];
    snprintf(text, sizeof text,
             "{\"kind\": \"static3d\", \"width\": %d, \"height\": %d, \"frames\": 4, \"seed\": %llu,"
             " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, -3], \"radius\": 0.8,"
             "   \"texture\": {\"type\": \"checkerboard\", \"cell\": 16}},"
             "  {\"type\": \"plane\", \"center\": [0, 0, -5], \"size\": [8, 8], \"texture\": {\"type\": \"noise\", \"cell\": 32}}],"
             " \"camera\": {\"fx\": %d, \"cx\": %g, \"cy\": %g, \"near\": 1.5, \"far\": 6,"
             "   \"start\": {\"position\": [-0.15, 0, 0], \"look_at\": [0, 0, -3]},"
             "   \"end\": {\"position\": [0.15, 0.05, 0], \"look_at\": [0, 0, -3]}}}",
             w, w, seed, w, w / 2.0, w / 2.0);
    sim_scene *sc = NULL;
    sci_error err = {0};
    if (sim_scene_load_string(&sc, "tiny.json", text, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    sci_problem **p;
    int k;
    if (sim_run(sc, &p, &k, NULL, NULL, NULL, &err) < 0)
        fail_msg("%s", err.msg);
    assert_int_equal(k, 1);
    sci_problem *one = p[0];
    free(p);
    sim_scene_free(sc);
    return one;
}

double nerf_mean_frame_psnr(const sci_problem *p)
{
    sci_cube *x, *phi;
    assert_int_equal(sci_cube_new(&x, p->mask->w, p->mask->h, p->mask->n, NULL), 0);
    assert_int_equal(sci_cube_new(&phi, p->mask->w, p->mask->h, 1, NULL), 0);
    sci_op_phi_sum(p->mask, phi);
    size_t fs = sci_cube_frame_size(x);
    for (int i = 0; i < x->n; i++)
        for (size_t k = 0; k < fs; k++)
            x->data[i * fs + k] = phi->data[k] > 0 ? p->meas->data[k] / phi->data[k] : 0;
    double psnr = sci_psnr(x, p->truth, SCI_PEAK_FIXED, p->peak, NULL);
    sci_cube_free(x);
    sci_cube_free(phi);
    return psnr;
}
