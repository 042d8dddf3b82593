"""A new method is its file and one table row: the Python module of the test build in $BUILD/extra-method
(Makefile; recon/solver.c with -DSCICAP_EXTRA_SOLVER, tests/extra_method/toy_mean.c) lists "toy-mean" with its
keys, help and ranges, checks its settings and reconstructs with it, while the normal build's module has no such
method. The extra module is a second `scicap` package, so it runs in a child interpreter of its own."""
import json
import os
import subprocess
import sys

import pytest

import scicap
from conftest import BUILD

XM_PYTHON = BUILD / "extra-method" / "python"

CHILD = r"""
import json, scicap
m = scicap.method("toy-mean")
out = {"names": [x["name"] for x in scicap.methods()], "keys": {k["key"]: k for k in m["keys"]},
       "defaults": m["defaults"]}
try:
    scicap.settings("toy-mean", gain=5)
    out["refused"] = None
except scicap.InputError as e:
    out["refused"] = str(e)
p = scicap.simulate()[0]
r = scicap.solve(p, "toy-mean", iters=2, gain=0.8)
out["result"] = {"method": r.method, "iters": r.iters_done, "shape": list(r.frames.shape),
                 "psnr": float(r.psnr(p.truth)), "trace": len(r.trace),
                 "gain": r.settings["gain"]}
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def extra():
    ext = list((XM_PYTHON / "scicap").glob("_scicap*.so"))
    assert ext, f"{XM_PYTHON}/scicap/_scicap*.so is missing: make BUILD={BUILD.name} python-extra-method"
    env = dict(os.environ, PYTHONPATH=str(XM_PYTHON))
    run = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout)


def test_listed_with_its_keys(extra):
    assert extra["names"][-1] == "toy-mean"
    assert extra["names"][:-1] == [m["name"] for m in scicap.methods()]
    gain = extra["keys"]["gain"]
    assert (gain["type"], gain["min"], gain["max"]) == ("float", 0.1, 1.9)
    assert gain["help"] == "step of each projection onto the snapshot"
    assert extra["defaults"]["iters"] == 3 and extra["defaults"]["gain"] == 1


def test_settings_checked_by_the_row(extra):
    assert extra["refused"] is not None and "gain" in extra["refused"] and "1.9" in extra["refused"]


def test_reconstructs(extra):
    r = extra["result"]
    assert r["method"] == "toy-mean" and r["iters"] == 2 and r["shape"] == [8, 256, 256]
    assert r["trace"] == 2 and r["gain"] == 0.8
    assert r["psnr"] > 10


def test_normal_build_does_not_have_it():
    assert "toy-mean" not in [m["name"] for m in scicap.methods()]
    with pytest.raises(scicap.InputError):
        scicap.settings("toy-mean")
