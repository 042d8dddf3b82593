#include "recon/bayer.h"

#include <assert.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static const char *const cfa_names[] = {"none", "RGGB", "BGGR", "GRBG", "GBRG"};

int sci_cfa_parse(const char *s, sci_cfa *out)
{
    for (int i = 0; i < 5; i++)
        if (strcasecmp(s, cfa_names[i]) == 0) {
            *out = (sci_cfa)i;
            return 0;
        }
    return -EINVAL;
}

const char *sci_cfa_name(sci_cfa cfa)
{
    return (unsigned)cfa < 5 ? cfa_names[cfa] : "?";
}

void sci_cfa_mosaic(sci_cfa cfa, const sci_cube *rgb, sci_cube *raw)
{
    assert(rgb->w == raw->w && rgb->h == raw->h && rgb->n == 3 * raw->n);
    for (int f = 0; f < raw->n; f++) {
        float *o = sci_cube_frame(raw, f);
        for (int y = 0; y < raw->h; y++)
            for (int x = 0; x < raw->w; x++) {
                const size_t i = (size_t)y * raw->w + x;
                o[i] = sci_cube_frame(rgb, 3 * f + sci_cfa_color(cfa, x, y))[i];
            }
    }
}

/* Sub-sample every frame of c at the site (dx, dy) into a new (w/2)×(h/2) cube. */
static int site_cube(const sci_cube *c, int dx, int dy, sci_cube **out, sci_error *err)
{
    const int w2 = c->w / 2, h2 = c->h / 2;
    int rc = sci_cube_new(out, w2, h2, c->n, err);
    if (rc < 0)
        return rc;
    for (int f = 0; f < c->n; f++) {
        const float *s = sci_cube_frame(c, f);
        float *d = sci_cube_frame(*out, f);
        for (int y = 0; y < h2; y++)
            for (int x = 0; x < w2; x++)
                d[(size_t)y * w2 + x] = s[(size_t)(2 * y + dy) * c->w + 2 * x + dx];
    }
    return 0;
}

int sci_bayer_split(const sci_problem *p, sci_cfa cfa, sci_problem *planes[4], sci_error *err)
{
    static const char *const cname[3] = {"R", "G", "B"};
    memset(planes, 0, 4 * sizeof *planes);
    if (cfa == SCI_CFA_NONE)
        return sci_error_set(err, -EINVAL, "%s: no colour filter array to split by", p->name);
    if (p->mask->w % 2 || p->mask->h % 2 || p->mask->w < 4 || p->mask->h < 4)
        return sci_error_set(err, SCI_ESHAPE, "%s: a Bayer mosaic needs an even size of at least 4x4, not %dx%d",
                             p->name, p->mask->w, p->mask->h);
    int rc = 0;
    for (int i = 0; i < 4; i++) {
        const int dx = i & 1, dy = i >> 1;
        sci_problem *q = calloc(1, sizeof *q);
        if (!q) {
            rc = sci_error_set(err, -ENOMEM, "%s: out of memory", p->name);
            goto fail;
        }
        planes[i] = q;
        q->peak = p->peak;
        const int c = sci_cfa_color(cfa, dx, dy);
        snprintf(q->name, sizeof q->name, "%.100s/%s%s", p->name, cname[c],
                 c != 1 ? "" : sci_cfa_color(cfa, dx ^ 1, dy) == 0 ? "r" : "b");
        if ((rc = site_cube(p->meas, dx, dy, &q->meas, err)) < 0 || (rc = site_cube(p->mask, dx, dy, &q->mask, err)) < 0 ||
            (p->truth && (rc = site_cube(p->truth, dx, dy, &q->truth, err)) < 0))
            goto fail;
    }
    return 0;
fail:
    for (int i = 0; i < 4; i++) {
        sci_problem_free(planes[i]);
        planes[i] = NULL;
    }
    return rc;
}

void sci_bayer_merge(sci_cube *const planes[4], sci_cube *raw)
{
    for (int i = 0; i < 4; i++) {
        const sci_cube *c = planes[i];
        const int dx = i & 1, dy = i >> 1;
        assert(c->w * 2 == raw->w && c->h * 2 == raw->h && c->n == raw->n);
        for (int f = 0; f < c->n; f++) {
            const float *s = sci_cube_frame(c, f);
            float *d = sci_cube_frame(raw, f);
            for (int y = 0; y < c->h; y++)
                for (int x = 0; x < c->w; x++)
                    d[(size_t)(2 * y + dy) * raw->w + 2 * x + dx] = s[(size_t)y * c->w + x];
        }
    }
}

int sci_bayer_solve(const sci_problem *p, sci_cfa cfa, sci_demosaic_method dm, sci_plane_solve_fn solve,
                    void *user, sci_cube **rgb, sci_cube **raw_out, sci_result plane_results[4], sci_error *err)
{
    *rgb = NULL;
    if (raw_out)
        *raw_out = NULL;
    sci_problem *planes[4];
    sci_result local[4];
    sci_result *res = plane_results ? plane_results : local;
    memset(res, 0, 4 * sizeof *res);
    sci_cube *raw = NULL;
    int rc = sci_bayer_split(p, cfa, planes, err);
    if (rc < 0)
        return rc;
    for (int i = 0; i < 4; i++)
        if ((rc = solve(planes[i], &res[i], user)) < 0) {
            sci_error_set(err, rc, "%s: %s", planes[i]->name, res[i].error.msg[0] ? res[i].error.msg : "failed");
            goto out;
        }
    const int w = p->mask->w, h = p->mask->h, n = p->mask->n;
    sci_cube *frames[4] = {res[0].frames, res[1].frames, res[2].frames, res[3].frames};
    if ((rc = sci_cube_new(&raw, w, h, n, err)) < 0 || (rc = sci_cube_new(rgb, w, h, 3 * n, err)) < 0)
        goto out;
    sci_bayer_merge(frames, raw);
    for (int f = 0; f < n; f++)
        sci_demosaic(cfa, dm, sci_cube_frame(raw, f), w, h, sci_cube_frame(*rgb, 3 * f), sci_cube_frame(*rgb, 3 * f + 1),
                     sci_cube_frame(*rgb, 3 * f + 2));
out:
    for (int i = 0; i < 4; i++)
        sci_problem_free(planes[i]);
    if (!plane_results || rc < 0)
        for (int i = 0; i < 4; i++)
            sci_result_free_contents(&res[i]);
    if (rc < 0) {
        sci_cube_free(*rgb);
        *rgb = NULL;
        sci_cube_free(raw);
    } else if (raw_out) {
        *raw_out = raw;
    } else {
        sci_cube_free(raw);
    }
    return rc;
}
