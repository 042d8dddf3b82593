/* drivers/backends.c — the drivers' backend lists and the lookup by name (see the header). */
#include "drivers/backends.h"

#include <stdio.h>
#include <string.h>

#include "drivers/camera_aravis.h"
#include "drivers/camera_v4l2.h"
#include "drivers/trigger_gpiod.h"

static const camera_ops *const cameras[] = {&camera_v4l2_ops, &camera_aravis_ops, NULL};
static const trigger_ops *const triggers[] = {&trigger_gpiod_ops, NULL};
static const dmd_ops *const dmds[] = {&dmd_dlpc900_ops, NULL};

const camera_ops *const *camera_backends_builtin(void) { return cameras; }
const trigger_ops *const *trigger_backends_builtin(void) { return triggers; }
const dmd_ops *const *dmd_backends_builtin(void) { return dmds; }

/* The three kinds differ only in the ops type, and every ops table starts with its name: the lookup and the list
 * are written once, over a kind's tables gathered as (name, table) pairs. */
enum { MAX_BACKENDS = 32 };

typedef struct backend_set {
    const char *name[MAX_BACKENDS];
    const void *ops[MAX_BACKENDS];
    int n;
} backend_set;

static void set_add(backend_set *s, const void *ops, const char *name)
{
    if (s->n < MAX_BACKENDS && name) {
        s->name[s->n] = name;
        s->ops[s->n++] = ops;
    }
}

static const char *set_join(const backend_set *s, char *buf, size_t size)
{
    if (size == 0)
        return buf;
    buf[0] = '\0';
    size_t at = 0;
    for (int i = 0; i < s->n && at < size - 1; i++) {
        int w = snprintf(buf + at, size - at, "%s%s", i ? ", " : "", s->name[i]);
        if (w < 0)
            break;
        at += (size_t)w;
    }
    return buf;
}

static const void *set_find(const backend_set *s, const char *kind, const char *name, sci_error *err)
{
    for (int i = 0; name && i < s->n; i++)
        if (strcmp(s->name[i], name) == 0)
            return s->ops[i];
    char known[512];
    set_join(s, known, sizeof known);
    if (!name)
        sci_error_set(err, SCI_ECONFIG, "%s: no backend given (known: %s)", kind, known);
    else
        sci_error_set(err, SCI_ECONFIG, "%s backend \"%s\" is unknown (known: %s)", kind, name, known);
    return NULL;
}

/* A kind's tables, the drivers' own then extra: the walk is the same for every ops type, so it is written once. */
#define SET_GATHER(s, own, extra)                                                                                 \
    do {                                                                                                          \
        for (int i_ = 0; (own)[i_]; i_++)                                                                         \
            set_add((s), (own)[i_], (own)[i_]->name);                                                             \
        for (int i_ = 0; (extra) && (extra)[i_]; i_++)                                                            \
            set_add((s), (extra)[i_], (extra)[i_]->name);                                                         \
    } while (0)

static backend_set camera_set(const camera_ops *const *extra)
{
    backend_set s = {0};
    SET_GATHER(&s, cameras, extra);
    return s;
}

static backend_set trigger_set(const trigger_ops *const *extra)
{
    backend_set s = {0};
    SET_GATHER(&s, triggers, extra);
    return s;
}

static backend_set dmd_set(const dmd_ops *const *extra)
{
    backend_set s = {0};
    SET_GATHER(&s, dmds, extra);
    return s;
}

const camera_ops *camera_backend_find(const char *name, const camera_ops *const *extra, sci_error *err)
{
    backend_set s = camera_set(extra);
    return set_find(&s, "camera", name, err);
}

const trigger_ops *trigger_backend_find(const char *name, const trigger_ops *const *extra, sci_error *err)
{
    backend_set s = trigger_set(extra);
    return set_find(&s, "trigger", name, err);
}

const dmd_ops *dmd_backend_find(const char *name, const dmd_ops *const *extra, sci_error *err)
{
    backend_set s = dmd_set(extra);
    return set_find(&s, "dmd", name, err);
}

const char *camera_backend_names(const camera_ops *const *extra, char *buf, size_t size)
{
    backend_set s = camera_set(extra);
    return set_join(&s, buf, size);
}

const char *trigger_backend_names(const trigger_ops *const *extra, char *buf, size_t size)
{
    backend_set s = trigger_set(extra);
    return set_join(&s, buf, size);
}

const char *dmd_backend_names(const dmd_ops *const *extra, char *buf, size_t size)
{
    backend_set s = dmd_set(extra);
    return set_join(&s, buf, size);
}
