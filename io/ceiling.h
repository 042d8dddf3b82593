/* io/ceiling.h — the ceiling tables of the NeRF methods (bench/results/nerf_ceiling*.md, written by
 * `bench_nerf_recon --ceiling`) and the rule that places the presets on them.
 *
 * A ceiling table is one long run per method of its fast preset, the learning rate decayed over all of the steps,
 * evaluated every steps/20: rows `| method | step | wall s | PSNR dB | residual | largest weight |`. The rule: a
 * preset sits at the least evaluated step whose PSNR is within the preset's margin of the best PSNR the method
 * reached in the table (fast 1 dB, balanced 0.3 dB, best 0.1 dB: the plateau). A run of n steps decayed over n
 * ends at least as high as the long run at step n (measured: orbit, 900 steps 27.06 dB against 27.01 at step 825
 * and 27.07 at 990 of the long run), so the step the rule gives is enough.
 *
 * Nothing here is thread-safe per object; a loaded table is read-only.
 */
#ifndef SCICAP_IO_CEILING_H
#define SCICAP_IO_CEILING_H

#include "base/error.h"
#include "recon/solver.h"

#define SCI_CEILING_MAX_POINTS 256

typedef struct sci_ceiling_point {
    char method[SOLVER_NAME_MAX];
    int step;
    double wall_s, psnr_db, residual, largest_weight;
} sci_ceiling_point;

typedef struct sci_ceiling {
    sci_ceiling_point p[SCI_CEILING_MAX_POINTS]; /* in the table's order: by method, then by step */
    int n;
} sci_ceiling;

/* The preset's margin below the plateau, dB (fast 1, balanced 0.3, best 0.1); NaN for an unknown preset. */
double sci_ceiling_margin_db(solver_preset p);

/* Read a ceiling table. -errno with the path; SCI_EFORMAT naming the line for a row that does not parse, steps
 * that do not increase within a method, or a table without rows. */
int sci_ceiling_load(const char *md_path, sci_ceiling *out, sci_error *err);

/* Where the rule puts preset p of `method` in this table: *step the least evaluated step within the margin of the
 * method's best PSNR, *prev the evaluated step before it (0 if none), *plateau_db that best PSNR. Returns 0, or
 * -ENOENT when the table has no row of the method. */
int sci_ceiling_preset_step(const sci_ceiling *c, const char *method, solver_preset p, int *step, int *prev,
                            double *plateau_db);

/* The method's PSNR at `wall_s` seconds, interpolated linearly between its evaluated points: for comparing methods
 * at equal wall time. Returns 0, -ENOENT without a row of the method, -ERANGE outside its measured times. */
int sci_ceiling_psnr_at(const sci_ceiling *c, const char *method, double wall_s, double *psnr_db);

/* Where the rule puts preset p of `method` over several tables (several scenes): the table that asks for the most
 * steps decides. */
typedef struct sci_ceiling_place {
    int step;          /* the least evaluated step within the margin on the deciding table */
    int prev;          /* the evaluated step before it there (0 if none): a preset must lie in (prev, step] */
    int table;         /* index of the deciding table */
    int tables;        /* how many of the tables have rows of the method */
    double plateau_db; /* the method's best PSNR on the deciding table */
} sci_ceiling_place;

/* Returns 0, or -ENOENT when no table has a row of the method. */
int sci_ceiling_place_preset(const sci_ceiling *tabs, int n_tabs, const char *method, solver_preset p,
                             sci_ceiling_place *out);

/* 1 when a preset of `steps` steps lies in its place (prev, step], else 0. */
int sci_ceiling_place_holds(const sci_ceiling_place *at, int steps);

#endif
