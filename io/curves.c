#include "io/curves.h"

#include "base/json.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct curve_row {
    char scene[32], method[SOLVER_NAME_MAX], setting[SCI_CURVE_SETTING_MAX];
    double psnr, wall_s, voxels;
    int camera;
} curve_row;

struct sci_curves {
    curve_row *rows;
    size_t n;
};

int sci_curves_load(sci_curves **out, const char *csv_path, sci_error *err)
{
    *out = NULL;
    FILE *f = fopen(csv_path, "r");
    if (!f)
        return sci_error_set(err, -errno, "%s: %s", csv_path, strerror(errno));
    sci_curves *c = calloc(1, sizeof *c);
    size_t cap = 0;
    char line[1024];
    int lineno = 0, rc = 0;
    int col_voxels = -1, col_camera = -1;
    while (c && fgets(line, sizeof line, f)) {
        lineno++;
        char *fields[20];
        int nf = 0;
        line[strcspn(line, "\r\n")] = 0;
        for (char *p = line, *tok; nf < 20 && (tok = strsep(&p, ",")) != NULL;)
            fields[nf++] = tok;
        if (lineno == 1) {
            for (int i = 0; i < nf; i++) {
                if (strcmp(fields[i], "voxels") == 0)
                    col_voxels = i;
                if (strcmp(fields[i], "camera") == 0)
                    col_camera = i;
            }
            if (nf < 7 || strcmp(fields[0], "scene") != 0 || col_voxels < 0 || col_camera < 0) {
                rc = sci_error_set(err, SCI_EFORMAT, "%s:1: not a scicap bench CSV (header)", csv_path);
                break;
            }
            continue;
        }
        if (nf <= col_voxels || nf <= col_camera) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s:%d: %d fields, expected at least %d", csv_path, lineno, nf,
                               (col_voxels > col_camera ? col_voxels : col_camera) + 1);
            break;
        }
        if (c->n == cap) {
            cap = cap ? cap * 2 : 64;
            curve_row *r = realloc(c->rows, cap * sizeof *r);
            if (!r) {
                rc = sci_error_set(err, -ENOMEM, "%s: out of memory", csv_path);
                break;
            }
            c->rows = r;
        }
        curve_row *r = &c->rows[c->n];
        if (strlen(fields[1]) >= sizeof r->method) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s:%d: method name longer than %zu bytes", csv_path, lineno,
                               sizeof r->method - 1);
            break;
        }
        if (strlen(fields[0]) >= sizeof r->scene || strlen(fields[2]) >= sizeof r->setting) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s:%d: scene name longer than %zu bytes or setting longer than %zu",
                               csv_path, lineno, sizeof r->scene - 1, sizeof r->setting - 1);
            break;
        }
        snprintf(r->scene, sizeof r->scene, "%s", fields[0]);
        snprintf(r->method, sizeof r->method, "%s", fields[1]);
        snprintf(r->setting, sizeof r->setting, "%s", fields[2]);
        char *e1, *e2, *e3;
        r->psnr = strtod(fields[3], &e1);
        r->wall_s = strtod(fields[6], &e2);
        r->voxels = strtod(fields[col_voxels], &e3);
        r->camera = atoi(fields[col_camera]);
        if (*e1 || *e2 || *e3 || !isfinite(r->psnr) || !(r->wall_s > 0) || !(r->voxels > 0)) {
            rc = sci_error_set(err, SCI_EFORMAT, "%s:%d: bad number", csv_path, lineno);
            break;
        }
        c->n++;
    }
    fclose(f);
    if (!c)
        return sci_error_set(err, -ENOMEM, "%s: out of memory", csv_path);
    if (rc < 0) {
        sci_curves_free(c);
        return rc;
    }
    *out = c;
    return 0;
}

void sci_curves_free(sci_curves *c)
{
    if (!c)
        return;
    free(c->rows);
    free(c);
}

int sci_curves_pick(const sci_curves *c, const char *method, int has_camera, double voxels, double budget_s,
                    sci_curve_choice *out, sci_error *err)
{
    /* The scenes of this kind. */
    const char *scenes[32];
    int ns = 0;
    for (size_t i = 0; i < c->n; i++) {
        if (c->rows[i].camera != !!has_camera)
            continue;
        int seen = 0;
        for (int s = 0; s < ns && !seen; s++)
            seen = strcmp(scenes[s], c->rows[i].scene) == 0;
        if (!seen && ns < 32)
            scenes[ns++] = c->rows[i].scene;
    }
    int found = 0, fits = 0;
    sci_curve_choice best = {0}, cheapest = {0};
    for (size_t i = 0; i < c->n; i++) {
        const curve_row *r = &c->rows[i];
        if (r->camera != !!has_camera || (method && strcmp(r->method, method) != 0))
            continue;
        /* Each (method, setting) once: at its first row. */
        int dup = 0;
        for (size_t j = 0; j < i && !dup; j++)
            dup = c->rows[j].camera == r->camera && strcmp(c->rows[j].method, r->method) == 0 &&
                  strcmp(c->rows[j].setting, r->setting) == 0;
        if (dup)
            continue;
        double sum = 0, worst = 0;
        int on = 0;
        for (size_t j = i; j < c->n; j++) {
            const curve_row *q = &c->rows[j];
            if (q->camera != r->camera || strcmp(q->method, r->method) != 0 || strcmp(q->setting, r->setting) != 0)
                continue;
            sum += q->psnr;
            worst = fmax(worst, q->wall_s * voxels / q->voxels);
            on++;
        }
        if (on < ns)
            continue; /* not measured on every scene of the kind */
        sci_curve_choice ch = {.predicted_s = worst, .mean_psnr = sum / on, .scenes = on};
        snprintf(ch.method, sizeof ch.method, "%s", r->method);
        snprintf(ch.setting, sizeof ch.setting, "%s", r->setting);
        if (!found || ch.predicted_s < cheapest.predicted_s)
            cheapest = ch;
        found = 1;
        if (ch.predicted_s <= budget_s && (!fits || ch.mean_psnr > best.mean_psnr ||
                                           (ch.mean_psnr == best.mean_psnr && ch.predicted_s < best.predicted_s))) {
            best = ch;
            fits = 1;
        }
    }
    if (!found)
        return sci_error_set(err, -ENOENT, "no measured setting%s%s for problems %s a camera", method ? " of " : "",
                             method ? method : "", has_camera ? "with" : "without");
    if (!fits) {
        *out = cheapest;
        return sci_error_set(err, -ERANGE,
                             "no setting fits %.3g s: the cheapest, %s %s, is predicted to take %.3g s", budget_s,
                             cheapest.method, cheapest.setting, cheapest.predicted_s);
    }
    *out = best;
    return 0;
}

json_t *sci_curves_setting_json(const char *setting)
{
    char buf[SCI_CURVE_SETTING_MAX];
    if (strlen(setting) >= sizeof buf)
        return NULL;
    json_t *o = json_object();
    snprintf(buf, sizeof buf, "%s", setting);
    for (char *p = buf, *tok; (tok = strsep(&p, " ")) != NULL;) {
        if (!*tok)
            continue;
        const char *eq = strchr(tok, '=');
        /* each token as `scicap recon --set` reads it, so a measured lambda=0.5 comes back a number */
        if (!eq || !eq[1] || sci_json_set_kv(o, tok) < 0) {
            json_decref(o);
            return NULL;
        }
    }
    return o;
}

/* Where a text being built in buf (n bytes) goes on once `off` bytes of it are counted, and the room left there:
 * none once the text has outgrown buf, so the snprintf calls go on counting what it would need. */
static char *text_end(char *buf, size_t n, size_t off, size_t *room)
{
    *room = off < n ? n - off : 0;
    return buf + (off < n ? off : n);
}

/* A number as the setting's text writes it; what snprintf returns. */
static int format_number(char *buf, size_t n, const json_t *v)
{
    if (json_is_integer(v))
        return snprintf(buf, n, "%lld", (long long)json_integer_value(v));
    const double x = json_real_value(v);
    int prec = 15, len;
    do
        len = snprintf(buf, n, "%.*g", prec, x);
    while ((size_t)len < n && strtod(buf, NULL) != x && ++prec <= 17);
    /* a real that prints as an integer (3) would read back an integer */
    if ((size_t)len < n && !strpbrk(buf, ".eEin"))
        len += snprintf(buf + len, n - (size_t)len, ".0");
    return len;
}

/* A string as the setting's text writes it: itself, or JSON-quoted when `--set` would read it as another value. */
static int format_string(char *buf, size_t n, const char *s)
{
    if (!*s || strpbrk(s, " ,"))
        return -EINVAL;
    for (const char *c = s; *c; c++)
        if ((unsigned char)*c < 0x20 || *c == 0x7f)
            return -EINVAL;
    json_t *as_read = json_loads(s, JSON_DECODE_ANY, NULL);
    json_decref(as_read);
    if (!as_read)
        return snprintf(buf, n, "%s", s);
    json_t *str = json_string(s);
    char *quoted = str ? json_dumps(str, JSON_ENCODE_ANY) : NULL;
    json_decref(str);
    const int len = quoted ? snprintf(buf, n, "%s", quoted) : -ENOMEM;
    free(quoted);
    return len;
}

/* One value; what snprintf returns, or -EINVAL. */
static int format_value(char *buf, size_t n, const json_t *v)
{
    if (json_is_string(v))
        return format_string(buf, n, json_string_value(v));
    if (json_is_boolean(v) || json_is_null(v))
        return snprintf(buf, n, "%s", json_is_null(v) ? "null" : json_is_true(v) ? "true" : "false");
    if (json_is_number(v))
        return format_number(buf, n, v);
    if (!json_is_array(v) || json_array_size(v) == 0)
        return -EINVAL;
    size_t i, len = 0, room;
    json_t *e;
    json_array_foreach(v, i, e) {
        if (!json_is_number(e))
            return -EINVAL;
        char *end = text_end(buf, n, len, &room); /* its own statement: `room` is read after text_end sets it */
        len += (size_t)snprintf(end, room, "%s", i ? "/" : "");
        end = text_end(buf, n, len, &room);
        len += (size_t)format_number(end, room, e);
    }
    return (int)len;
}

int sci_curves_setting_text(const json_t *settings, char *buf, size_t n)
{
    const char *key;
    json_t *v;
    size_t off = 0, room;
    int rc = json_is_object(settings) ? 0 : -EINVAL;
    if (rc == 0)
        json_object_foreach((json_t *)settings, key, v) {
            if (!*key || strpbrk(key, "= ,") || strlen(key) >= 128) {
                rc = -EINVAL;
                break;
            }
            char *end = text_end(buf, n, off, &room);
            off += (size_t)snprintf(end, room, "%s%s=", off ? " " : "", key);
            end = text_end(buf, n, off, &room);
            const int vlen = format_value(end, room, v);
            if (vlen < 0) {
                rc = vlen;
                break;
            }
            off += (size_t)vlen;
        }
    if (rc == 0 && off >= n)
        rc = -ENAMETOOLONG;
    if (rc < 0 && n)
        buf[0] = 0; /* nothing half-written */
    return rc;
}
