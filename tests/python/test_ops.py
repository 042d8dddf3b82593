"""The operators and the simulator from Python equal the command line's: scicap sim writes meas = A(truth)
computed by the C library; numpy's forward of the same masks and truth must give it to 1e-6, the adjoint must be
mask * y and satisfy <A x, y> = <x, A^T y>, and Python's simulate must give the CLI's folder exactly."""
import subprocess

import numpy as np
import pytest

import scicap


@pytest.fixture(scope="module")
def cli_problem(scicap_bin, tmp_path_factory):
    out = tmp_path_factory.mktemp("ops") / "sim"
    subprocess.run([str(scicap_bin), "sim", "--default", "--seed", "7", "-o", str(out), "-q"], check=True,
                   capture_output=True)
    return out, scicap.read(out, snapshot=1)


def test_forward_equals_cli(cli_problem):
    _, p = cli_problem
    assert p.mask.shape == (8, 256, 256) and p.meas.shape == (256, 256)
    y = scicap.forward(p.mask, p.truth)
    assert y.dtype == np.float32 and y.shape == p.meas.shape
    assert np.max(np.abs(y - p.meas)) <= 1e-6
    ref = np.sum(p.mask.astype(np.float64) * p.truth.astype(np.float64), axis=0)
    assert np.max(np.abs(y - ref)) <= 1e-6


def test_adjoint_equals_definition_and_is_the_transpose(cli_problem):
    _, p = cli_problem
    x = scicap.adjoint(p.mask, p.meas)
    assert x.shape == p.mask.shape
    assert np.max(np.abs(x - p.mask * p.meas[None])) <= 1e-6
    rng = np.random.default_rng(3)
    u = rng.random(p.mask.shape, dtype=np.float32)
    v = rng.random(p.meas.shape, dtype=np.float32)
    lhs = np.vdot(scicap.forward(p.mask, u).astype(np.float64), v)
    rhs = np.vdot(u.astype(np.float64), scicap.adjoint(p.mask, v).astype(np.float64))
    assert abs(lhs - rhs) <= 1e-6 * abs(lhs)


def test_phi_sum_and_residual(cli_problem):
    _, p = cli_problem
    phi = scicap.phi_sum(p.mask)
    ref = np.sum(p.mask.astype(np.float64) ** 2, axis=0)
    ref[ref == 0] = 1
    assert np.max(np.abs(phi - ref)) <= 1e-5
    assert scicap.residual(p.mask, p.truth, p.meas) <= 1e-6


def test_simulate_equals_cli(cli_problem):
    _, p = cli_problem
    (q,) = scicap.simulate(None, seed=7)
    for a, b in ((q.meas, p.meas), (q.mask, p.mask), (q.truth, p.truth)):
        assert np.array_equal(a, b)


def test_problem_dir_and_mat_round_trip(cli_problem, tmp_path):
    _, p = cli_problem
    scicap.write_problem_dir(tmp_path / "copy", [p])
    (q,) = scicap.read(tmp_path / "copy")
    assert np.array_equal(q.meas, p.meas) and np.array_equal(q.mask, p.mask) and np.array_equal(q.truth, p.truth)
    # .mat stores 8-bit-style values times 255 as doubles: the round trip is exact to float32 rounding
    scicap.write_mat(tmp_path / "p.mat", [p])
    (m,) = scicap.read(tmp_path / "p.mat")
    assert np.max(np.abs(m.meas - p.meas)) <= 1e-5 and np.max(np.abs(m.truth - p.truth)) <= 1e-6
    assert scicap.probe(tmp_path / "p.mat") == {"w": 256, "h": 256, "n": 8, "snapshots": 1}
