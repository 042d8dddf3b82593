"""Reconstruction through Python: every method of the CLI's table by name, GAP-TV on drop40 snapshot 1 at the
benchmark's 34.63 dB (the figure tests/integration/test_cli_recon_mat.c gets from the CLI: 34.6289), the same
trace as `scicap recon` row for row, the trace as a structured array, and a result folder like the CLI's."""
import csv
import json
import pathlib
import subprocess

import numpy as np
import pytest

import scicap


def test_methods_are_the_cli_table(scicap_bin):
    names = [m["name"] for m in scicap.methods()]
    usage = subprocess.run([str(scicap_bin), "--help"], capture_output=True, text=True).stdout
    listed = usage.split("reconstruction methods")[1].split("\n\n")[0].splitlines()[1:]
    assert names == [line.split()[0] for line in listed]  # the CLI's list is the table, in its order
    assert names[0] == "gap-tv" and "pnp-ffdnet" in names
    for m in scicap.methods():
        assert set(m["presets"]) == set(scicap.PRESETS)
        for preset, values in m["presets"].items():  # each preset is a whole setting, as settings() gives it
            assert set(values) == set(m["defaults"])
            assert scicap.settings(m["name"], preset=preset) == values
        assert any(k["key"] == "iters" for k in m["keys"])
    gap = scicap.method("gap-tv")
    assert gap["presets"]["fast"]["iters"] < gap["defaults"]["iters"] < gap["presets"]["best"]["iters"]
    assert scicap.settings("gap-tv", preset="fast", tv_weight=0.05)["tv_weight"] == 0.05


def test_gaptv_drop40_snapshot1_psnr(drop40):
    p = scicap.read(drop40, snapshot=1)
    r = scicap.solve(p, "gap-tv")
    assert r.frames.shape == (8, 256, 256) and r.frames.dtype == np.float32
    assert r.iters_done == 100 and r.stopped == ""
    assert r.trace.dtype == scicap.TRACE_DTYPE and len(r.trace) == 100
    assert list(r.trace["iter"]) == list(range(1, 101))
    psnr = r.psnr(p.truth)
    print(f"GAP-TV drop40 snapshot 1 through Python: {psnr:.4f} dB, {r.trace['wall_s'][-1]:.2f} s solver time")
    assert round(psnr, 2) == 34.63
    assert abs(r.trace["psnr"][-1] - psnr) < 1e-9  # the trace's last row measures the result itself
    assert np.all(np.diff(r.trace["wall_s"]) >= 0)


def test_trace_equals_cli(drop40, scicap_bin, tmp_path):
    out = tmp_path / "cli"
    subprocess.run([str(scicap_bin), "recon", str(drop40), "-s", "2", "-i", "12", "-j", "1", "-q", "-o", str(out)],
                   check=True, capture_output=True)
    with open(out / "trace.csv") as f:
        rows = list(csv.DictReader(f))
    r = scicap.solve(scicap.read(drop40, snapshot=2), "gap-tv", iters=12)
    assert len(rows) == len(r.trace) == 12
    for row, t in zip(rows, r.trace):
        assert int(row["iter"]) == t["iter"]
        assert float(row["residual"]) == pytest.approx(t["residual"], rel=1e-6)
        assert float(row["psnr_db"]) == pytest.approx(t["psnr"], abs=1e-4)
    # the result folder from Python has the CLI's layout and figures
    p = scicap.read(drop40, snapshot=2)
    r.write(tmp_path / "py", p)
    cli = json.loads((out / "result.json").read_text())
    py = json.loads((tmp_path / "py" / "result.json").read_text())
    assert sorted(p.name for p in (tmp_path / "py").iterdir()) == sorted(p.name for p in out.iterdir())
    assert py["params"]["iters"] == cli["params"]["iters"] == 12


def test_admmtv_and_progress_can_stop(drop40):
    p = scicap.read(drop40, snapshot=1)
    seen = []

    def progress(row):
        seen.append(row["iter"])
        return row["iter"] >= 5  # True stops the run

    r = scicap.solve(p, "admm-tv", progress=progress, iters=50)
    assert r.stopped == "canceled" and r.iters_done == 5 and seen == [1, 2, 3, 4, 5]
    assert r.frames is not None and np.all(np.isfinite(r.frames))


def test_nerf_tiny():
    from conftest import TINY_STATIC3D
    (p,) = scicap.simulate(TINY_STATIC3D)
    assert p.camera is not None and p.camera["poses"].shape == (4, 3, 4)
    # tiny: 10 steps, 8 samples, a 2^12 hash table, one thread (seconds, not minutes)
    tiny = dict(iters=10, samples=8, log2_table=12, metrics_every=0, threads=1)
    r = scicap.solve(p, "rayformer", preset="fast", patch=8, patches_per_step=2, **tiny)
    assert r.frames.shape == (4, 24, 24) and np.all(np.isfinite(r.frames))
    assert len(r.trace) == 10 and np.all(np.isfinite(r.trace["loss"]))
    assert np.isfinite(r.psnr(p.truth, peak=1.0)) and np.isfinite(r.trace["psnr"][-1])
    assert r.settings["patches_per_step"] == 2 and r.settings["log2_table"] == 12
    s = scicap.solve(p, "scinerf", preset="fast", rays_per_step=128, **tiny)
    assert s.frames.shape == (4, 24, 24) and np.all(np.isfinite(s.frames)) and len(s.trace) == 10
    # the same seed gives the same run
    again = scicap.solve(p, "rayformer", preset="fast", patch=8, patches_per_step=2, **tiny)
    assert np.array_equal(again.frames, r.frames)


def test_pnp_ffdnet_weights_keyword(drop40):
    p = scicap.read(drop40, snapshot=1)
    weights = str(pathlib.Path(drop40).parent / "ffdnet" / "net_gray.pth")
    r = scicap.solve(p, "pnp-ffdnet", iters=10, sigma=[50], weights=weights)
    assert len(r.trace) == 10 and r.psnr(p.truth) > 24  # one sigma stage of ten iterations: 25.05 dB
    with pytest.raises(scicap.Error, match="pnp-ffdnet: weights: /nonexistent.pth"):
        scicap.solve(p, "pnp-ffdnet", iters=1, sigma=[50], weights="/nonexistent.pth")


def test_real_capture_scales_inferred():
    """A real CACTI capture of another lab (grey masks 0-113, float counts, no truth) read with no scale keyword:
    the frames land on [0, 1] as with `scicap recon` (test_cli_recon_mat.c's test_real_capture)."""
    from conftest import DATA
    path = DATA / "real" / "6fan14_cacti.mat"
    assert path.exists(), f"{path} is missing (../shared/data/real/, or $SCICAP_DATA)"
    (p,) = scicap.read(str(path))
    assert p.mask.shape == (14, 256, 256) and p.truth is None
    assert abs(float(p.mask.max()) - 1.0) < 1e-6  # measured grey masks divided by their maximum
    r = scicap.solve(p, "gap-tv")
    p1, p99 = np.percentile(r.frames, [1, 99])
    print(f"real capture through Python: frames 1st percentile {p1:.3f}, 99th {p99:.3f}, "
          f"residual {r.trace['residual'][-1]:.2g}")
    assert 0 <= p1 < 0.2 and 0.3 < p99 < 1.0  # neither black nor saturated
    assert r.trace["residual"][-1] < 0.05
