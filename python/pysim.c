/* python/pysim.c — the simulator (sim/simulate.h): a scene file, JSON text or the embedded default scene to
 * problems with truth, as `scicap sim` makes them. The GIL is released while rendering; Ctrl-C stops between
 * snapshots. */
#include "python/pyinterrupt.h"

#include <ctype.h>
#include <stdlib.h>

#include "recon/bayer.h"
#include "sim/default_scene.h"
#include "sim/simulate.h"

static int on_snapshot(void *user, int done, int total)
{
    return py_interrupt_poll(user);
}

/* The RGB truth of a colour scene's snapshot j, a new (3n, h, w) array; NULL with an exception on failure. */
static PyObject *truth_rgb(const sim_scene *sc, int j)
{
    sci_cube *rgb = NULL;
    sci_error err = {0};
    int rc = sci_cube_new(&rgb, sc->w, sc->h, 3 * sc->n, &err);
    if (rc == 0)
        rc = sim_render_truth_rgb(sc, j, rgb, &err);
    PyObject *a = rc < 0 ? py_error_raise(rc, &err) : py_array_from_cube(rgb, 0);
    sci_cube_free(rgb);
    return a;
}

static PyObject *py_simulate(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kws[] = {"scene", "seed", "snapshots", NULL};
    const char *scene = NULL;
    PyObject *seed_o = Py_None;
    int snapshots = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "|z$Oi:simulate", kws, &scene, &seed_o, &snapshots))
        return NULL;
    unsigned long long seed = 0;
    if (seed_o != Py_None && (seed = PyLong_AsUnsignedLongLong(seed_o)) == (unsigned long long)-1 && PyErr_Occurred())
        return NULL;
    const char *s = scene;
    while (s && isspace((unsigned char)*s))
        s++;
    sim_scene *sc = NULL;
    sci_problem **ps = NULL;
    json_t *record = NULL;
    int k = 0, rc;
    sci_error err = {0};
    sim_stats st;
    PyObject *list = NULL;
    py_interrupt in = {0};
    py_interrupt_begin(&in);
    rc = !scene ? sim_default_scene_load(&sc, &err)
         : *s == '{' ? sim_scene_load_string(&sc, "scene", scene, NULL, &err)
                     : sim_scene_load_file(&sc, scene, &err);
    if (rc == 0 && seed_o != Py_None)
        rc = sim_scene_set_seed(sc, seed, &err);
    if (rc == 0 && snapshots > 0)
        rc = sim_scene_set_snapshots(sc, snapshots, &err);
    if (rc == 0)
        rc = sim_run(sc, &ps, &k, &st, on_snapshot, &in, &err);
    if (rc == 0 && !(record = sim_record_new(sc, &st)))
        rc = -ENOMEM;
    py_interrupt_end(&in);
    if (in.raised == 1)
        goto done; /* KeyboardInterrupt (or another handler's exception) is set */
    if (rc < 0) {
        py_error_raise(rc, &err);
        goto done;
    }
    if (!(list = py_problem_list(ps, k)))
        goto done;
    char *text = json_dumps(record, JSON_COMPACT);
    for (int j = 0; j < k; j++) {
        PyObject *d = PyList_GET_ITEM(list, j);
        PyObject *src = PyUnicode_FromString(text ? text : "{}");
        int bad = !src || PyDict_SetItemString(d, "source", src) < 0;
        Py_XDECREF(src);
        if (!bad && sc->cfa) {
            PyObject *rgb = truth_rgb(sc, j), *cfa = PyUnicode_FromString(sci_cfa_name((sci_cfa)sc->cfa));
            bad = !rgb || !cfa || PyDict_SetItemString(d, "truth_rgb", rgb) < 0 ||
                  PyDict_SetItemString(d, "cfa", cfa) < 0;
            Py_XDECREF(rgb);
            Py_XDECREF(cfa);
        }
        if (bad) {
            Py_CLEAR(list);
            break;
        }
    }
    free(text);
done:
    json_decref(record);
    if (ps)
        sci_problem_array_free(ps, k);
    sim_scene_free(sc);
    return list;
}

static PyObject *py_default_scene(PyObject *self, PyObject *unused)
{
    return PyUnicode_FromString(sim_default_scene_json());
}

PyMethodDef py_sim_methods[] = {
    {"simulate", (PyCFunction)(void (*)(void))py_simulate, METH_VARARGS | METH_KEYWORDS,
     "simulate(scene=None, *, seed=None, snapshots=0) -> list of problem dicts\n\n"
     "Simulate a scene (docs/scene-format.md): a file path, JSON text, or None for the embedded default scene.\n"
     "Each problem holds its truth (and a camera for static3d scenes) and 'source', the scene record (JSON text);\n"
     "colour scenes add 'cfa' and 'truth_rgb' (3n, h, w). Ctrl-C stops between snapshots."},
    {"default_scene", py_default_scene, METH_NOARGS, "default_scene() -> str\n\nThe embedded default scene's JSON."},
    {NULL, NULL, 0, NULL},
};
