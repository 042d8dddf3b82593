"""scicap batch (C, cli/batch.c) as a user runs it: inputs as folders, quoted globs and capture ids; a bad input
fails alone; the summary; resuming runs only what has no output; Ctrl-C stops the jobs and keeps the state.
(Slurm: make check-slurm.)"""
import json
import os
import signal
import subprocess
import time

import numpy as np

import scicap

ITERS = ["--", "--iters", "10", "--ssim-every", "0"]


def small(seed):
    rng = np.random.default_rng(seed)
    mask = (rng.random((4, 48, 40)) > 0.5).astype(np.float32)
    truth = rng.random((4, 48, 40), dtype=np.float32)
    return scicap.Problem(meas=scicap.forward(mask, truth), mask=mask, truth=truth, name=f"small{seed}")


def states(out):
    st = json.loads((out / ".batch" / "state.json").read_text())
    return {j["name"]: j["state"] for j in st["jobs"]}


def test_batch_inputs_failure_summary_resume(scicap_bin, tmp_path):
    inp = tmp_path / "in"
    for i in (1, 2):
        scicap.write_problem_dir(inp / f"p{i}", small(i), previews=False)
    scicap.write_mat(inp / "m3.mat", small(3))
    (inp / "bad.mat").write_bytes(b"not a mat file")
    store = tmp_path / "store" / "captures"
    scicap.write_problem_dir(store / "c000007", small(7), previews=False)
    out = tmp_path / "out"
    cmd = [str(scicap_bin), "batch", str(inp / "p*"), str(inp / "m3.mat"), str(inp / "bad.mat"), "c000007",
           "--store", str(tmp_path / "store"), "-o", str(out)]
    r = subprocess.run(cmd + ITERS, capture_output=True, text=True)
    assert r.returncode == 1, r.stderr  # one job failed, the others ran
    assert states(out) == {"p1": "done", "p2": "done", "m3": "done", "bad": "failed", "c000007": "done"}
    assert "5 job(s): 4 done, 1 failed, 0 not finished" in r.stdout
    assert "bad" in r.stdout and "MAT-file" in r.stdout  # the failure's own message in the summary
    assert "batch: 5/5 finished: 4 done, 1 failed" in r.stderr
    for name in ("p1", "p2", "m3", "c000007"):
        res = json.loads((out / name / "result.json").read_text())
        assert res["iterations"] == 10 and res["method"] == "gap-tv"
    # again, with no inputs: only the failed job runs
    r = subprocess.run([str(scicap_bin), "batch", "-o", str(out)], capture_output=True, text=True)
    assert r.returncode == 1 and "5 job(s), 4 already done, 1 to run" in r.stderr
    # fixed: the next run runs it and nothing else
    (inp / "bad.mat").unlink()
    scicap.write_mat(inp / "bad.mat", small(4))
    r = subprocess.run([str(scicap_bin), "batch", "-o", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "4 already done, 1 to run" in r.stderr and set(states(out).values()) == {"done"}
    r = subprocess.run([str(scicap_bin), "batch", "-o", str(out)], capture_output=True, text=True)
    assert r.returncode == 0 and "5 already done, 0 to run" in r.stderr


def test_batch_ctrl_c_keeps_state(scicap_bin, tmp_path):
    for i in (1, 2):
        scicap.write_problem_dir(tmp_path / "in" / f"p{i}", small(i), previews=False)
    out = tmp_path / "out"
    proc = subprocess.Popen([str(scicap_bin), "batch", str(tmp_path / "in"), "-o", str(out), "--", "--iters",
                             "10000000", "--metrics-every", "0", "--ssim-every", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 20
    while not ((out / ".batch" / "state.json").exists() and "running" in states(out).values()):
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == -signal.SIGINT, err  # it dies of the signal, as a shell loop expects
    assert "interrupted" in err and set(states(out).values()) == {"pending"}
    assert sorted(p.name for p in out.iterdir()) == [".batch"]  # nothing half-written left


def test_batch_sighup_status_129_no_temporary_folders(scicap_bin, tmp_path):
    """A closed terminal (SIGHUP) stops a batch as Ctrl-C does: the shell that ran it sees 128 + 1, the state is
    kept, and neither OUTDIR nor the inputs hold a staging folder (NAME.tmp-PID) afterwards."""
    for i in (1, 2):
        scicap.write_problem_dir(tmp_path / "in" / f"p{i}", small(i), previews=False)
    out = tmp_path / "out"
    pidfile = tmp_path / "batch.pid"
    script = '"$@" & echo $! > "$PIDFILE"; wait $!; echo "status=$?"'
    proc = subprocess.Popen(["sh", "-c", script, "sh", str(scicap_bin), "batch", str(tmp_path / "in"), "-o",
                             str(out), "--", "--iters", "10000000", "--metrics-every", "0", "--ssim-every", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PIDFILE": str(pidfile)})
    deadline = time.monotonic() + 20
    while not (pidfile.exists() and pidfile.read_text().strip() and (out / ".batch" / "state.json").exists()
               and "running" in states(out).values()):
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.05)
    os.kill(int(pidfile.read_text()), signal.SIGHUP)
    so, err = proc.communicate(timeout=20)
    assert "status=129" in so, so + err
    assert "interrupted" in err and set(states(out).values()) == {"pending"}
    assert sorted(p.name for p in out.iterdir()) == [".batch"]
    left = [str(p) for p in tmp_path.rglob("*") if ".tmp-" in p.name]
    assert left == [], left
