#include "sim/bench_source.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sim/dmd_sim.h"
#include "sim/simulate.h"

struct sim_bench_source {
    const sim_scene *scene;
    const dmd *dmd;
    sim_bench_source_options opt;
    int frames;          /* K·N scene frames in the loop */
    float **frame;       /* rendered on first use */
    int nmask;
    float **mask;        /* DMD masks as floats, read from the DMD on first use */
    uint8_t *mask_u8;
    double *acc;         /* w×h accumulator, double so the sum does not depend on piece count */
    float *last;
};

int sim_bench_source_new(sim_bench_source **out, const sim_scene *scene, const dmd *device,
                         const sim_bench_source_options *opt, sci_error *err)
{
    *out = NULL;
    if (!opt || opt->slot_ns <= 0)
        return sci_error_set(err, -EINVAL, "bench source: slot_ns must be > 0");
    sim_bench_source *s = calloc(1, sizeof *s);
    size_t px = (size_t)scene->w * scene->h;
    if (!s)
        return sci_error_set(err, -ENOMEM, "bench source: out of memory");
    s->scene = scene;
    s->dmd = device;
    s->opt = *opt;
    if (s->opt.steps_per_slot <= 0)
        s->opt.steps_per_slot = 8;
    s->frames = scene->n * scene->snapshots;
    s->nmask = 4096;
    s->frame = calloc((size_t)s->frames, sizeof *s->frame);
    s->mask = calloc((size_t)s->nmask, sizeof *s->mask);
    s->mask_u8 = malloc(px);
    s->acc = malloc(px * sizeof *s->acc);
    s->last = malloc(px * sizeof *s->last);
    if (!s->frame || !s->mask || !s->mask_u8 || !s->acc || !s->last) {
        sim_bench_source_free(s);
        return sci_error_set(err, -ENOMEM, "bench source: out of memory for a %dx%d scene", scene->w, scene->h);
    }
    s->last[0] = NAN; /* marks "no fill yet" */
    *out = s;
    return 0;
}

void sim_bench_source_free(sim_bench_source *s)
{
    if (!s)
        return;
    for (int i = 0; s->frame && i < s->frames; i++)
        free(s->frame[i]);
    for (int i = 0; s->mask && i < s->nmask; i++)
        free(s->mask[i]);
    free(s->frame);
    free(s->mask);
    free(s->mask_u8);
    free(s->acc);
    free(s->last);
    free(s);
}

const float *sim_bench_source_last(const sim_bench_source *s) { return isnan(s->last[0]) ? NULL : s->last; }

static const float *scene_frame(sim_bench_source *s, int64_t g, sci_error *err)
{
    int i = (int)(g % s->frames);
    if (!s->frame[i]) {
        size_t px = (size_t)s->scene->w * s->scene->h;
        if (!(s->frame[i] = malloc(px * sizeof(float)))) {
            sci_error_set(err, -ENOMEM, "bench source: out of memory for a scene frame");
            return NULL;
        }
        sim_render_frame(s->scene, (double)i, s->frame[i]);
    }
    return s->frame[i];
}

static const float *dmd_mask(sim_bench_source *s, int k, sci_error *err)
{
    if (k >= s->nmask) {
        sci_error_set(err, -ERANGE, "bench source: mask index %d out of range", k);
        return NULL;
    }
    if (!s->mask[k]) {
        size_t px = (size_t)s->scene->w * s->scene->h;
        int rc = dmd_sim_mask(s->dmd, k, s->mask_u8);
        if (rc < 0) {
            sci_error_set(err, rc, "bench source: cannot read mask %d from the simulated DMD", k);
            return NULL;
        }
        if (!(s->mask[k] = malloc(px * sizeof(float)))) {
            sci_error_set(err, -ENOMEM, "bench source: out of memory for a mask");
            return NULL;
        }
        for (size_t i = 0; i < px; i++)
            s->mask[k][i] = s->mask_u8[i] ? 1.0f : 0.0f;
    }
    return s->mask[k];
}

int sim_bench_source_fill(void *source, const camera_sim_exposure *e, uint16_t *samples, uint32_t w, uint32_t h,
                          int bits, sci_error *err)
{
    sim_bench_source *s = source;
    if ((int)w != s->scene->w || (int)h != s->scene->h)
        return sci_error_set(err, -EINVAL, "bench source: camera frame %ux%u but scene %s is %dx%d", w, h,
                             s->scene->name, s->scene->w, s->scene->h);
    size_t px = (size_t)w * h;
    memset(s->acc, 0, px * sizeof *s->acc);
    int64_t t0 = dmd_sim_started_ns(s->dmd);
    if (t0 > 0) {
        int64_t slot = s->opt.slot_ns, step = slot / s->opt.steps_per_slot;
        step = step > 0 ? step : 1;
        int64_t a = e->start_ns - t0, b = e->end_ns - t0; /* window relative to the DMD start */
        a = a > 0 ? a : 0;
        /* Pieces: the window cut at multiples of `step` (steps start at the slot boundaries). */
        for (int64_t p = a; p < b;) {
            int64_t next = (p / step + 1) * step;
            next = next < b ? next : b;
            int64_t mid = p + (next - p) / 2;
            int k = dmd_sim_displayed_at(s->dmd, mid);
            if (k >= 0) {
                const float *m = dmd_mask(s, k, err), *x = m ? scene_frame(s, mid / slot, err) : NULL;
                if (!x)
                    return err ? err->code : -ENOMEM;
                double wgt = (double)(next - p) / (double)slot;
#pragma omp parallel for schedule(static)
                for (size_t i = 0; i < px; i++)
                    s->acc[i] += wgt * ((double)m[i] * x[i]);
            }
            p = next;
        }
    }
    double cw = s->opt.counts_white > 0 ? s->opt.counts_white : (double)((1u << bits) - 1) / s->scene->n;
    double scale = cw * (e->gain >= 0 ? e->gain / 100.0 : 1.0), max = (double)((1u << bits) - 1);
    for (size_t i = 0; i < px; i++) {
        s->last[i] = (float)s->acc[i];
        double c = nearbyint(s->acc[i] * scale);
        samples[i] = (uint16_t)(c < 0 ? 0 : c > max ? max : c);
    }
    return 0;
}
