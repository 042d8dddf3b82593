#!/usr/bin/python3
"""The capture rate with the web page open and updating against the rate without the web view: scicapd on the
simulated bench, a capture of N snapshots timed from its capture.started to its capture.done over the control
socket, alternately with web off and with web on and the page open in headless chromium (each capture.stored makes
the page reload /api/state and a thumbnail). Prints snapshots per second of each run and the ratio of the medians.

    BUILD=build tests/web/capture_rate.py [SNAPSHOTS [ROUNDS]]     (default 40 snapshots, 3 rounds)

A measurement, not a test: on shared cores the figures are noisy (the 1-minute load is printed beside them).
"""
import json
import os
import shutil
import signal
import socket
import statistics
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(__file__))
import test_web_view as tv  # noqa: E402

tv.DEADLINE = time.monotonic() + 1800


def capture_rate(sock_path, n):
    s = socket.socket(socket.AF_UNIX)
    s.connect(sock_path)
    s.sendall((json.dumps({"v": 1, "id": 1, "cmd": "capture", "args": {"count": n}}) + "\n").encode())
    buf, t0 = b"", None
    while True:
        chunk = s.recv(65536)
        if not chunk:
            tv.fail("scicapd closed the control connection")
        buf += chunk
        while b"\n" in buf:
            line, buf = buf.split(b"\n", 1)
            m = json.loads(line)
            ev = m.get("event")
            if ev == "capture.started":
                t0 = time.monotonic()
            elif ev == "capture.done":
                s.close()
                return (n - 1) / (time.monotonic() - t0)  # intervals between the first and last snapshots
            elif ev and ev.endswith(".failed"):
                tv.fail(f"capture failed: {m}")


def one_run(web, n):
    tmp = tempfile.mkdtemp(prefix="scicap-rate-")
    port = tv.free_port()
    daemon, _ = tv.start_daemon(tmp, port, web=web)
    chrome = None
    try:
        if web:
            chrome, ws_url = tv.start_chromium(tmp)
            dt = tv.DevTools(ws_url)
            dt.call("Page.enable")
            dt.call("Page.navigate", url=f"http://127.0.0.1:{port}/")
            while dt.eval(tv.DOM_PROBE)["conn"] != "live":
                time.sleep(0.1)
        return capture_rate(os.path.join(tmp, "control.sock"), n)
    finally:
        if chrome:
            chrome.terminate()
            chrome.wait(10)
        daemon.send_signal(signal.SIGTERM)
        daemon.wait(30)
        shutil.rmtree(tmp, ignore_errors=True)


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    off, on = [], []
    for r in range(rounds):
        for web, out in ((False, off), (True, on)):
            rate = one_run(web, n)
            out.append(rate)
            print(f"round {r + 1}: web {'on, page open' if web else 'off':14s} {rate:6.2f} snapshots/s "
                  f"(load {os.getloadavg()[0]:.2f})", flush=True)
    m_off, m_on = statistics.median(off), statistics.median(on)
    print(f"median: web off {m_off:.2f}/s, web on with the page open {m_on:.2f}/s: "
          f"{100 * (m_on / m_off - 1):+.1f} %")


if __name__ == "__main__":
    main()
