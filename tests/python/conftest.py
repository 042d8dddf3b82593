"""pytest setup for the Python module (make check runs these after the C tests).

The module is imported from the build tree: PYTHONPATH=$BUILD/python (the Makefile sets it). Programs come from
$BUILD (scicap, scicapd), benchmark data from $SCICAP_DATA. A test that cannot find what it needs fails; nothing
is skipped in silence: a skipped test fails the session (see pytest_sessionfinish).
"""
import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILD = ROOT / os.environ.get("BUILD", "build")
DATA = pathlib.Path(os.environ.get("SCICAP_DATA", ROOT.parent / "shared" / "data"))

#: A tiny static3d scene (as tests/integration/test_cli_recon_nerf.c): a checkered sphere before a noise wall.
TINY_STATIC3D = {
    "kind": "static3d", "width": 24, "height": 24, "frames": 4, "seed": 5,
    "objects": [
        {"type": "sphere", "center": [0, 0, -3], "radius": 0.8, "texture": {"type": "checkerboard", "cell": 12}},
        {"type": "plane", "center": [0, 0, -5], "size": [8, 8], "texture": {"type": "noise", "cell": 24}},
    ],
    "camera": {"fx": 24, "cx": 12, "cy": 12, "near": 1.5, "far": 6,
               "start": {"position": [-0.15, 0, 0], "look_at": [0, 0, -3]},
               "end": {"position": [0.15, 0.05, 0], "look_at": [0, 0, -3]}},
}


@pytest.fixture(scope="session")
def scicap_bin():
    path = BUILD / "scicap"
    assert path.exists(), f"{path} is missing: make BUILD={BUILD.name} all"
    return path


@pytest.fixture(scope="session")
def scicapd_bin():
    path = BUILD / "scicapd"
    assert path.exists(), f"{path} is missing: make BUILD={BUILD.name} all"
    return path


@pytest.fixture(scope="session")
def drop40():
    path = DATA / "drop40_cacti.mat"
    assert path.exists(), f"{path} is missing (SCICAP_DATA={DATA})"
    return path


def pytest_sessionfinish(session, exitstatus):
    """No silent skips: a skipped test fails the run (make check must not pass on what it did not test)."""
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    skipped = len(reporter.stats.get("skipped", [])) if reporter else 0
    if skipped and session.exitstatus == 0:
        print(f"\ntests/python: {skipped} test(s) skipped: a skip is a failure here")
        session.exitstatus = 1
