"""Bad input raises Python exceptions carrying the library's message: scicap.InputError (also a ValueError) for
shapes, values and names, scicap.Error for files and failures, with the library's code."""
import errno
import re

import numpy as np
import pytest

import scicap


def small_problem(**over):
    rng = np.random.default_rng(1)
    mask = (rng.random((4, 8, 8)) > 0.5).astype(np.float32)
    truth = rng.random((4, 8, 8), dtype=np.float32)
    d = dict(meas=scicap.forward(mask, truth), mask=mask, truth=truth, name="small")
    d.update(over)
    return scicap.Problem(**d)


def test_shapes():
    p = small_problem()
    with pytest.raises(scicap.InputError, match=r"x has shape \(4, 8, 9\) but mask has \(4, 8, 8\)"):
        scicap.forward(p.mask, np.zeros((4, 8, 9), np.float32))
    with pytest.raises(ValueError, match="stack of shape"):
        scicap.forward(p.mask[0], p.truth)
    with pytest.raises(scicap.InputError, match="real numeric"):
        scicap.adjoint(p.mask, np.zeros((8, 8), np.complex64))
    with pytest.raises(scicap.InputError, match="masks are 8x8 but the measurement is 9x8"):
        scicap.solve(small_problem(meas=np.zeros((8, 9), np.float32)))
    with pytest.raises(scicap.InputError, match="mask is required"):
        scicap.solve(small_problem(mask=None))


def test_values():
    bad = small_problem()
    bad.meas = bad.meas.copy()
    bad.meas[3, 2] = np.nan
    with pytest.raises(scicap.InputError, match="small: measurement") as e:
        scicap.solve(bad)
    assert e.value.code == -4003  # SCI_ENONFINITE
    with pytest.raises(scicap.InputError, match=r"settings.iters: must be an integer in \[1,"):
        scicap.solve(small_problem(), "gap-tv", iters=0)
    with pytest.raises(scicap.InputError, match="settings.preset: must be fast, balanced or best"):
        scicap.solve(small_problem(), "gap-tv", preset="slow")
    names = ", ".join(m["name"] for m in scicap.methods())
    with pytest.raises(scicap.InputError, match=r"unknown method 'gap' \(" + re.escape(names) + r"\)"):
        scicap.solve(small_problem(), "gap")
    with pytest.raises(scicap.InputError, match="no_such_key"):
        scicap.solve(small_problem(), "gap-tv", no_such_key=1)
    with pytest.raises(scicap.InputError, match="needs a camera"):
        scicap.solve(small_problem(), "scinerf", iters=1)
    with pytest.raises(scicap.InputError, match="peak must be > 0"):
        scicap.psnr(small_problem().truth, small_problem().truth, peak=0)


def test_files(tmp_path):
    with pytest.raises(scicap.Error, match="nothing.mat") as e:
        scicap.read(tmp_path / "nothing.mat")
    assert e.value.code == -errno.ENOENT and not isinstance(e.value, ValueError)
    junk = tmp_path / "junk.mat"
    junk.write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    with pytest.raises(scicap.Error, match="junk.mat"):
        scicap.read(junk)
    scicap.write_problem_dir(tmp_path / "once", small_problem())
    with pytest.raises(scicap.Error, match="exists"):
        scicap.write_problem_dir(tmp_path / "once", small_problem())
    with pytest.raises(scicap.Error, match=r"scene:\d+:\d+: "):
        scicap.simulate('{"kind": "video2d", "width": -3}')


def test_errors_name_keywords_not_flags(drop40, tmp_path):
    """Messages the library writes for the command line ("--meas-var NAME", "use --force") name, from Python, the
    keyword argument that does the same."""
    flag = re.compile(r"--[a-z]")
    cases = [
        (lambda: scicap.read(drop40, meas_var="nope"), "meas_var=NAME"),
        (lambda: scicap.read(drop40, mask_var="nope"), "mask_var=NAME"),
        (lambda: scicap.read(drop40, mask_var="nope"), "mask=FILE"),
        (lambda: scicap.read(drop40, truth_var="nope"), "truth_var=NAME"),
        (lambda: scicap.read(drop40, frames=9), "frames=9"),
    ]
    scicap.write_problem_dir(tmp_path / "folder", small_problem())
    cases += [
        (lambda: scicap.read(tmp_path / "folder", scale=3), "mask_var, meas_var, truth_var, frames, scale"),
        (lambda: scicap.write_problem_dir(tmp_path / "folder", small_problem()), "overwrite=True"),
    ]
    for call, keyword in cases:
        with pytest.raises(scicap.Error) as e:
            call()
        text = str(e.value)
        assert keyword in text, text
        assert not flag.search(text), text
    # the keywords the messages name exist: frames and mask_scale are read()'s too
    assert len(scicap.read(drop40, frames=4)[0].mask) == 4
    with pytest.raises(scicap.InputError, match="frames must be >= 0"):
        scicap.read(drop40, frames=-1)
