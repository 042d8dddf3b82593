/* bench/bench_nerf_compare.c — the NeRF comparison on static3d and photo scenes: GAP-TV, ADMM-TV, scinerf and
 * rayformer with each ablation step added in the paper's order (baseline → +patch sampling → +inter-ray →
 * +intra-ray → +TV), the patch-size study (2, 4, 8, 16), the window-stride study (the + patch rung and the full
 * method with windows of stride 2 and 3, part "stride"), the ladder's rungs above the baseline with each training
 * window's stride drawn from 1 … 4 (part "dilation", patch_stride_max 4; its own table of steps), and scinerf /
 * rayformer with the camera poses optimised
 * from a SCINeRF-style start (start/end on SE(3) from the identity plus a small perturbation: only the
 * intrinsics known). PSNR (peak = 1), SSIM, wall time and, for the NeRF rows, the measurement residual and the mean
 * largest ray weight (the fog diagnostics) per row; the table is rewritten after every row, so a long run
 * shows its progress and a killed one keeps what it finished. Tables: bench/results/nerf_compare_<preset>.md by
 * default, the presets' own comparison (`--scenes corridor,orbit,noisy,tabletop --parts classic,scinerf,full`; each
 * method's presets sit on its own ceiling curve, io/ceiling.h, so the two methods' rows of a preset differ in time:
 * `bench_nerf_recon --place` compares them at equal wall time on the ceilings), and `--out NAME` for another (the
 * ladder, patch and pose studies live in `--out nerf_ablation`, on the fast preset).
 *
 * It takes hours on the 2-core machine (every NeRF row trains a whole preset), so `make bench` only prints how to
 * run it:  build/bench/bench_nerf_compare --run [--preset fast|balanced|best] [--scenes corridor,orbit,noisy]
 *          (a scene is etc/scenes/static3d_NAME.json, else etc/scenes/NAME.json: photo_llff, photo_orbit, photo_noisy)
 *                                         [--parts classic,scinerf,ladder,patch,stride,dilation,poses]
 *                                         [--seeds N | --more-seeds N]
 *        build/bench/bench_nerf_compare --table [--preset P] [--out NAME]   (only rewrites a table from its rows)
 * (part "attention": only the ladder's rungs from + inter-ray on, the ones a change to the attention or TV moves;
 * the baseline and + patch rows are kept; part "full": only the ladder's last rung, the full method). --seeds N
 * trains every NeRF row N times (seeds 1 … N) and keeps the mean
 * and the PSNR's standard deviation: one seed moves a fast-preset row by up to 0.35 dB, more than most ladder steps
 * (docs/nerf-methods.md, "The ablation ladder over three seeds"), so the steps are judged on the mean.
 * --more-seeds N adds seeds n+1 … n+N to each row the run measures that the table holds with n seeds at the same steps and rays (a row it does not hold:
 * seeds 1 … N), so a third seed costs one training per row, not three.
 * Run from the repository root (it reads etc/scenes/ and writes bench/results/). Rows persist in
 * the table's .tsv beside it: a run replaces the rows of the scenes it measures and keeps the others, so the
 * scenes can be measured in separate sittings; each row keeps the load average at its end.
 */
#include <assert.h>
#include <math.h>
#include <stdio.h>
#include <unistd.h>
#include <stdlib.h>
#include <string.h>

#include "base/file.h"
#include "base/runtime_env.h"
#include "bench/bench_load.h"
#include "bench/bench_scene.h"
#include "recon/admmtv.h"
#include "recon/gaptv.h"
#include "recon/sci_ops.h"
#include "recon/pnp_ffdnet.h"
#include "recon/nerf/patch_sampler.h"
#include "recon/nerf/rayformer_solve.h"
#include "recon/nerf/scinerf_solve.h"
#include "sim/simulate.h"

#define MAX_ROWS 256

typedef struct row {
    char scene[32], method[96];
    double psnr, ssim, wall_s, pose_rot, pose_trans;
    double meas_res, max_w; /* NeRF rows: measurement residual ‖y − ΦX‖/‖y‖ and mean largest ray weight over the rays
                             * that hit something, at the end (NaN: not a NeRF row, or a row stored without it) */
    int iters, rays;
    int seeds;      /* trainings averaged (seeds 1 … seeds); 1 for the classic rows */
    double psnr_sd; /* sample standard deviation of the PSNR over the seeds (0 for one) */
    char load[24];  /* 1-minute load average when the row finished */
} row;

static row rows[MAX_ROWS];
static int n_rows;
static char preset[16] = "fast";
static int n_seeds = 1;
/* --more-seeds N: rows the run measures that the table already holds (same steps and rays) are extended by seeds
 * n+1 … n+N, folded into the stored mean and standard deviation; `prior` keeps those stored rows. 0: off. */
static int more_seeds;
static row prior[MAX_ROWS];
static int n_prior;
static char tsv_path[64], md_path[64]; /* bench/results/<out>.{tsv,md} (main) */
/* The ladder's rungs in the paper's order; each ladder row's label (one_scene) contains its rung's tag, which is how
 * the stored rows are recognised (attention_rung, write_ladder_steps). */
static const char *const ladder_tag[5] = {"baseline", "+ patch", "+ inter", "+ intra", "+ TV"};
/* what labels the rungs of part "dilation" */
static const char dilation_tag[] = ", strides 1-4";

static int tsv_rows(FILE *f, void *user, sci_error *err)
{
    (void)user, (void)err;
    fprintf(f, "scene\tmethod\tsteps\trays\tpsnr\tssim\twall_s\tpose_rot\tpose_trans\tload1\tseeds\tpsnr_sd\t"
               "meas_res\tmax_w\n");
    for (int i = 0; i < n_rows; i++) {
        const row *r = &rows[i];
        /* the residual and weight at full float precision: --table rounds them for the Markdown once, as a run does */
        fprintf(f, "%s\t%s\t%d\t%d\t%.4f\t%.6f\t%.3f\t%.5f\t%.5f\t%s\t%d\t%.4f\t%.9g\t%.9g\n", r->scene, r->method,
                r->iters, r->rays, r->psnr, r->ssim, r->wall_s, r->pose_rot, r->pose_trans, r->load, r->seeds,
                r->psnr_sd, r->meas_res, r->max_w);
    }
    return 0;
}

/* Replace a results file with what `rows_fn` writes, or say on stderr why not. */
static void write_table(const char *path, sci_file_writer rows_fn)
{
    sci_error err = {0};
    if (sci_file_write_atomic_with(path, 0644, 0, rows_fn, NULL, &err) < 0)
        fprintf(stderr, "%s\n", err.msg);
}

static void write_tsv(void) { write_table(tsv_path, tsv_rows); }

/* The part of the comparison a row belongs to, by its method label. */
static const char *row_part(const char *method)
{
    if (strncmp(method, "GAP-TV", 6) == 0 || strncmp(method, "ADMM-TV", 7) == 0 || strncmp(method, "PnP-FFDNet", 10) == 0)
        return "classic";
    if (strstr(method, "poses optimised"))
        return "poses";
    if (strstr(method, dilation_tag))
        return "dilation";
    if (strstr(method, ", stride "))
        return "stride";
    /* the SCINeRF rows are labelled by the method's name (its row in recon/solver.h) */
    if (strncmp(method, sci_scinerf_solver.name, strlen(sci_scinerf_solver.name)) == 0)
        return sci_scinerf_solver.name;
    if (strncmp(method, "rayformer full, patch", 21) == 0)
        return "patch";
    return "ladder";
}

/* The ladder's rungs from + inter-ray attention on (part "attention"). */
static int attention_rung(const char *method)
{
    return strcmp(row_part(method), "ladder") == 0 && !strstr(method, ladder_tag[0]) && !strstr(method, ladder_tag[1]);
}

/* The ladder's last rung, the full method (part "full": the row the presets are judged by). */
static int full_rung(const char *method)
{
    return strcmp(row_part(method), "ladder") == 0 && strstr(method, ladder_tag[4]);
}

/* Whether `parts` measures the row labelled `method` again. */
static int redone(const char *method, const char *parts)
{
    return strstr(parts, row_part(method)) || (strstr(parts, "attention") && attention_rung(method)) ||
           (strstr(parts, "full") && full_rung(method));
}

/* Rows in the order of the scenes' first appearance, then of the parts (classic, scinerf, ladder, patch, poses),
 * then as measured. */
static int part_rank(const char *method)
{
    const char *const order[] = {"classic", sci_scinerf_solver.name, "ladder", "patch", "stride", "dilation", "poses"};
    for (int i = 0; i < 7; i++)
        if (strcmp(row_part(method), order[i]) == 0)
            return i;
    return 7;
}

static void sort_rows(void)
{
    /* insertion sort: stable, a few dozen rows */
    char first[MAX_ROWS][32];
    int nf = 0;
    for (int i = 0; i < n_rows; i++) {
        int k;
        for (k = 0; k < nf && strcmp(first[k], rows[i].scene) != 0; k++)
            ;
        if (k == nf)
            snprintf(first[nf++], sizeof first[0], "%s", rows[i].scene);
    }
    for (int i = 1; i < n_rows; i++) {
        row r = rows[i];
        int sr = 0, pr = part_rank(r.method);
        while (strcmp(first[sr], r.scene) != 0)
            sr++;
        int j = i - 1;
        for (; j >= 0; j--) {
            int sj = 0;
            while (strcmp(first[sj], rows[j].scene) != 0)
                sj++;
            if (sj < sr || (sj == sr && part_rank(rows[j].method) <= pr))
                break;
            rows[j + 1] = rows[j];
        }
        rows[j + 1] = r;
    }
}

/* Keeps the stored rows, except those of a scene in the comma-separated list `redo` that belong to a part in
 * `parts` (they are measured again). */
static void read_tsv(const char *redo, const char *parts)
{
    FILE *f = fopen(tsv_path, "r");
    if (!f)
        return;
    char line[512];
    if (!fgets(line, sizeof line, f)) {
        fclose(f);
        return;
    }
    while (n_rows < MAX_ROWS && fgets(line, sizeof line, f)) {
        row r = {0};
        char *fld[14];
        int k = 0;
        line[strcspn(line, "\n")] = 0;
        for (char *s = line, *t; k < 14; s = t + 1) {
            fld[k++] = s;
            if (!(t = strchr(s, '\t')))
                break;
            *t = 0;
        }
        if (k != 10 && k != 12 && k != 14) /* 10: written before --seeds, one seed; 12: before the diagnostics */
            continue;
        char key[40];
        snprintf(key, sizeof key, ",%s,", fld[0]);
        char list[160];
        snprintf(list, sizeof list, ",%s,", redo);
        const int redo_row = strstr(list, key) && redone(fld[1], parts);
        if (redo_row && !more_seeds)
            continue;
        snprintf(r.scene, sizeof r.scene, "%s", fld[0]);
        snprintf(r.method, sizeof r.method, "%s", fld[1]);
        r.iters = atoi(fld[2]), r.rays = atoi(fld[3]);
        r.psnr = strtod(fld[4], NULL), r.ssim = strtod(fld[5], NULL), r.wall_s = strtod(fld[6], NULL);
        r.pose_rot = strtod(fld[7], NULL), r.pose_trans = strtod(fld[8], NULL);
        snprintf(r.load, sizeof r.load, "%s", fld[9]);
        r.seeds = k >= 12 ? atoi(fld[10]) : 1;
        r.psnr_sd = k >= 12 ? strtod(fld[11], NULL) : 0;
        r.meas_res = k == 14 ? strtod(fld[12], NULL) : NAN;
        r.max_w = k == 14 ? strtod(fld[13], NULL) : NAN;
        if (redo_row) {
            if (n_prior < MAX_ROWS)
                prior[n_prior++] = r;
        } else
            rows[n_rows++] = r;
    }
    fclose(f);
}

/* The ladder's steps: each rung's PSNR minus the one below it, per scene that has the whole ladder, and their mean
 * over those scenes (the measure the recipe judges a step by). Rungs are recognised by their labels' order: the
 * baseline of part "ladder", the rungs above it of `part` ("ladder" or "dilation"); `title` heads the table. */
static void write_ladder_steps(FILE *f, const char *part, const char *title)
{
    double step[4][16], psnr[5];
    char scene[16][32];
    int ns = 0;
    for (int i = 0; i < n_rows && ns < 16; i++) {
        if (i > 0 && strcmp(rows[i].scene, rows[i - 1].scene) == 0)
            continue;
        int found = 0;
        for (int k = 0; k < 5; k++)
            for (int j = i; j < n_rows && strcmp(rows[j].scene, rows[i].scene) == 0; j++)
                if (strcmp(row_part(rows[j].method), k ? part : "ladder") == 0 &&
                    strstr(rows[j].method, ladder_tag[k])) {
                    psnr[k] = rows[j].psnr, found++;
                    break;
                }
        if (found != 5)
            continue;
        snprintf(scene[ns], sizeof scene[0], "%s", rows[i].scene);
        for (int k = 0; k < 4; k++)
            step[k][ns] = psnr[k + 1] - psnr[k];
        ns++;
    }
    if (ns == 0)
        return;
    fprintf(f, "\n%s (PSNR gained by each rung over the one below it, dB):\n\n| step |", title);
    for (int s = 0; s < ns; s++)
        fprintf(f, " %s |", scene[s]);
    fprintf(f, " mean |\n|---|");
    for (int s = 0; s <= ns; s++)
        fprintf(f, "---:|");
    fprintf(f, "\n");
    for (int k = 0; k < 4; k++) {
        double m = 0;
        fprintf(f, "| %s |", ladder_tag[k + 1]);
        for (int s = 0; s < ns; s++)
            fprintf(f, " %+.2f |", step[k][s]), m += step[k][s];
        fprintf(f, " %+.2f |\n", m / ns);
    }
}

/* The steps the current preset trains each NeRF method for (rows that differ were measured with an earlier one). */
static void preset_steps(int *rf, int *sn)
{
    sci_rayformer_params q;
    sci_rayformer_params_default(&q);
    sci_rayformer_params_preset(&q, preset);
    sci_scinerf_params v;
    sci_scinerf_params_default(&v);
    sci_scinerf_params_preset(&v, preset);
    *rf = q.iters, *sn = v.iters;
}

/* The first snapshot of scene `name` (etc/scenes/static3d_NAME.json, else etc/scenes/NAME.json) as the simulator
 * makes it; NULL (the error printed) when the scene does not load. Free with sci_problem_free. */
static sci_problem *scene_simulate(const char *name)
{
    char path[256];
    snprintf(path, sizeof path, "etc/scenes/static3d_%s.json", name); /* corridor, ...; else photo_llff, ... */
    if (access(path, R_OK) != 0)
        snprintf(path, sizeof path, "etc/scenes/%s.json", name);
    sci_error err = {0};
    sci_problem *p = bench_scene_first(path, &err);
    if (!p)
        printf("%s: %s\n", path, err.msg);
    return p;
}

/* ‖y − ΦX‖/‖y‖ of the scene's own truth X: the part of the snapshot that is sensor noise, below which a
 * reconstruction's residual only fits noise. NaN when the scene does not load. */
static double truth_residual(const char *name)
{
    sci_problem *p = scene_simulate(name);
    if (!p)
        return NAN;
    double r = p->truth ? sci_op_residual(p->mask, p->truth, p->meas) : NAN;
    sci_problem_free(p);
    return r;
}

/* The footer line that gives each scene's truth residual. */
static void write_noise_floor(FILE *f)
{
    fprintf(f, "\nThe truth's own residual ‖y − ΦX_true‖/‖y‖, the measurement noise (a residual below it fits "
               "noise):");
    for (int i = 0; i < n_rows; i++)
        if (i == 0 || strcmp(rows[i].scene, rows[i - 1].scene) != 0)
            fprintf(f, "%s %s %.1f %%", i ? ";" : "", rows[i].scene, 100 * truth_residual(rows[i].scene));
    fprintf(f, ".\n");
}

static int md_rows(FILE *f, void *user, sci_error *err)
{
    (void)user, (void)err;
    fprintf(f, "Measured by bench/bench_nerf_compare.c (`--run`, preset `%s`, 2 threads): each row one reconstruction "
               "of the scene's single snapshot (N = 8), PSNR with peak = 1 and SSIM averaged over the 8 frames, wall "
               "time of the method (training and the final render; trace evaluations excluded); for the NeRF rows the "
               "measurement residual ‖y − ΦX‖/‖y‖ and the mean largest ray weight over the rays that hit something "
               "(opacity ≥ 0.5) at the end. Known poses: the simulator's camera poses are given; optimised: only the "
               "intrinsics, poses from the identity (pose error = gauge-blind relative rotation and scale-aligned "
               "translation against the truth). RayFormer's transformer learns at 0.1× the hash table's rate.\n\n",
            preset);
    fprintf(f, "| scene | method | steps | rays/step | PSNR dB | SSIM | wall s | residual %% | largest weight |\n"
               "|---|---|---:|---:|---:|---:|---:|---:|---:|\n");
    int rf_steps, sn_steps, stale = 0;
    preset_steps(&rf_steps, &sn_steps);
    for (int i = 0; i < n_rows; i++) {
        const row *r = &rows[i];
        char rays[16] = "", steps[16] = "", res[16] = "", mw[16] = "";
        if (r->rays)
            snprintf(rays, sizeof rays, "%d", r->rays);
        if (r->iters)
            snprintf(steps, sizeof steps, "%d", r->iters);
        if (!isnan(r->meas_res))
            snprintf(res, sizeof res, "%.1f", 100 * r->meas_res);
        if (!isnan(r->max_w))
            snprintf(mw, sizeof mw, "%.2f", r->max_w);
        const size_t sn_len = strlen(sci_scinerf_solver.name);
        if (strcmp(row_part(r->method), "classic") != 0)
            stale |= r->iters != (strncmp(r->method, sci_scinerf_solver.name, sn_len) == 0 ? sn_steps : rf_steps);
        char psnr[32];
        if (r->seeds > 1)
            snprintf(psnr, sizeof psnr, "%.2f ± %.2f (%d seeds)", r->psnr, r->psnr_sd, r->seeds);
        else
            snprintf(psnr, sizeof psnr, "%.2f", r->psnr);
        fprintf(f, "| %s | %s | %s | %s | %s | %.4f | %.*f | %s | %s |\n", r->scene, r->method, steps, rays, psnr,
                r->ssim, r->wall_s < 10 ? 2 : 0, r->wall_s, res, mw);
    }
    if (stale)
        fprintf(f, "\nRows whose steps differ from the preset's as it is now (rayformer %d, scinerf %d) were measured "
                   "with an earlier version of the preset; their residual and largest weight are blank if measured "
                   "before the table had them.\n",
                rf_steps, sn_steps);
    write_ladder_steps(f, "ladder", "The ladder's steps");
    write_ladder_steps(f, "dilation", "The ladder's steps with each training window's stride drawn from 1 … 4");
    int any_pose = 0;
    for (int i = 0; i < n_rows; i++)
        any_pose |= !isnan(rows[i].pose_rot);
    if (any_pose) {
        fprintf(f, "\nPose error of the rows with optimised poses (mean over frames 2…8):\n\n| scene | method | "
                   "rotation rad | translation (scale-aligned) |\n|---|---|---:|---:|\n");
        for (int i = 0; i < n_rows; i++)
            if (!isnan(rows[i].pose_rot))
                fprintf(f, "| %s | %s | %.4f | %.4f |\n", rows[i].scene, rows[i].method, rows[i].pose_rot,
                        rows[i].pose_trans);
    }
    write_noise_floor(f);
    fprintf(f, "\n1-minute load average when each row finished (2 cores; above 2 means another job shared them and "
               "the wall times are inflated):");
    for (int i = 0; i < n_rows; i++)
        if (i == 0 || strcmp(rows[i].scene, rows[i - 1].scene) != 0) {
            double lo = INFINITY, hi = -INFINITY;
            for (int j = i; j < n_rows && strcmp(rows[j].scene, rows[i].scene) == 0; j++) {
                double v = strtod(rows[j].load, NULL);
                if (!isnan(v))
                    lo = fmin(lo, v), hi = fmax(hi, v);
            }
            fprintf(f, "%s %s %.2f–%.2f", i ? ";" : "", rows[i].scene, lo, hi);
        }
    fprintf(f, ".\n");
    return 0;
}

static void write_md(void)
{
    sort_rows();
    write_table(md_path, md_rows);
    write_tsv();
}

/* One finished reconstruction as a row: its last trace entry, the load now, the pose error when poses were
 * learned (`poses` non-NULL). */
static row row_measure(const char *scene, const char *method, const sci_result *r, int rays, const sci_problem *p,
                       const double (*poses)[12])
{
    row w = {0};
    snprintf(w.scene, sizeof w.scene, "%s", scene);
    snprintf(w.method, sizeof w.method, "%s", method);
    const sci_trace_entry *e = &r->trace.e[r->trace.len - 1];
    w.psnr = e->psnr_peak1, w.ssim = e->ssim, w.wall_s = e->wall_s, w.iters = r->iters_done, w.rays = rays;
    w.meas_res = e->meas_residual, w.max_w = e->max_weight;
    w.seeds = 1;
    w.pose_rot = w.pose_trans = NAN;
    char la[64];
    bench_loadavg(la, sizeof la);
    la[strcspn(la, " ")] = 0;
    snprintf(w.load, sizeof w.load, "%s", la);
    if (poses) {
        nerf_poses *pp;
        if (nerf_poses_new(&pp, NERF_POSES_PER_FRAME, p->mask->n, poses, 0, 0, 0, NULL) == 0) {
            nerf_pose_error pe = nerf_poses_relative_error(pp, (const double(*)[12])p->camera->pose);
            w.pose_rot = pe.rot_rad, w.pose_trans = pe.trans_scaled;
            nerf_poses_free(pp);
        }
    }
    return w;
}

/* With several seeds, each training's result as it finishes (the row's mean comes after the last). */
static void seed_done(const row *w, int seed, int last)
{
    if (last > 1)
        fprintf(stderr, "  %s, %s, seed %d of %d: PSNR %.2f dB, %.0f s\n", w->scene, w->method, seed, last, w->psnr,
                w->wall_s);
}

/* Folds the k-th training's row (k from 0) into the running mean `acc`; `psnr_sq` keeps the PSNR's sum of squared
 * deviations (Welford), so psnr_sd holds the sample standard deviation after each fold. */
static void row_fold(row *acc, const row *w, int k, double *psnr_sq)
{
    if (k == 0) {
        *acc = *w, *psnr_sq = 0;
        return;
    }
    const double n = k + 1, d = w->psnr - acc->psnr;
    acc->psnr += d / n;
    *psnr_sq += d * (w->psnr - acc->psnr);
    acc->psnr_sd = sqrt(*psnr_sq / k);
    acc->ssim += (w->ssim - acc->ssim) / n;
    acc->wall_s += (w->wall_s - acc->wall_s) / n;
    acc->pose_rot += (w->pose_rot - acc->pose_rot) / n;
    acc->pose_trans += (w->pose_trans - acc->pose_trans) / n;
    acc->meas_res += (w->meas_res - acc->meas_res) / n;
    acc->max_w += (w->max_w - acc->max_w) / n;
    acc->seeds = k + 1;
    snprintf(acc->load, sizeof acc->load, "%s", w->load);
}

static void add(const row *w)
{
    if (n_rows >= MAX_ROWS)
        return;
    rows[n_rows++] = *w;
    if (w->seeds > 1)
        printf("%-9s %-40s PSNR %6.2f ± %.2f dB (%d seeds)  SSIM %.4f  %8.2f s\n", w->scene, w->method, w->psnr,
               w->psnr_sd, w->seeds, w->ssim, w->wall_s);
    else
        printf("%-9s %-40s PSNR %6.2f dB  SSIM %.4f  %8.2f s\n", w->scene, w->method, w->psnr, w->ssim, w->wall_s);
    fflush(stdout);
    write_md();
}

static void fail(const char *scene, const char *method, const sci_result *r)
{
    printf("%-9s %-40s failed: %s\n", scene, method, r->error.msg);
}

static int progress(const sci_trace_entry *e, void *user)
{
    (void)user;
    if (!isnan(e->psnr_peak1))
        fprintf(stderr, "    step %d, %.0f s, PSNR %.2f dB\n", e->iter, e->wall_s, e->psnr_peak1);
    return 0;
}

/* One training of a NeRF row at `seed`: 0, or < 0 with r->error set; the learned poses into `poses`. */
typedef int (*train_fn)(const sci_problem *p, const void *params, unsigned long long seed, sci_result *r,
                        double (*poses)[12]);

static int train_rayformer(const sci_problem *p, const void *params, unsigned long long seed, sci_result *r,
                           double (*poses)[12])
{
    sci_rayformer_params v = *(const sci_rayformer_params *)params;
    v.seed = seed;
    return sci_rayformer_solve_ex(p, &v, r, progress, NULL, poses);
}

static int train_scinerf(const sci_problem *p, const void *params, unsigned long long seed, sci_result *r,
                         double (*poses)[12])
{
    sci_scinerf_params v = *(const sci_scinerf_params *)params;
    v.seed = seed;
    return sci_scinerf_solve_ex(p, &v, r, progress, NULL, poses);
}

/* The stored row of `scene` and `method` measured with `steps` and `rays`, or NULL (--more-seeds). */
static const row *prior_find(const char *scene, const char *method, int steps, int rays)
{
    for (int i = 0; i < n_prior; i++)
        if (strcmp(prior[i].scene, scene) == 0 && strcmp(prior[i].method, method) == 0 && prior[i].iters == steps &&
            prior[i].rays == rays)
            return &prior[i];
    return NULL;
}

/* Trains the row once per seed (1 … n_seeds, or with --more-seeds the stored row's next ones) and adds the mean; a
 * failed training drops the row (a mean over fewer seeds than the table says would mislead), or keeps the stored
 * row unchanged when it was extending one. `learned`: the poses are optimised (the row reports their error). */
static void seeded_row(const char *scene, const sci_problem *p, const char *name, int steps, int rays, int learned,
                       train_fn train, const void *params)
{
    double(*poses)[12] = malloc((size_t)p->mask->n * sizeof *poses);
    const row *old = more_seeds ? prior_find(scene, name, steps, rays) : NULL;
    const int first = old ? old->seeds + 1 : 1, last = first - 1 + (more_seeds ? more_seeds : n_seeds);
    row acc;
    double sq = 0;
    if (old) {
        /* the stored sd is the sample sd over its seeds: back to Welford's sum of squared deviations */
        acc = *old, sq = old->psnr_sd * old->psnr_sd * (old->seeds - 1);
        fprintf(stderr, "  %s, %s: the stored mean of %d seed%s, %.2f dB, extended by seeds %d … %d\n", scene, name,
                old->seeds, old->seeds > 1 ? "s" : "", old->psnr, first, last);
    } else if (more_seeds)
        fprintf(stderr, "  %s, %s: no stored row of %d steps and %d rays: seeds 1 … %d\n", scene, name, steps, rays,
                last);
    for (int s = first; s <= last; s++) {
        sci_result r = {0};
        if (train(p, params, (unsigned long long)s, &r, poses) < 0) {
            fail(scene, name, &r);
            sci_result_free_contents(&r);
            free(poses);
            if (old) /* the stored row stands as it was */
                add(old);
            return;
        }
        row w = row_measure(scene, name, &r, rays, p, learned ? (const double(*)[12])poses : NULL);
        seed_done(&w, s, last);
        row_fold(&acc, &w, s - 1, &sq);
        sci_result_free_contents(&r);
    }
    free(poses);
    add(&acc);
}

static void rayformer_row(const char *scene, const sci_problem *p, const char *name, const sci_rayformer_params *q)
{
    seeded_row(scene, p, name, q->iters, q->patches_per_step * q->patch * q->patch, q->pose_mode != NERF_POSES_KNOWN,
               train_rayformer, q);
}

static void scinerf_row(const char *scene, const sci_problem *p, const char *name, const sci_scinerf_params *q)
{
    seeded_row(scene, p, name, q->iters, q->rays_per_step, q->pose_mode != NERF_POSES_KNOWN, train_scinerf, q);
}

/* SCINeRF-style pose start: start and end on SE(3) from the identity plus U(±0.005) per twist component; the
 * method's own pose learning rates (what `scicap recon --pose-mode linear` uses). */
static void optimised_poses_rf(sci_rayformer_params *q)
{
    q->pose_mode = NERF_POSES_LINEAR, q->pose_init_identity = 1;
    q->pose_perturb_rot_rad = q->pose_perturb_trans = 0.005;
}

/* patch-size study: the full method at every other patch side (the default's row is the ladder's last), the same
 * number of rays per step */
static void patch_study(const char *name, const sci_problem *p, const sci_rayformer_params *qf)
{
    const sci_rayformer_params q = *qf;
    const int rays = q.patches_per_step * q.patch * q.patch;
    const int sizes[] = {2, 4, 8, 16};
    for (int i = 0; i < 4; i++) {
        sci_rayformer_params v = q;
        if (sizes[i] == q.patch)
            continue;
        v.patch = sizes[i];
        v.patches_per_step = rays / (sizes[i] * sizes[i]) > 0 ? rays / (sizes[i] * sizes[i]) : 1;
        if (p->mask->w < v.patch || p->mask->h < v.patch)
            continue;
        char label[96];
        snprintf(label, sizeof label, "rayformer full, patch %d", sizes[i]);
        rayformer_row(name, p, label, &v);
    }
}

/* window-stride study: the + patch rung and the full method with windows of stride 2 and 3 (the stride-1 rows are
 * the ladder's), the same rays per step: what the rungs trade in coverage of the image a step */
static void stride_study(const char *name, const sci_problem *p, const sci_rayformer_params *qf, double tv)
{
    for (int d = 2; d <= 3; d++)
        for (int rung = 1; rung <= 4; rung += 3) {
            sci_rayformer_params v = *qf;
            sci_rayformer_params_ablation(&v, rung, tv);
            v.patch_stride = d;
            if (p->mask->w < v.patch * d || p->mask->h < v.patch * d)
                continue;
            char label[96];
            snprintf(label, sizeof label, "rayformer %s, stride %d", rung == 1 ? "+ patch sampling" : "full", d);
            rayformer_row(name, p, label, &v);
        }
}

/* the ladder's rungs above the baseline with each training window's stride drawn from 1 … 4 (GRAF's random patch
 * scale; inference keeps adjacent windows): does coverage change what each rung gains? */
static void dilation_study(const char *name, const sci_problem *p, const sci_rayformer_params *qf, double tv)
{
    static const char *const rung_name[5] = {NULL, "+ patch sampling", "+ inter-ray attention",
                                             "+ intra-ray attention", "+ TV (full)"};
    for (int rung = 1; rung <= 4; rung++) {
        sci_rayformer_params v = *qf;
        sci_rayformer_params_ablation(&v, rung, tv);
        v.patch_stride_max = 4;
        if (p->mask->w < nerf_patch_span(v.patch, 4) || p->mask->h < nerf_patch_span(v.patch, 4))
            continue;
        char label[96];
        snprintf(label, sizeof label, "rayformer %s%s", rung_name[rung], dilation_tag);
        assert(strstr(label, ladder_tag[rung]));
        rayformer_row(name, p, label, &v);
    }
}

static void one_scene(const char *name, const char *parts)
{
    sci_problem *p = scene_simulate(name);
    if (!p)
        return;
    printf("%s: %dx%dx%d\n", name, p->mask->w, p->mask->h, p->mask->n);

    if (strstr(parts, "classic")) {
        sci_result r = {0};
        sci_gaptv_params g;
        sci_gaptv_params_default(&g);
        g.metrics_every = 0;
        if (sci_gaptv_solve(p, &g, &r, NULL, NULL) == 0) {
            row w = row_measure(name, "GAP-TV (100 iterations)", &r, 0, p, NULL);
            add(&w);
        }
        sci_result_free_contents(&r);
        r = (sci_result){0};
        sci_admmtv_params a;
        sci_admmtv_params_default(&a);
        a.metrics_every = 0;
        if (sci_admmtv_solve(p, &a, &r, NULL, NULL) == 0) {
            row w = row_measure(name, "ADMM-TV (100 iterations)", &r, 0, p, NULL);
            add(&w);
        }
        sci_result_free_contents(&r);
        /* the learned 2-D prior (the paper's Table 1 row between GAP-TV and SCINeRF), at the same preset */
        r = (sci_result){0};
        sci_pnp_params f;
        sci_pnp_params_default(&f);
        solver_preset pp = SOLVER_PRESET_BALANCED;
        solver_preset_parse(preset, &pp, NULL, NULL);
        sci_pnp_ffdnet_solver.preset(&f, pp);
        f.metrics_every = 0;
        char label[64];
        snprintf(label, sizeof label, "PnP-FFDNet (%d iterations)", f.iters);
        if (sci_pnp_solve(p, &f, &r, NULL, NULL) == 0) {
            row w = row_measure(name, label, &r, 0, p, NULL);
            add(&w);
        } else {
            printf("%s: pnp-ffdnet: %s\n", name, r.error.msg);
        }
        sci_result_free_contents(&r);
    }

    sci_scinerf_params sn;
    sci_scinerf_params_default(&sn);
    sci_scinerf_params_preset(&sn, preset);
    sn.metrics_every = 0;
    if (strstr(parts, sci_scinerf_solver.name))
        scinerf_row(name, p, "scinerf, known poses", &sn);

    sci_rayformer_params q;
    sci_rayformer_params_default(&q);
    sci_rayformer_params_preset(&q, preset);
    q.metrics_every = 0;
    const double tv = q.tv_weight;
    char full[96];
    snprintf(full, sizeof full, "rayformer + TV (full), patch %d", q.patch);
    const char *const ladder[5] = {"rayformer baseline (random rays, no attention, no TV)",
                                   "rayformer + patch sampling", "rayformer + inter-ray attention",
                                   "rayformer + intra-ray attention", full};
    for (int s = 0; s <= 4; s++) {
        assert(strstr(ladder[s], ladder_tag[s]));
        sci_rayformer_params_ablation(&q, s, tv);
        if (redone(ladder[s], parts))
            rayformer_row(name, p, ladder[s], &q);
    }
    if (strstr(parts, "patch"))
        patch_study(name, p, &q);
    if (strstr(parts, "stride"))
        stride_study(name, p, &q, tv);
    if (strstr(parts, "dilation"))
        dilation_study(name, p, &q, tv);
    if (!strstr(parts, "poses")) {
        sci_problem_free(p);
        return;
    }
    /* only the intrinsics known: poses optimised from the identity */
    sci_scinerf_params sp = sn;
    sp.pose_mode = NERF_POSES_LINEAR, sp.pose_init_identity = 1;
    sp.pose_perturb_rot_rad = sp.pose_perturb_trans = 0.005;
    scinerf_row(name, p, "scinerf, poses optimised", &sp);
    sci_rayformer_params qp = q;
    optimised_poses_rf(&qp);
    rayformer_row(name, p, "rayformer full, poses optimised", &qp);
    sci_problem_free(p);
}

int main(int argc, char **argv)
{
    sci_runtime_env_apply(argv); /* the BLAS kernels and OpenMP waiting that scicap and scicapd run with */
    int run = 0;
    char scenes[128] = "corridor,orbit,noisy", parts[128] = "classic,scinerf,ladder,patch,poses", out[32] = "";
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--run") == 0)
            run = 1;
        else if (strcmp(argv[i], "--table") == 0)
            run = 2;
        else if (strcmp(argv[i], "--preset") == 0 && i + 1 < argc)
            snprintf(preset, sizeof preset, "%s", argv[++i]);
        else if (strcmp(argv[i], "--scenes") == 0 && i + 1 < argc)
            snprintf(scenes, sizeof scenes, "%s", argv[++i]);
        else if (strcmp(argv[i], "--parts") == 0 && i + 1 < argc)
            snprintf(parts, sizeof parts, "%s", argv[++i]);
        else if (strcmp(argv[i], "--out") == 0 && i + 1 < argc && strspn(argv[i + 1], "abcdefghijklmnopqrstuvwxyz_") ==
                                                                       strlen(argv[i + 1]) && strlen(argv[i + 1]) < sizeof out)
            snprintf(out, sizeof out, "%s", argv[++i]);
        else if (strcmp(argv[i], "--seeds") == 0 && i + 1 < argc && (n_seeds = atoi(argv[++i])) >= 1 && n_seeds <= 16)
            ;
        else if (strcmp(argv[i], "--more-seeds") == 0 && i + 1 < argc && (more_seeds = atoi(argv[++i])) >= 1 &&
                 more_seeds <= 16)
            ;
        else {
            fprintf(stderr, "usage: bench_nerf_compare --run [--preset fast|balanced|best] [--scenes a,b,c]\n"
                            "         [--parts classic,scinerf,ladder,attention,full,patch,stride,dilation,poses]\n"
                            "         [--seeds 1…16 | --more-seeds 1…16]\n"
                            "         [--out NAME]   (bench/results/NAME.{tsv,md}, a-z and _, up to 31; default nerf_compare_<preset>)\n"
                            "       bench_nerf_compare --table [--preset P] [--out NAME]   (the table from its stored rows)\n"
                            "  the ablation study (ladder, patch sizes, poses) lives in --out nerf_ablation\n");
            return 2;
        }
    }
    if (!out[0])
        snprintf(out, sizeof out, "nerf_compare_%s", preset);
    snprintf(tsv_path, sizeof tsv_path, "bench/results/%s.tsv", out);
    snprintf(md_path, sizeof md_path, "bench/results/%s.md", out);
    if (!run) {
        printf("bench_nerf_compare: the NeRF comparison takes hours; not run by make bench.\n"
               "  run it with: %s --run [--preset balanced] --scenes corridor,orbit,noisy,tabletop --parts classic,scinerf,full\n"
               "  (writes bench/results/nerf_compare_<preset>.md); the ablation study: --out nerf_ablation\n",
               argv[0]);
        return 0;
    }
    sci_rayformer_params chk;
    sci_rayformer_params_default(&chk);
    if (sci_rayformer_params_preset(&chk, preset) < 0) {
        fprintf(stderr, "unknown preset '%s'\n", preset);
        return 2;
    }
    read_tsv(run == 2 ? "" : scenes, parts);
    for (char *s = strtok(scenes, ","); s && run == 1; s = strtok(NULL, ","))
        one_scene(s, parts);
    write_md(); /* also when nothing was measured: the table from the stored rows */
    return 0;
}
