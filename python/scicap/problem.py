"""Problems and results as Python objects (the C library's sci_problem and sci_result, recon/problem.h).

Arrays follow the library's cube layout (base/cube.h): a stack of n frames of h rows by w columns is a float32
array of shape (n, h, w); a measurement is one frame, (h, w). Values are on the problem's scale: benchmark .mat
data divided by 255 (truth on [0, 1], peak 1).
"""
import dataclasses
import json
from typing import Optional

import numpy as np

from . import _scicap


@dataclasses.dataclass
class Problem:
    """One coded snapshot and what is needed to reconstruct it.

    meas (h, w), mask (n, h, w), truth (n, h, w) or None; camera None or a dict {fx, fy, cx, cy, near, far,
    poses (n, 3, 4) camera-to-world} for the NeRF methods; peak: the value of white; name: shown in printouts.
    source: the simulator's scene record (JSON text) when simulated; cfa and truth_rgb (3n, h, w) for colour
    scenes.
    """

    meas: np.ndarray
    mask: np.ndarray
    truth: Optional[np.ndarray] = None
    camera: Optional[dict] = None
    peak: float = 1.0
    name: str = ""
    source: Optional[str] = None
    cfa: Optional[str] = None
    truth_rgb: Optional[np.ndarray] = None

    @property
    def shape(self):
        """(n, h, w): frames per snapshot, rows, columns."""
        return tuple(self.mask.shape)

    def forward(self, x):
        """A(x) with this problem's masks: (n, h, w) -> (h, w)."""
        return _scicap.forward(self.mask, x)

    def adjoint(self, y):
        """A^T(y) with this problem's masks: (h, w) -> (n, h, w)."""
        return _scicap.adjoint(self.mask, y)

    def __repr__(self):
        n, h, w = self.shape
        extra = ", truth" if self.truth is not None else ""
        extra += ", camera" if self.camera is not None else ""
        return f"Problem({self.name!r}, {w}x{h}, {n} frames{extra}, peak {self.peak:g})"


def problem_from_dict(d):
    """A Problem from the extension's dict (unknown keys are an error: they would be silently lost)."""
    return Problem(**d)


@dataclasses.dataclass
class Result:
    """A reconstruction: frames (n, h, w), the trace (a structured array of TRACE_DTYPE rows, one per
    iteration: iter, wall_s, cpu_s, residual, loss, psnr, psnr_peak1, ssim, meas_residual, max_weight; NaN where
    not computed), the settings used (a dict, as scicap.settings gives them), the method, iterations done, and
    stopped: '' (ran to the end) or 'canceled' (the progress callable returned True)."""

    frames: Optional[np.ndarray]
    trace: np.ndarray
    settings: dict
    method: str
    iters_done: int
    stopped: str = ""

    def psnr(self, truth, peak=None):
        """Mean PSNR in dB against truth; peak None: each truth frame's maximum (the MATLAB convention)."""
        return _scicap.psnr(self.frames, truth, peak)[0]

    def ssim(self, truth, data_range=1.0):
        return _scicap.ssim(self.frames, truth, data_range)[0]

    def write(self, dir, problem, overwrite=False):
        """The folder scicap recon writes (frames as EXR, previews, trace.csv, result.json), all or nothing."""
        _scicap.write_recon(dir, problem, self.frames, self.trace, method=self.method,
                            params=json.dumps(self.settings), overwrite=overwrite)

    def __repr__(self):
        last = self.trace[-1] if len(self.trace) else None
        tail = "" if last is None else f", residual {last['residual']:.3g}"
        if last is not None and np.isfinite(last["psnr"]):
            tail += f", {last['psnr']:.2f} dB"
        return f"Result({self.method}, {self.iters_done} iterations{tail}{', canceled' if self.stopped else ''})"
