#!/usr/bin/python3
"""The web view in a real browser: scicapd on the simulated bench with the web view on 127.0.0.1, Debian's
chromium headless driven through the DevTools protocol (a minimal WebSocket client on the standard library).

Checks, from the DOM: the page connects to the event stream; a capture requested with a reconstruction (through
the web's own control route, with the token) appears in the captures list; the reconstruction's plot gets points
while it runs (before its recon.done); the reconstruction's frame previews load; the page raised no JavaScript
exception and no Content-Security-Policy violation; at phone width nothing overflows sideways. Screenshots at
1280x800 and 390x844 go to the artefacts folder printed at the end (SCICAP_WEB_ARTIFACTS, default
BUILD/web-artifacts).

Fails (never skips) when chromium or the build is missing. Bounded: 180 s.
"""
import base64
import json
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

BUILD = os.environ.get("BUILD", "build")
ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
OUT = os.path.abspath(os.environ.get("SCICAP_WEB_ARTIFACTS", os.path.join(ROOT, BUILD, "web-artifacts")))
DEADLINE = time.monotonic() + 180


def fail(msg):
    print(f"tests/web: FAIL: {msg}", file=sys.stderr)
    raise SystemExit(1)


def left():
    t = DEADLINE - time.monotonic()
    if t <= 0:
        fail("over the 180 s bound")
    return t


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


# ---- a WebSocket client, enough for the DevTools protocol (RFC 6455: text frames, client masking) ----

class WebSocket:
    def __init__(self, url):
        assert url.startswith("ws://")
        hostport, path = url[5:].split("/", 1)
        host, port = hostport.rsplit(":", 1)
        self.sock = socket.create_connection((host, int(port)), timeout=30)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET /{path} HTTP/1.1\r\nHost: {hostport}\r\nUpgrade: websocket\r\n"
                           f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n")
                          .encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(4096)
            if not chunk:
                fail("DevTools closed the WebSocket handshake")
            head += chunk
        if b" 101 " not in head.split(b"\r\n")[0]:
            fail(f"DevTools refused the WebSocket: {head[:200]!r}")
        self.buf = head.split(b"\r\n\r\n", 1)[1]

    def _read(self, n):
        while len(self.buf) < n:
            chunk = self.sock.recv(1 << 20)
            if not chunk:
                fail("DevTools closed the connection")
            self.buf += chunk
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def send(self, text):
        data = text.encode()
        n = len(data)
        head = bytes([0x81])
        if n < 126:
            head += bytes([0x80 | n])
        elif n < 65536:
            head += bytes([0x80 | 126]) + struct.pack(">H", n)
        else:
            head += bytes([0x80 | 127]) + struct.pack(">Q", n)
        mask = os.urandom(4)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(data))
        self.sock.sendall(head + mask + masked)

    def recv(self):
        message = b""
        while True:
            b0, b1 = self._read(2)
            n = b1 & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._read(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._read(8))[0]
            mask = self._read(4) if b1 & 0x80 else None
            payload = self._read(n)
            if mask:
                payload = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
            opcode = b0 & 0x0F
            if opcode == 8:
                fail("DevTools closed the WebSocket")
            if opcode in (9, 10):  # ping/pong: not sent by DevTools in practice; ignored
                continue
            message += payload
            if b0 & 0x80:
                return message.decode()


class DevTools:
    def __init__(self, ws_url):
        self.ws = WebSocket(ws_url)
        self.next_id = 0
        self.problems = []  # exceptions and CSP violations reported by the page

    def _note(self, m):
        method = m.get("method", "")
        p = m.get("params", {})
        if method == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            self.problems.append("exception: " + (d.get("exception", {}).get("description") or d.get("text", "")))
        elif method == "Log.entryAdded":
            e = p.get("entry", {})
            if e.get("level") == "error":
                self.problems.append(f"console {e.get('source')}: {e.get('text')} {e.get('url', '')}")

    def call(self, method, **params):
        self.next_id += 1
        mid = self.next_id
        self.ws.send(json.dumps({"id": mid, "method": method, "params": params}))
        while True:
            left()
            m = json.loads(self.ws.recv())
            if m.get("id") == mid:
                if "error" in m:
                    fail(f"DevTools {method}: {m['error']}")
                return m.get("result", {})
            self._note(m)

    def eval(self, expr):
        r = self.call("Runtime.evaluate", expression=expr, returnByValue=True)
        if "exceptionDetails" in r:
            fail(f"evaluating {expr!r}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def screenshot(self, path, width, height, mobile):
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1,
                  mobile=mobile)
        time.sleep(0.8)  # the chart resizes on the next frame
        shot = self.call("Page.captureScreenshot", format="png")
        with open(path, "wb") as f:
            f.write(base64.b64decode(shot["data"]))
        m = self.call("Page.getLayoutMetrics")
        size = m.get("cssContentSize") or m.get("contentSize")
        full = self.call("Page.captureScreenshot", format="png", captureBeyondViewport=True,
                         clip={"x": 0, "y": 0, "width": width, "height": size["height"], "scale": 1})
        with open(path.replace(".png", "-full.png"), "wb") as f:
            f.write(base64.b64decode(full["data"]))
        return size


# ---- the daemon ----

def http(port, path, body=None, token=None):
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", data=body,
                                 method="POST" if body is not None else "GET")
    if token:
        req.add_header("Authorization", "Bearer " + token)
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def start_daemon(tmp, port, web=True):
    binary = os.path.join(ROOT, BUILD, "scicapd")
    if not os.access(binary, os.X_OK):
        fail(f"no {binary}: build it first (make BUILD={BUILD} all)")
    cfg = os.path.join(tmp, "scicapd.json")
    with open(cfg, "w") as f:
        doc = {"version": 1}
        if web:
            doc["web"] = {"listen": f"127.0.0.1:{port}", "control": True, "token_file": os.path.join(tmp, "web.token")}
        json.dump(doc, f)
    sock = os.path.join(tmp, "control.sock")
    args = [binary, "--config", cfg, "--socket", sock, "--storage", os.path.join(tmp, "store"),
            "--runtime-dir", os.path.join(tmp, "run"), "--no-fsync"]
    if os.geteuid() == 0:
        args.append("--allow-root")
    log = open(os.path.join(tmp, "scicapd.log"), "w")
    proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT)
    if not web:
        while not os.path.exists(sock):
            if proc.poll() is not None:
                fail(f"scicapd exited at start ({proc.returncode}); log {log.name}")
            time.sleep(0.05)
        time.sleep(0.2)
        return proc, None
    while left() > 0:
        if proc.poll() is not None:
            fail(f"scicapd exited at start ({proc.returncode}); log {log.name}")
        try:
            if http(port, "/api/state")[0] == 200:
                break
        except OSError:
            pass
        time.sleep(0.1)
    with open(os.path.join(tmp, "web.token")) as f:
        return proc, f.read().strip()


def start_chromium(tmp):
    exe = shutil.which("chromium")
    if not exe:
        fail("chromium not found: the browser test needs Debian's chromium (make deps installs it)")
    prof = os.path.join(tmp, "chrome")
    args = [exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run", "--no-default-browser-check",
            "--disable-extensions", "--disable-background-networking", "--remote-debugging-port=0",
            f"--user-data-dir={prof}", "--window-size=1280,800", "about:blank"]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=open(os.path.join(tmp, "chromium.log"), "w"))
    port_file = os.path.join(prof, "DevToolsActivePort")
    while not os.path.exists(port_file) or os.path.getsize(port_file) == 0:
        if proc.poll() is not None or left() < 150:
            fail(f"chromium did not start its DevTools endpoint; log {tmp}/chromium.log")
        time.sleep(0.1)
    with open(port_file) as f:
        dport = int(f.readline())
    with urllib.request.urlopen(f"http://127.0.0.1:{dport}/json/list", timeout=10) as r:
        pages = [t for t in json.load(r) if t.get("type") == "page"]
    if not pages:
        fail("chromium has no page target")
    return proc, pages[0]["webSocketDebuggerUrl"]


DOM_PROBE = """(() => {
  if (!document.body || !document.getElementById('conn')) return {conn: ''};  // still loading
  const b = document.body.dataset;
  const imgs = [...document.querySelectorAll('#recon-frames img')];
  return {conn: document.getElementById('conn').textContent,
          captures: [...document.querySelectorAll('#captures a[data-capture]')].map(a => a.dataset.capture),
          points: +(b.points || 0), pointsWhileRunning: +(b.pointsWhileRunning || 0), recon: b.recon || '',
          frames: imgs.length, framesLoaded: imgs.filter(i => i.dataset.loaded === '1' && i.naturalWidth > 0).length,
          framesFailed: imgs.filter(i => i.dataset.loaded === 'error').length,
          jobs: document.querySelectorAll('#jobs tr[data-job]').length,
          devices: document.querySelectorAll('#devices li').length, curves: +(b.curves || 0), diff: +(b.diff || 0),
          methods: [...document.querySelectorAll('#method option')].map(o => o.value),
          anim: (() => { const a = document.getElementById('recon-anim'); return a.complete && a.naturalWidth > 0; })(),
          overflow: document.documentElement.scrollWidth - window.innerWidth};
})()"""


def main():
    os.makedirs(OUT, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix="scicap-web-")
    port = free_port()
    daemon = chrome = None
    try:
        daemon, token = start_daemon(tmp, port)
        chrome, ws_url = start_chromium(tmp)
        dt = DevTools(ws_url)
        for domain in ("Page", "Runtime", "Log"):
            dt.call(domain + ".enable")
        dt.call("Emulation.setDeviceMetricsOverride", width=1280, height=800, deviceScaleFactor=1, mobile=False)
        dt.call("Page.navigate", url=f"http://127.0.0.1:{port}/")
        while dt.eval(DOM_PROBE)["conn"] != "live":
            time.sleep(0.1)
            left()
        print("tests/web: page live on its event stream")
        table = [m["name"] for m in json.loads(http(port, "/api/state")[1])["methods"]]
        while dt.eval(DOM_PROBE)["methods"] != table:  # the control form's methods are the solver table's
            time.sleep(0.1)
            left()
        print(f"tests/web: the control form offers the solver table's methods: {', '.join(table)}")
        if "gap-tv" not in table or "rayformer" not in table:
            fail(f"/api/state lists methods {table}, not the solver table")
        status, body = http(port, "/api/capture", json.dumps(
            {"count": 1, "reconstruct": True, "method": "gap-tv", "preset": "best"}).encode(), token)
        if status != 200:
            fail(f"POST /api/capture: {status} {body[:300]!r}")
        print(f"tests/web: capture requested through the web: {body.decode().strip()}")
        seen_running_points = 0
        samples = 0
        while True:
            left()
            p = dt.eval(DOM_PROBE)
            samples += 1
            if p["recon"] == "running":
                seen_running_points = max(seen_running_points, p["points"])
            if p["recon"] in ("failed", "canceled"):
                fail(f"the reconstruction {p['recon']}")
            if p["recon"] == "done" and p["frames"] and p["framesLoaded"] + p["framesFailed"] == p["frames"]:
                break
            time.sleep(0.1)
        print(f"tests/web: DOM: {p['captures']} listed; {p['pointsWhileRunning']} points plotted before recon.done "
              f"({seen_running_points} seen while it ran, {samples} samples); {p['framesLoaded']}/{p['frames']} "
              f"frame previews loaded; {p['jobs']} jobs, {p['devices']} devices shown; {p['curves']} methods in the "
              f"accuracy-against-time chart")
        if not p["captures"]:
            fail("the capture did not appear in the captures list")
        if p["pointsWhileRunning"] < 2:
            fail(f"the plot got {p['pointsWhileRunning']} points while the reconstruction ran (want >= 2)")
        if p["framesLoaded"] != p["frames"]:
            fail(f"{p['framesFailed']} of {p['frames']} frame previews did not load")
        if p["curves"] < 2:
            fail(f"the accuracy-against-time chart has {p['curves']} methods (want the measured ones)")
        while True:  # the animation, and the difference to the truth (the simulated bench knows it)
            q = dt.eval(DOM_PROBE)
            if q["anim"] and q["diff"] == p["frames"]:
                break
            time.sleep(0.1)
            left()
        print(f"tests/web: the animation loaded; {q['diff']} difference frames drawn against the truth")
        if p["devices"] < 3:
            fail(f"{p['devices']} devices shown (want dmd, camera, trigger)")
        desk = dt.screenshot(os.path.join(OUT, "desktop-1280x800.png"), 1280, 800, False)
        phone = dt.screenshot(os.path.join(OUT, "phone-390x844.png"), 390, 844, True)
        overflow = dt.eval(DOM_PROBE)["overflow"]
        print(f"tests/web: page {desk['width']:.0f}x{desk['height']:.0f} at desktop, "
              f"{phone['width']:.0f}x{phone['height']:.0f} at phone width; sideways overflow at 390: {overflow}px")
        if overflow > 0:
            fail(f"at 390 px wide the page overflows sideways by {overflow} px")
        dt.eval("0")  # drain the events the page reported meanwhile
        if dt.problems:
            fail("the page reported: " + "; ".join(dt.problems[:5]))
    finally:
        if chrome:
            chrome.terminate()
            try:
                chrome.wait(10)
            except subprocess.TimeoutExpired:
                chrome.kill()
        if daemon and daemon.poll() is None:
            daemon.send_signal(signal.SIGTERM)
            try:
                rc = daemon.wait(30)
            except subprocess.TimeoutExpired:
                daemon.kill()
                rc = "killed"
            if rc != 0:
                print(f"tests/web: scicapd ended with {rc}; log {tmp}/scicapd.log", file=sys.stderr)
                raise SystemExit(1)
    shutil.rmtree(tmp, ignore_errors=True)
    print(f"tests/web: PASS; screenshots in {OUT}")


if __name__ == "__main__":
    main()
