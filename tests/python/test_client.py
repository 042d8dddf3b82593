"""The daemon client: a real scicapd on the simulated bench (no configuration, a temporary folder), asked for
its status, a capture with a reconstruction followed to the end, a reconstruction of a stored capture, its jobs,
an error answer, and shutdown."""
import os
import subprocess
import time

import pytest

import scicap


@pytest.fixture
def daemon(scicapd_bin, tmp_path):
    sock = tmp_path / "control.sock"
    cmd = [str(scicapd_bin), "--no-config", "--socket", str(sock), "--storage", str(tmp_path / "store"),
           "--runtime-dir", str(tmp_path / "run")]
    if os.getuid() == 0:
        cmd.append("--allow-root")  # as root outside systemd (docs/man/scicapd.8)
    log = open(tmp_path / "scicapd.log", "w")
    proc = subprocess.Popen(cmd, stderr=log)
    for _ in range(100):  # the socket file appears at bind(), before listen(): wait for a connection
        try:
            scicap.Client(sock).close()
            break
        except OSError:
            assert proc.poll() is None, (tmp_path / "scicapd.log").read_text()
            time.sleep(0.1)
    yield sock, tmp_path
    # Stop it with a shutdown request (the test's own, or this one if the test failed before) and wait, before
    # any SIGTERM: a SIGTERM that reaches scicapd while it is already shutting down makes it spin (reported:
    # daemon/daemon.c forward_to_main).
    try:
        with scicap.Client(sock, timeout=5) as c:
            c.request("shutdown")
    except (OSError, scicap.DaemonError):
        pass
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        pytest.fail("scicapd did not stop within 30 s of shutdown:\n" + (tmp_path / "scicapd.log").read_text())
    finally:
        log.close()
    assert proc.returncode == 0, (tmp_path / "scicapd.log").read_text()


def test_status_capture_reconstruct(daemon):
    sock, tmp = daemon
    watcher = scicap.Client(sock)
    watched = watcher.watch(timeout=60)  # a second connection that follows everything
    with scicap.Client(sock) as c:
        st = c.status()
        assert st["pid"] > 0 and "devices" in st
        res = c.capture(count=1, reconstruct=True, method="gap-tv", preset="fast")
        assert res["state"] == "queued"
        events = list(c.wait(timeout=60))
        names = [e["event"] for e in events]
        assert "capture.stored" in names and "capture.done" in names and names[-1] == "recon.done", names
        done = events[-1]["data"]
        assert os.path.isdir(done["dir"]) and done["method"] == "gap-tv"
        capture = next(e["data"]["capture"] for e in events if e["event"] == "capture.stored")
        c.reconstruct(capture, method="admm-tv", preset="fast")
        again = list(c.wait(timeout=60))
        assert again[-1]["event"] == "recon.done" and again[-1]["data"]["method"] == "admm-tv"
        assert len(c.jobs()) >= 2
        with pytest.raises(scicap.DaemonError) as e:
            c.reconstruct("c_no_such_capture")
        assert e.value.code in ("not_found", "bad_arguments")
        # a refused argument is named by its keyword, not by the request's JSON position
        with pytest.raises(scicap.DaemonError) as e:
            c.reconstruct(capture, method="x")
        assert e.value.code == "bad_arguments" and e.value.arg == "method", e.value
        assert str(e.value).startswith("bad_arguments: method: unknown method 'x' (gap-tv"), e.value
        assert "request:" not in str(e.value) and "args." not in str(e.value), e.value
        with pytest.raises(scicap.DaemonError) as e:
            c.reconstruct(capture, params={"iters": 0})
        assert e.value.arg == "params['iters']" and "request:" not in str(e.value), e.value
        # the stored captures, with their reconstructions: a bare number names the capture too
        listed = {e["capture"]: e for e in c.captures()}
        assert capture in listed and listed[capture]["truth"], listed
        assert {r["method"] for r in listed[capture]["recons"]} == {"gap-tv", "admm-tv"}, listed[capture]
        c.reconstruct(str(int(capture[1:])), method="gap-tv", preset="fast")
        third = list(c.wait(timeout=60))[-1]["data"]
        assert third["capture"] == capture and third["folder"] == "gap-tv.2", third
        seen = []  # the watcher saw both reconstructions and the capture
        for ev in watched:
            data = ev.get("data") or {}
            seen.append(ev["event"] + (f"({data.get('method')})" if ev["event"] == "recon.done" else ""))
            if seen[-1] == "recon.done(admm-tv)":
                break
        for want in ("capture.started", "capture.stored", "recon.done(gap-tv)", "recon.done(admm-tv)"):
            assert want in seen, " ".join(seen)
        watcher.close()
        c.request("shutdown")
