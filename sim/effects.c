#include "sim/effects.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "io/image.h"
#include "recon/sci_ops.h"

static const char *const fx_names[SIM_FX_COUNT + 1] = {
    "motion_blur", "blur", "vignetting", "dmd_contrast", "misregistration", "jitter",
    "shot_noise", "dark_offset", "saturation", "read_noise", "quantization", NULL};

const char *sim_fx_name(int fx) { return fx >= 0 && fx < SIM_FX_COUNT ? fx_names[fx] : NULL; }

/* Stream ids: effect in the top bits, then snapshot, then row, so every (effect, snapshot, row) has its own
 * sequence. The 0x5346 ("SF") tag keeps them apart from the mask and texture streams. */
static uint64_t fx_stream(int fx, int snapshot, int row)
{
    return (0x5346ULL << 48) | ((uint64_t)fx << 40) | ((uint64_t)(unsigned)snapshot << 20) | (uint64_t)(unsigned)row;
}

static uint64_t draw_hash(double v, uint64_t pos)
{
    uint64_t z;
    memcpy(&z, &v, sizeof z);
    z ^= pos * 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* ---- parsing ------------------------------------------------------------------------------------------- */

static int parse_psf(const sci_json_doc *doc, const char *path, const char *file, const char *base_dir,
                     sim_effects_spec *s, sci_error *err)
{
    char full[4096];
    if (file[0] != '/' && base_dir && *base_dir)
        snprintf(full, sizeof full, "%s/%s", base_dir, file);
    else
        snprintf(full, sizeof full, "%s", file);
    sci_cube *c = NULL;
    int bits = 32, rc = sci_image_read(full, &c, &bits, err);
    if (rc < 0) {
        char msg[SCI_ERROR_MSG_MAX];
        snprintf(msg, sizeof msg, "%s", err ? err->msg : "cannot read");
        return sci_json_fail(doc, err, path, "%s", msg);
    }
    c->n = 1;
    double sum = 0;
    int bad = 0;
    for (size_t i = 0; i < sci_cube_frame_size(c); i++) {
        bad |= !(c->data[i] >= 0) || !isfinite(c->data[i]);
        sum += c->data[i];
    }
    if (c->w % 2 == 0 || c->h % 2 == 0 || c->w > 255 || c->h > 255 || bad || !(sum > 0)) {
        rc = sci_json_fail(doc, err, path,
                           "%s: a PSF image must have odd sides up to 255 pixels (got %dx%d) and finite values "
                           ">= 0 with a positive sum", full, c->w, c->h);
        sci_cube_free(c);
        return rc;
    }
    for (size_t i = 0; i < sci_cube_frame_size(c); i++)
        c->data[i] = (float)(c->data[i] / sum);
    s->psf = c;
    return 0;
}

static int parse_one(const sci_json_doc *doc, const json_t *o, const char *path, int fx, const char *base_dir,
                     sim_effects_spec *s, sci_error *err)
{
    static const char *const keys[SIM_FX_COUNT][4] = {
        {"samples", NULL},
        {"sigma_px", "psf", NULL},
        {"corner", NULL},
        {"leakage", "fill_factor", NULL},
        {"shift_px", "rotation_rad", NULL},
        {"sigma", NULL},
        {NULL},
        {"e", NULL},
        {NULL},
        {"sigma_e", NULL},
        {NULL},
    };
    int rc;
    if (json_is_true(o))
        o = NULL; /* "effect": true lists it with its defaults */
    else if ((rc = sci_json_check_keys(doc, o, path, keys[fx], err)) < 0)
        return rc;
    const json_t *empty = json_object();
    const json_t *obj = o ? o : empty;
    long long samples = s->motion_samples;
    char p[1024];
    switch (fx) {
    case SIM_FX_MOTION_BLUR:
        rc = sci_json_get_int(doc, obj, path, "samples", 0, 2, 1024, &samples, err);
        s->motion_samples = (int)samples;
        break;
    case SIM_FX_BLUR: {
        const char *file = NULL;
        rc = sci_json_get_string(doc, obj, path, "psf", 0, &file, err);
        if (rc == 0) {
            if (json_object_get(obj, "sigma_px")) {
                rc = sci_json_fail(doc, err, path, "give either \"sigma_px\" or \"psf\", not both");
                break;
            }
            s->blur_sigma_px = 0;
            rc = parse_psf(doc, sci_json_path_key(p, sizeof p, path, "psf"), file, base_dir, s, err);
        } else if (rc == 1)
            rc = sci_json_get_double(doc, obj, path, "sigma_px", 0, 0.05, 64, &s->blur_sigma_px, err);
        break;
    }
    case SIM_FX_VIGNETTING:
        rc = sci_json_get_double(doc, obj, path, "corner", 0, 0.01, 1, &s->vignetting_corner, err);
        break;
    case SIM_FX_DMD_CONTRAST:
        if ((rc = sci_json_get_double(doc, obj, path, "leakage", 0, 0, 0.5, &s->leakage, err)) >= 0)
            rc = sci_json_get_double(doc, obj, path, "fill_factor", 0, 0.01, 1, &s->fill_factor, err);
        break;
    case SIM_FX_MISREGISTRATION: {
        const json_t *sh = json_object_get(obj, "shift_px");
        rc = 0;
        if (sh) {
            sci_json_path_key(p, sizeof p, path, "shift_px");
            if (!json_is_array(sh) || json_array_size(sh) != 2 || !json_is_number(json_array_get(sh, 0)) ||
                !json_is_number(json_array_get(sh, 1)) || fabs(json_number_value(json_array_get(sh, 0))) > 1e4 ||
                fabs(json_number_value(json_array_get(sh, 1))) > 1e4) {
                rc = sci_json_fail(doc, err, p, "must be [dx, dy] in pixels, each within ±1e4");
                break;
            }
            s->misreg_dx_px = json_number_value(json_array_get(sh, 0));
            s->misreg_dy_px = json_number_value(json_array_get(sh, 1));
        }
        rc = sci_json_get_double(doc, obj, path, "rotation_rad", 0, -M_PI, M_PI, &s->misreg_rotation_rad, err);
        break;
    }
    case SIM_FX_JITTER:
        rc = sci_json_get_double(doc, obj, path, "sigma", 0, 0, 1, &s->jitter_sigma, err);
        break;
    case SIM_FX_DARK_OFFSET:
        rc = sci_json_get_double(doc, obj, path, "e", 0, 0, 1e7, &s->dark_e, err);
        break;
    case SIM_FX_READ_NOISE:
        rc = sci_json_get_double(doc, obj, path, "sigma_e", 0, 0, 1e6, &s->read_sigma_e, err);
        break;
    default:
        rc = 0;
    }
    json_decref((json_t *)empty);
    return rc < 0 ? rc : 0;
}

int sim_effects_parse(const sci_json_doc *doc, const json_t *root, const char *base_dir, int n, int bit_depth,
                      sim_effects_spec *s, sci_error *err)
{
    memset(s, 0, sizeof *s);
    s->motion_samples = 8;
    s->blur_sigma_px = 1;
    s->vignetting_corner = 0.7;
    s->leakage = 0.002;
    s->fill_factor = 0.92;
    s->misreg_dx_px = 0.5;
    s->misreg_dy_px = 0;
    s->jitter_sigma = 0.05;
    s->dark_e = 10;
    s->read_sigma_e = 3;
    s->photons_white = 1000;
    s->bit_depth = bit_depth;
    int rc;
    const json_t *sensor = json_object_get(root, "sensor");
    if (sensor) {
        static const char *const allowed[] = {"photons_white", "full_well_e", "gain_e_per_dn", NULL};
        if ((rc = sci_json_check_keys(doc, sensor, "sensor", allowed, err)) < 0 ||
            (rc = sci_json_get_double(doc, sensor, "sensor", "photons_white", 0, 1e-3, 1e9, &s->photons_white,
                                      err)) < 0)
            return rc;
    }
    s->full_well_e = s->photons_white * n;
    if (sensor && (rc = sci_json_get_double(doc, sensor, "sensor", "full_well_e", 0, 1e-3, 1e12, &s->full_well_e,
                                            err)) < 0)
        return rc;
    s->gain_e_per_dn = s->full_well_e / (double)((1LL << bit_depth) - 1);
    if (sensor && (rc = sci_json_get_double(doc, sensor, "sensor", "gain_e_per_dn", 0, 1e-6, 1e9,
                                            &s->gain_e_per_dn, err)) < 0)
        return rc;
    const json_t *fx = json_object_get(root, "effects");
    if (!fx)
        return 0;
    if (!json_is_object(fx))
        return sci_json_fail(doc, err, "effects", "must be an object whose keys name effects");
    if ((rc = sci_json_check_keys(doc, fx, "effects", fx_names, err)) < 0)
        return rc;
    for (int i = 0; i < SIM_FX_COUNT; i++) {
        const json_t *o = json_object_get(fx, fx_names[i]);
        if (!o || json_is_false(o))
            continue;
        char p[128];
        sci_json_path_key(p, sizeof p, "effects", fx_names[i]);
        if (!json_is_object(o) && !json_is_true(o)) {
            sim_effects_spec_clear(s);
            return sci_json_fail(doc, err, p, "must be an object of parameters, true, or false");
        }
        if ((rc = parse_one(doc, o, p, i, base_dir, s, err)) < 0) {
            sim_effects_spec_clear(s);
            return rc;
        }
        s->listed |= 1u << i;
    }
    return 0;
}

void sim_effects_spec_clear(sim_effects_spec *s)
{
    sci_cube_free(s->psf);
    s->psf = NULL;
    s->listed = 0;
}

/* ---- plan ---------------------------------------------------------------------------------------------- */

struct sim_effects {
    const sim_effects_spec *spec;
    int w, h, n;
    uint64_t seed;
    sci_cube *xwork;  /* frames the sensor sees (scene and optics effects), or NULL */
    sci_cube *mwork;  /* masks the sensor sees (DMD effects), or NULL */
    float *tmp;       /* one frame of scratch: blur, misregistration, motion blur */
    float *vig;       /* vignetting map */
    float *kernel;    /* Gaussian taps, 2·radius + 1 */
    int radius;
    size_t bytes;
};

#define FX(b) (1u << (b))
#define FX_SCENE (FX(SIM_FX_MOTION_BLUR) | FX(SIM_FX_BLUR) | FX(SIM_FX_VIGNETTING))
#define FX_DMD (FX(SIM_FX_DMD_CONTRAST) | FX(SIM_FX_MISREGISTRATION) | FX(SIM_FX_JITTER))

static void *plan_alloc(sim_effects *fx, size_t bytes)
{
    void *p = calloc(1, bytes);
    if (p)
        fx->bytes += bytes;
    return p;
}

int sim_effects_new(sim_effects **out, const sim_effects_spec *spec, int w, int h, int n, uint64_t seed,
                    sci_error *err)
{
    *out = NULL;
    sim_effects *fx = calloc(1, sizeof *fx);
    if (!fx)
        return sci_error_set(err, -ENOMEM, "out of memory for the effects plan");
    fx->spec = spec;
    fx->w = w;
    fx->h = h;
    fx->n = n;
    fx->seed = seed;
    unsigned L = spec->listed;
    size_t frame = (size_t)w * h * sizeof(float);
    int rc = 0;
    if ((L & FX_SCENE) && (rc = sci_cube_new(&fx->xwork, w, h, n, err)) < 0)
        goto fail;
    if ((L & FX_DMD) && (rc = sci_cube_new(&fx->mwork, w, h, n, err)) < 0)
        goto fail;
    fx->bytes += (fx->xwork ? frame * n : 0) + (fx->mwork ? frame * n : 0);
    if ((L & (FX(SIM_FX_MOTION_BLUR) | FX(SIM_FX_BLUR) | FX(SIM_FX_MISREGISTRATION))) &&
        !(fx->tmp = plan_alloc(fx, frame)))
        goto nomem;
    if (L & FX(SIM_FX_BLUR) && !spec->psf) {
        fx->radius = (int)ceil(3.5 * spec->blur_sigma_px);
        if (!(fx->kernel = plan_alloc(fx, (size_t)(2 * fx->radius + 1) * sizeof(float))))
            goto nomem;
        double sum = 0, k[2 * 224 + 1];
        for (int i = -fx->radius; i <= fx->radius; i++)
            sum += k[i + fx->radius] = exp(-0.5 * i * i / (spec->blur_sigma_px * spec->blur_sigma_px));
        for (int i = 0; i <= 2 * fx->radius; i++)
            fx->kernel[i] = (float)(k[i] / sum);
    }
    if (L & FX(SIM_FX_VIGNETTING)) {
        if (!(fx->vig = plan_alloc(fx, frame)))
            goto nomem;
        /* (1 + (r_c/f)²)⁻² = corner at the corner radius r_c. */
        double rc2 = 0.25 * ((double)w * w + (double)h * h), q = 1 / sqrt(spec->vignetting_corner) - 1;
        double inv_f2 = q > 0 ? q / rc2 : 0;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                double dx = x + 0.5 - 0.5 * w, dy = y + 0.5 - 0.5 * h, a = 1 + (dx * dx + dy * dy) * inv_f2;
                fx->vig[(size_t)y * w + x] = (float)(1 / (a * a));
            }
    }
    *out = fx;
    return 0;
nomem:
    rc = sci_error_set(err, -ENOMEM, "out of memory for the effects' working buffers (%dx%dx%d)", w, h, n);
fail:
    sim_effects_free(fx);
    return rc;
}

void sim_effects_free(sim_effects *fx)
{
    if (!fx)
        return;
    sci_cube_free(fx->xwork);
    sci_cube_free(fx->mwork);
    free(fx->tmp);
    free(fx->vig);
    free(fx->kernel);
    free(fx);
}

size_t sim_effects_work_bytes(const sim_effects *fx) { return fx ? fx->bytes : 0; }

/* ---- scene and optics ---------------------------------------------------------------------------------- */

static int motion_blur(sim_effects *fx, int snapshot, sim_render_fn render, void *user, sci_error *err)
{
    int S = fx->spec->motion_samples;
    size_t fs = (size_t)fx->w * fx->h;
    for (int k = 0; k < fx->n; k++) {
        float *dst = sci_cube_frame(fx->xwork, k);
        memset(dst, 0, fs * sizeof *dst);
        double g = (double)snapshot * fx->n + k;
        for (int s = 0; s < S; s++) {
            /* Sample instants at the centres of S equal slices of [g − ½, g + ½]. */
            int rc = render(user, g - 0.5 + (s + 0.5) / S, fx->tmp);
            if (rc < 0)
                return sci_error_set(err, rc, "motion_blur: rendering frame %.3f failed", g);
            for (size_t i = 0; i < fs; i++)
                dst[i] += fx->tmp[i];
        }
        float inv = 1.0f / (float)S;
        for (size_t i = 0; i < fs; i++)
            dst[i] *= inv;
    }
    return 0;
}

static inline int clampi(int v, int lo, int hi) { return v < lo ? lo : v > hi ? hi : v; }

static void blur_frame(sim_effects *fx, float *f)
{
    int w = fx->w, h = fx->h;
    float *t = fx->tmp;
    if (fx->spec->psf) {
        const sci_cube *p = fx->spec->psf;
        int rx = p->w / 2, ry = p->h / 2;
        memcpy(t, f, (size_t)w * h * sizeof *t);
#pragma omp parallel for schedule(static)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                double acc = 0;
                for (int j = -ry; j <= ry; j++) {
                    const float *row = t + (size_t)clampi(y - j, 0, h - 1) * w;
                    const float *kr = p->data + (size_t)(j + ry) * p->w;
                    for (int i = -rx; i <= rx; i++)
                        acc += (double)kr[i + rx] * row[clampi(x - i, 0, w - 1)];
                }
                f[(size_t)y * w + x] = (float)acc;
            }
        return;
    }
    int r = fx->radius;
    const float *k = fx->kernel;
#pragma omp parallel for schedule(static)
    for (int y = 0; y < h; y++) {
        const float *src = f + (size_t)y * w;
        for (int x = 0; x < w; x++) {
            double acc = 0;
            for (int i = -r; i <= r; i++)
                acc += (double)k[i + r] * src[clampi(x + i, 0, w - 1)];
            t[(size_t)y * w + x] = (float)acc;
        }
    }
#pragma omp parallel for schedule(static)
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double acc = 0;
            for (int i = -r; i <= r; i++)
                acc += (double)k[i + r] * t[(size_t)clampi(y + i, 0, h - 1) * w + x];
            f[(size_t)y * w + x] = (float)acc;
        }
}

/* ---- DMD side ------------------------------------------------------------------------------------------ */

static void misregister_frame(sim_effects *fx, float *m)
{
    const sim_effects_spec *s = fx->spec;
    int w = fx->w, h = fx->h;
    memcpy(fx->tmp, m, (size_t)w * h * sizeof *m);
    const float *src = fx->tmp;
    double c = cos(s->misreg_rotation_rad), sn = sin(s->misreg_rotation_rad), cx = 0.5 * w, cy = 0.5 * h;
#pragma omp parallel for schedule(static)
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            /* Sensor point p sees mask point R(−θ)(p − c − d) + c; bilinear between mirror centres (+0.5). */
            double px = x + 0.5 - cx - s->misreg_dx_px, py = y + 0.5 - cy - s->misreg_dy_px;
            double u = c * px + sn * py + cx - 0.5, v = -sn * px + c * py + cy - 0.5;
            double fu = floor(u), fv = floor(v), au = u - fu, av = v - fv;
            int i = (int)fu, j = (int)fv;
            double acc = 0;
            for (int dj = 0; dj < 2; dj++)
                for (int di = 0; di < 2; di++) {
                    int ii = i + di, jj = j + dj;
                    double wgt = (di ? au : 1 - au) * (dj ? av : 1 - av);
                    if (wgt != 0 && ii >= 0 && ii < w && jj >= 0 && jj < h)
                        acc += wgt * src[(size_t)jj * w + ii];
                }
            m[(size_t)y * w + x] = (float)acc;
        }
}

void sim_effects_jitter_weights(const sim_effects_spec *s, uint64_t seed, int snapshot, int n, double *w,
                                sim_stats *stats)
{
    sci_rng rng;
    sci_rng_seed(&rng, seed, fx_stream(SIM_FX_JITTER, snapshot, 0));
    double sum = 0;
    uint64_t hsh = 0;
    for (int k = 0; k < n; k++) {
        double z = sci_rng_normal(&rng);
        hsh ^= draw_hash(z, (uint64_t)snapshot * n + k);
        w[k] = 1 + s->jitter_sigma * z;
        w[k] = w[k] > 0 ? w[k] : 0;
        sum += w[k];
    }
    for (int k = 0; k < n; k++)
        w[k] = sum > 0 ? w[k] * n / sum : 1;
    if (stats) {
        stats->draws[SIM_FX_JITTER] += n;
        stats->draw_hash[SIM_FX_JITTER] ^= hsh;
    }
}

/* ---- sensor -------------------------------------------------------------------------------------------- */

static void sensor_effect(sim_effects *fx, int e, int snapshot, float *y, sim_stats *stats)
{
    const sim_effects_spec *s = fx->spec;
    int w = fx->w, h = fx->h;
    double p = s->photons_white, inv_p = 1 / p;
    long long draws = 0;
    uint64_t hsh = 0;
    double maxdn = (double)((1LL << s->bit_depth) - 1), g = s->gain_e_per_dn;
#pragma omp parallel for schedule(static) reduction(+ : draws) reduction(^ : hsh)
    for (int r = 0; r < h; r++) {
        float *row = y + (size_t)r * w;
        sci_rng rng;
        if (e == SIM_FX_SHOT_NOISE || e == SIM_FX_READ_NOISE)
            sci_rng_seed(&rng, fx->seed, fx_stream(e, snapshot, r));
        uint64_t base = ((uint64_t)snapshot * h + r) * w;
        for (int x = 0; x < w; x++) {
            double v = row[x], z;
            switch (e) {
            case SIM_FX_SHOT_NOISE:
                z = sci_rng_poisson(&rng, v > 0 ? v * p : 0);
                hsh ^= draw_hash(z, base + x);
                draws++;
                v = z * inv_p;
                break;
            case SIM_FX_DARK_OFFSET:
                v += s->dark_e * inv_p;
                break;
            case SIM_FX_SATURATION:
                v = fmin(v, s->full_well_e * inv_p);
                break;
            case SIM_FX_READ_NOISE:
                z = sci_rng_normal(&rng);
                hsh ^= draw_hash(z, base + x);
                draws++;
                v += s->read_sigma_e * z * inv_p;
                break;
            case SIM_FX_QUANTIZATION: {
                double dn = nearbyint(v * p / g);
                v = fmin(fmax(dn, 0), maxdn) * g * inv_p;
                break;
            }
            }
            row[x] = (float)v;
        }
    }
    if (stats) {
        stats->draws[e] += draws;
        stats->draw_hash[e] ^= hsh;
    }
}

/* ---- measure ------------------------------------------------------------------------------------------- */

int sim_effects_measure(sim_effects *fx, int snapshot, const sci_cube *truth, const sci_cube *mask,
                        sim_render_fn render, void *user, sci_cube *y, sim_stats *stats, sci_error *err)
{
    const sim_effects_spec *s = fx->spec;
    unsigned L = s->listed;
    size_t fs = (size_t)fx->w * fx->h;
    const sci_cube *X = truth, *M = mask;
    int rc;
    if (stats)
        stats->work_bytes = fx->bytes;
#define COUNT(e)                                                                                                  \
    do {                                                                                                          \
        if (stats)                                                                                                \
            stats->passes[e]++;                                                                                   \
    } while (0)
    if (L & FX_SCENE) {
        if (L & FX(SIM_FX_MOTION_BLUR)) {
            if (!render)
                return sci_error_set(err, -EINVAL, "motion_blur is listed but no renderer was given");
            if ((rc = motion_blur(fx, snapshot, render, user, err)) < 0)
                return rc;
            COUNT(SIM_FX_MOTION_BLUR);
        } else
            memcpy(fx->xwork->data, truth->data, sci_cube_count(truth) * sizeof(float));
        X = fx->xwork;
        if (L & FX(SIM_FX_BLUR)) {
            for (int k = 0; k < fx->n; k++)
                blur_frame(fx, sci_cube_frame(fx->xwork, k));
            COUNT(SIM_FX_BLUR);
        }
        if (L & FX(SIM_FX_VIGNETTING)) {
            for (int k = 0; k < fx->n; k++) {
                float *f = sci_cube_frame(fx->xwork, k);
                for (size_t i = 0; i < fs; i++)
                    f[i] *= fx->vig[i];
            }
            COUNT(SIM_FX_VIGNETTING);
        }
    }
    if (L & FX_DMD) {
        memcpy(fx->mwork->data, mask->data, sci_cube_count(mask) * sizeof(float));
        M = fx->mwork;
        if (L & FX(SIM_FX_DMD_CONTRAST)) {
            float a = (float)(s->fill_factor * s->leakage), b = (float)(s->fill_factor * (1 - s->leakage));
            size_t cnt = sci_cube_count(fx->mwork);
            for (size_t i = 0; i < cnt; i++)
                fx->mwork->data[i] = a + b * fx->mwork->data[i];
            COUNT(SIM_FX_DMD_CONTRAST);
        }
        if (L & FX(SIM_FX_MISREGISTRATION)) {
            for (int k = 0; k < fx->n; k++)
                misregister_frame(fx, sci_cube_frame(fx->mwork, k));
            COUNT(SIM_FX_MISREGISTRATION);
        }
        if (L & FX(SIM_FX_JITTER)) {
            double wk[4096];
            if (fx->n > 4096)
                return sci_error_set(err, -EINVAL, "jitter supports at most 4096 frames per snapshot");
            sim_effects_jitter_weights(s, fx->seed, snapshot, fx->n, wk, stats);
            for (int k = 0; k < fx->n; k++) {
                float *f = sci_cube_frame(fx->mwork, k), c = (float)wk[k];
                for (size_t i = 0; i < fs; i++)
                    f[i] *= c;
            }
            COUNT(SIM_FX_JITTER);
        }
    }
    sci_op_forward(M, X, y);
    for (int e = SIM_FX_SHOT_NOISE; e <= SIM_FX_QUANTIZATION; e++)
        if (L & FX(e)) {
            sensor_effect(fx, e, snapshot, y->data, stats);
            COUNT(e);
        }
#undef COUNT
    return 0;
}
