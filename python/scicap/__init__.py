"""scicap from Python: video snapshot compressive imaging on numpy arrays.

    import scicap
    p = scicap.read("drop40_cacti.mat")[0]          # a Problem: meas (h, w), mask and truth (n, h, w)
    r = scicap.solve(p, "gap-tv")                    # every method of the CLI's table, by name
    print(r.psnr(p.truth), r.trace["psnr"][-1])      # 34.63 dB

The same C library as the scicap command and scicapd (the extension scicap._scicap): the forward and adjoint
operators, every reconstruction method by name with its settings and presets (fast, balanced, best), the trace
as a numpy structured array, .mat files and problem folders, the simulator, and a client of the daemon
(scicap.Client). Errors raise scicap.Error (a RuntimeError; scicap.InputError for bad input, also a ValueError)
with the library's message. Solves release the GIL and stop on Ctrl-C (KeyboardInterrupt). docs/python.md.
"""
import json as _json
import os as _os

# GNU OpenMP threads spin at every barrier by default; on shared cores that turns 0.1 s of GAP-TV into seconds
# (base/runtime_env.h). libgomp reads the policy once, when the extension loads it: set it first unless the user chose.
_os.environ.setdefault("OMP_WAIT_POLICY", "passive")


def _blas_core():
    """OpenBLAS takes a CPU it cannot name (a virtual "Intel Xeon Processor") for a Prescott and runs SSE3 kernels
    although it has AVX-512 (base/runtime_env.h): ask for SkylakeX where the CPU has AVX-512 F, CD, BW, DQ and VL."""
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((line.split() for line in f if line.startswith("flags")), [])
    except OSError:
        return None
    return "SkylakeX" if {"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"} <= set(flags) else None


if _blas_core():  # read by the extension's OpenBLAS when it loads, below
    _os.environ.setdefault("OPENBLAS_CORETYPE", _blas_core())

import numpy as _np  # noqa: E402

from . import _scicap  # noqa: E402
from ._scicap import Error, InputError, adjoint, forward, phi_sum, residual
from .client import Client, DaemonError
from .problem import Problem, Result, problem_from_dict as _problem

__all__ = [
    "Error", "InputError", "DaemonError", "Problem", "Result", "Client", "TRACE_DTYPE", "PRESETS",
    "forward", "adjoint", "phi_sum", "residual", "psnr", "ssim",
    "read", "probe", "write_mat", "write_problem_dir", "simulate", "default_scene",
    "methods", "method", "settings", "solve",
]
__version__ = _scicap.VERSION

#: The presets every method has (recon/solver.h).
PRESETS = ("fast", "balanced", "best")


#: The dtype of a trace row (recon/problem.h, sci_trace_entry).
TRACE_DTYPE = _scicap.TRACE_DTYPE


def psnr(x, truth, peak=None):
    """(mean, per-frame) PSNR in dB; peak None: each truth frame's maximum, else a fixed peak (1 on /255 data)."""
    return _scicap.psnr(x, truth, peak)


def ssim(x, truth, data_range=1.0):
    """(mean, per-frame) SSIM (MATLAB's: Gaussian window sigma 1.5)."""
    return _scicap.ssim(x, truth, data_range)


def read(path, snapshot=None, **options):
    """The problems in a .mat file or a problem folder (io/source.h), as a list of Problem; with snapshot=J
    (1-based) only that one, as a Problem. Options for a .mat (docs/formats.md): mask (a mask file), mask_var,
    meas_var, truth_var, scale (the value of white, default 255, or 'auto'), frames (the first N masks),
    mask_scale (a fully open mask pixel's value), allow_large. Errors name these keywords."""
    problems = [_problem(d) for d in _scicap.read(str(path), **options)]
    if snapshot is None:
        return problems
    if not 1 <= snapshot <= len(problems):
        raise InputError(f"{path} has {len(problems)} snapshot(s); snapshot {snapshot} is out of range")
    return problems[snapshot - 1]


def probe(path):
    """{w, h, n, snapshots}: the sizes a source declares, without reading its data."""
    return _scicap.probe(str(path))


def _as_list(problems):
    return [problems] if isinstance(problems, (Problem, dict)) else list(problems)


def write_mat(path, problems, scale=255):
    """A benchmark-layout .mat (mask, meas, orig; values times scale)."""
    _scicap.write_mat(str(path), _as_list(problems), scale)


def write_problem_dir(dir, problems, overwrite=False, previews=True):
    """A problem folder that scicap recon and scicap batch read (problem.json, float EXR stacks)."""
    problems = _as_list(problems)
    source = getattr(problems[0], "source", None) if problems else None
    _scicap.write_problem_dir(str(dir), problems, overwrite=overwrite, previews=previews, source=source)


def default_scene():
    """The embedded default scene (JSON text) that simulate() uses without a scene."""
    return _scicap.default_scene()


def simulate(scene=None, seed=None, snapshots=0):
    """Simulate a scene (docs/scene-format.md): a file path, JSON text, a dict, or None (the default scene).
    Returns a list of Problem with truth (and a camera for static3d scenes)."""
    if isinstance(scene, dict):
        scene = _json.dumps(scene)
    elif scene is not None:
        scene = str(scene)
    return [_problem(d) for d in _scicap.simulate(scene, seed=seed, snapshots=snapshots)]


def methods():
    """Every reconstruction method (the table the CLI and the daemon use) as dicts: name, summary, needs_camera,
    checkpoints, poses, keys (key, type, min, max, choices, alias, help), defaults, presets."""
    return _scicap.methods()


def method(name):
    """One method's dict from methods(); InputError for an unknown name."""
    for m in _scicap.methods():
        if m["name"] == name:
            return m
    _scicap.settings(name)  # raises InputError naming the methods
    raise InputError(f"unknown method '{name}'")


def _settings_json(preset, settings):
    s = dict(settings)
    if preset is not None:
        s["preset"] = preset
    return _json.dumps(s) if s else None


def settings(method_name="gap-tv", preset=None, **settings):
    """The settings a solve would use: the method's defaults, the preset, then the keys given; checked."""
    return _scicap.settings(method_name, _settings_json(preset, settings))


def solve(problem, method="gap-tv", preset=None, progress=None, **settings):
    """Reconstruct one Problem with a method of the table, by name: its defaults, then the preset (fast,
    balanced, best), then the keys given (scicap.method(name)['keys'], e.g. iters=50, tv_weight=0.05).

    The GIL is released while the solver runs; Ctrl-C raises KeyboardInterrupt promptly. progress (optional) is
    called with each trace row as a dict; returning True stops the run (Result.stopped == 'canceled', the
    frames are the estimate so far). Returns a Result; raises InputError for bad settings or problems, Error
    when the solver fails (e.g. diverges)."""
    r = _scicap.solve(problem, method, _settings_json(preset, settings), progress=progress)
    return Result(**r)
