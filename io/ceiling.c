/* io/ceiling.c — reading a NeRF ceiling table and placing the presets on it (see ceiling.h). */
#include "io/ceiling.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

double sci_ceiling_margin_db(solver_preset p)
{
    static const double margin[SOLVER_PRESET_COUNT] = {[SOLVER_PRESET_FAST] = 1.0,
                                                       [SOLVER_PRESET_BALANCED] = 0.3,
                                                       [SOLVER_PRESET_BEST] = 0.1};
    return (unsigned)p < SOLVER_PRESET_COUNT ? margin[p] : NAN;
}

/* One table row into *pt: 1 for a data row, 0 for any other line (prose, header, rule), -1 for a row that starts
 * like data and does not parse. */
static int parse_row(const char *line, sci_ceiling_point *pt)
{
    char method[64];
    int used = 0;
    if (sscanf(line, "| %63[a-z0-9_-] |%n", method, &used) != 1 || used == 0 || !isalpha((unsigned char)method[0]) ||
        strcmp(method, "method") == 0)
        return 0; /* not a row, the header or its rule */
    if (strlen(method) >= sizeof pt->method)
        return -1;
    memset(pt, 0, sizeof *pt);
    snprintf(pt->method, sizeof pt->method, "%s", method);
    if (sscanf(line + used, " %d | %lf | %lf | %lf | %lf |", &pt->step, &pt->wall_s, &pt->psnr_db, &pt->residual,
               &pt->largest_weight) != 5)
        return -1;
    return pt->step > 0 && isfinite(pt->psnr_db) && pt->wall_s >= 0 ? 1 : -1;
}

int sci_ceiling_load(const char *md_path, sci_ceiling *out, sci_error *err)
{
    out->n = 0;
    FILE *f = fopen(md_path, "r");
    if (!f)
        return sci_error_set(err, -errno, "%s: %s", md_path, strerror(errno));
    char line[1024];
    int lineno = 0, rc = 0;
    while (rc == 0 && fgets(line, sizeof line, f)) {
        lineno++;
        sci_ceiling_point pt;
        int k = parse_row(line, &pt);
        if (k == 0)
            continue;
        const sci_ceiling_point *last = out->n ? &out->p[out->n - 1] : NULL;
        if (k < 0)
            rc = sci_error_set(err, SCI_EFORMAT, "%s:%d: not a ceiling row (method, step, wall s, PSNR, residual, "
                                                 "largest weight)", md_path, lineno);
        else if (out->n == SCI_CEILING_MAX_POINTS)
            rc = sci_error_set(err, SCI_EFORMAT, "%s:%d: more than %d rows", md_path, lineno, SCI_CEILING_MAX_POINTS);
        else if (last && strcmp(last->method, pt.method) == 0 && pt.step <= last->step)
            rc = sci_error_set(err, SCI_EFORMAT, "%s:%d: %s: step %d after step %d", md_path, lineno, pt.method,
                               pt.step, last->step);
        else
            out->p[out->n++] = pt;
    }
    fclose(f);
    if (rc == 0 && out->n == 0)
        rc = sci_error_set(err, SCI_EFORMAT, "%s: no ceiling rows", md_path);
    return rc;
}

int sci_ceiling_preset_step(const sci_ceiling *c, const char *method, solver_preset p, int *step, int *prev,
                            double *plateau_db)
{
    double best = -INFINITY;
    for (int i = 0; i < c->n; i++)
        if (strcmp(c->p[i].method, method) == 0 && c->p[i].psnr_db > best)
            best = c->p[i].psnr_db;
    if (best == -INFINITY)
        return -ENOENT;
    const double want = best - sci_ceiling_margin_db(p);
    int before = 0;
    for (int i = 0; i < c->n; i++) {
        if (strcmp(c->p[i].method, method) != 0)
            continue;
        /* a hundredth of a dB of slack: the table prints two decimals */
        if (c->p[i].psnr_db >= want - 0.005) {
            *step = c->p[i].step, *prev = before, *plateau_db = best;
            return 0;
        }
        before = c->p[i].step;
    }
    return -ENOENT; /* not reached: the best point itself qualifies */
}

int sci_ceiling_place_preset(const sci_ceiling *tabs, int n_tabs, const char *method, solver_preset p,
                             sci_ceiling_place *out)
{
    *out = (sci_ceiling_place){.table = -1};
    for (int t = 0; t < n_tabs; t++) {
        int step, prev;
        double plateau;
        if (sci_ceiling_preset_step(&tabs[t], method, p, &step, &prev, &plateau) < 0)
            continue;
        out->tables++;
        if (step > out->step)
            out->step = step, out->prev = prev, out->table = t, out->plateau_db = plateau;
    }
    return out->tables ? 0 : -ENOENT;
}

int sci_ceiling_psnr_at(const sci_ceiling *c, const char *method, double wall_s, double *psnr_db)
{
    const sci_ceiling_point *prev = NULL;
    for (int i = 0; i < c->n; i++) {
        const sci_ceiling_point *q = &c->p[i];
        if (strcmp(q->method, method) != 0)
            continue;
        if (q->wall_s >= wall_s) {
            if (!prev) {
                if (q->wall_s > wall_s)
                    return -ERANGE;
                *psnr_db = q->psnr_db;
                return 0;
            }
            const double t = (wall_s - prev->wall_s) / (q->wall_s - prev->wall_s);
            *psnr_db = prev->psnr_db + t * (q->psnr_db - prev->psnr_db);
            return 0;
        }
        prev = q;
    }
    return prev ? -ERANGE : -ENOENT;
}

int sci_ceiling_place_holds(const sci_ceiling_place *at, int steps) { return steps > at->prev && steps <= at->step; }
