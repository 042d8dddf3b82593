#include "recon/problem.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/file.h"

int sci_problem_validate(const sci_problem *p, sci_error *err)
{
    const char *name = p->name[0] ? p->name : "problem";
    if (!p->meas || !p->mask)
        return sci_error_set(err, -EINVAL, "%s: measurement and masks are required", name);
    if (p->meas->n != 1)
        return sci_error_set(err, SCI_ESHAPE, "%s: measurement must be one frame, has %d", name, p->meas->n);
    if (p->mask->w != p->meas->w || p->mask->h != p->meas->h)
        return sci_error_set(err, SCI_ESHAPE, "%s: masks are %dx%d but the measurement is %dx%d", name,
                             p->mask->w, p->mask->h, p->meas->w, p->meas->h);
    if (p->truth && (p->truth->w != p->mask->w || p->truth->h != p->mask->h || p->truth->n != p->mask->n))
        return sci_error_set(err, SCI_ESHAPE, "%s: truth is %dx%dx%d but masks are %dx%dx%d", name, p->truth->w,
                             p->truth->h, p->truth->n, p->mask->w, p->mask->h, p->mask->n);
    char what[200];
    snprintf(what, sizeof what, "%s: measurement", name);
    int rc = sci_cube_check_finite(p->meas, what, err);
    if (rc == 0) {
        snprintf(what, sizeof what, "%s: masks", name);
        rc = sci_cube_check_finite(p->mask, what, err);
    }
    if (rc == 0 && p->truth) {
        snprintf(what, sizeof what, "%s: truth", name);
        rc = sci_cube_check_finite(p->truth, what, err);
    }
    if (rc < 0)
        return rc;
    if (!(p->peak > 0) || !isfinite(p->peak))
        return sci_error_set(err, -EINVAL, "%s: peak must be a positive finite number (got %g)", name, p->peak);
    if (p->camera) {
        const sci_camera *c = p->camera;
        if (c->n != p->mask->n)
            return sci_error_set(err, SCI_ESHAPE, "%s: camera has %d poses for %d frames", name, c->n, p->mask->n);
        double v[] = {c->fx, c->fy, c->cx, c->cy, c->near_m, c->far_m};
        for (size_t i = 0; i < sizeof v / sizeof v[0]; i++)
            if (!isfinite(v[i]))
                return sci_error_set(err, SCI_ENONFINITE, "%s: camera intrinsics are not finite", name);
        if (!(c->fx > 0 && c->fy > 0) || !(c->far_m > c->near_m && c->near_m >= 0))
            return sci_error_set(err, -EINVAL, "%s: camera needs fx, fy > 0 and 0 <= near < far", name);
        for (int k = 0; k < c->n; k++)
            for (int j = 0; j < 12; j++)
                if (!isfinite(c->pose[k][j]))
                    return sci_error_set(err, SCI_ENONFINITE, "%s: camera pose %d is not finite", name, k);
    }
    return 0;
}

sci_camera *sci_camera_new(int n)
{
    sci_camera *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    c->pose = calloc((size_t)(n > 0 ? n : 1), sizeof *c->pose);
    if (!c->pose) {
        free(c);
        return NULL;
    }
    c->n = n;
    return c;
}

void sci_camera_free(sci_camera *c)
{
    if (!c)
        return;
    free(c->pose);
    free(c);
}

void sci_problem_free(sci_problem *p)
{
    if (!p)
        return;
    sci_cube_free(p->meas);
    sci_cube_free(p->mask);
    sci_cube_free(p->truth);
    sci_camera_free(p->camera);
    free(p);
}

void sci_problem_array_free(sci_problem **p, int k)
{
    if (!p)
        return;
    for (int i = 0; i < k; i++)
        sci_problem_free(p[i]);
    free(p);
}

int sci_trace_push(sci_trace *t, const sci_trace_entry *e)
{
    if (t->len == t->cap) {
        size_t cap = t->cap ? t->cap * 2 : 128;
        sci_trace_entry *ne = realloc(t->e, cap * sizeof *ne);
        if (!ne)
            return -ENOMEM;
        t->e = ne;
        t->cap = cap;
    }
    t->e[t->len++] = *e;
    return 0;
}

void sci_trace_clear(sci_trace *t)
{
    free(t->e);
    t->e = NULL;
    t->len = t->cap = 0;
}

static int trace_write_rows(FILE *f, void *user, sci_error *err)
{
    (void)err;
    const sci_trace *t = user;
    fprintf(f, "iter,wall_s,cpu_s,residual,loss,psnr_db,psnr_peak1_db,ssim,meas_residual,max_weight,plane\n");
    for (size_t i = 0; i < t->len; i++) {
        const sci_trace_entry *e = &t->e[i];
        fprintf(f, "%d,%.6f,%.6f,%.9g,%.9g,%.4f,%.4f,%.5f,%.6g,%.4f,%d\n", e->iter, e->wall_s, e->cpu_s,
                e->residual, e->loss, e->psnr, e->psnr_peak1, e->ssim, e->meas_residual, e->max_weight, e->plane);
    }
    return 0;
}

int sci_trace_write_csv(const sci_trace *t, const char *path, sci_error *err)
{
    return sci_file_write_atomic_with(path, 0644, 0, trace_write_rows, (void *)t, err);
}

void sci_result_free_contents(sci_result *r)
{
    if (!r)
        return;
    sci_cube_free(r->frames);
    r->frames = NULL;
    sci_trace_clear(&r->trace);
    free(r->final_metrics);
    r->final_metrics = NULL;
    r->final_n = 0;
    r->final_of = NULL;
}
