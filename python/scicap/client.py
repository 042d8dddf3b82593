"""A small client of scicapd over its control socket (docs/protocol.md): newline-delimited JSON requests and
replies on a Unix stream socket, events interleaved.

    c = scicap.Client()                     # $SCICAP_SOCKET, else /run/scicapd/control.sock
    print(c.status()["devices"])
    c.capture(count=2, reconstruct=True, method="gap-tv")
    for ev in c.wait():                     # the capture's events until it and its reconstructions ended
        print(ev["event"], ev.get("data"))
"""
import json
import os
import socket

DEFAULT_SOCKET = "/run/scicapd/control.sock"

#: Events that end a job.
MAIN_END_EVENTS = ("capture.done", "capture.failed", "capture.canceled", "calibrate.done", "calibrate.failed")
RECON_END_EVENTS = ("recon.done", "recon.failed", "recon.canceled", "recon.rejected")


def _keyword(arg):
    """The keyword argument of a request argument's path: "method", "params.iters" -> "params['iters']"."""
    head, *rest = arg.split(".")
    return head + "".join(f"[{k!r}]" for k in rest)


class DaemonError(RuntimeError):
    """The daemon answered ok: false: .code is the protocol's error code (busy, bad_arguments, not_found, ...),
    .message the daemon's message; for a refused argument also .arg (its keyword, e.g. "method") and .reason,
    which the exception's text uses instead of the request's JSON position."""

    def __init__(self, code, message, arg=None, reason=None):
        self.code = code
        self.message = message
        self.arg = _keyword(arg) if arg else None
        self.reason = reason
        super().__init__(f"{code}: {self.arg}: {reason}" if arg and reason else f"{code}: {message}")


class Client:
    """One connection to scicapd. Requests are answered in order; events that arrive meanwhile are kept for
    events()/wait(). Not thread-safe; close() or use as a context manager."""

    def __init__(self, socket_path=None, timeout=30.0):
        self.path = str(socket_path or os.environ.get("SCICAP_SOCKET") or DEFAULT_SOCKET)
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._sock.settimeout(timeout)
        self._sock.connect(self.path)
        self._buf = b""
        self._events = []
        self._next_id = 1
        self.last_id = None

    def close(self):
        self._sock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _read(self, timeout=None):
        """The next message (a dict); None at end of stream."""
        if timeout is not None:
            self._sock.settimeout(timeout)
        while b"\n" not in self._buf:
            chunk = self._sock.recv(65536)
            if not chunk:
                return None
            self._buf += chunk
        line, self._buf = self._buf.split(b"\n", 1)
        return json.loads(line)

    def request(self, cmd, **args):
        """Send one request; return its result, or raise DaemonError."""
        rid = self._next_id
        self._next_id += 1
        self.last_id = rid
        msg = {"v": 1, "id": rid, "cmd": cmd}
        args = {k: v for k, v in args.items() if v is not None}
        if args:
            msg["args"] = args
        self._sock.sendall(json.dumps(msg).encode() + b"\n")
        while True:
            m = self._read()
            if m is None:
                raise DaemonError("closed", f"{self.path}: the daemon closed the connection")
            if "event" in m:
                self._events.append(m)
            elif m.get("id") == rid or m.get("id") is None:
                if m.get("ok"):
                    return m.get("result", {})
                err = m.get("error") or {}
                raise DaemonError(err.get("code", "unknown"), err.get("message", ""), err.get("arg"),
                                  err.get("reason"))

    def status(self):
        return self.request("status")

    def devices(self):
        return self.request("devices")

    def jobs(self):
        return self.request("jobs")["jobs"]

    def captures(self, limit=None):
        """The stored captures (the newest `limit`, default all), oldest first, each with its reconstructions
        (docs/protocol.md, "captures")."""
        return self.request("captures", limit=limit)["captures"]

    def cancel(self, job):
        return self.request("cancel", job=job)

    def capture(self, **args):
        """capture: mask_set, count, pattern_us, dark_us, exposure_us, sync_mode, reconstruct, method, preset,
        params (docs/protocol.md). Returns {job, state}."""
        return self.request("capture", **args)

    def reconstruct(self, capture, method=None, preset=None, params=None, budget_s=None):
        return self.request("reconstruct", capture=capture, method=method, preset=preset, params=params,
                            budget_s=budget_s)

    def events(self, timeout=None):
        """Events as they come (those received while waiting for replies first); ends when the daemon closes."""
        while True:
            if self._events:
                yield self._events.pop(0)
                continue
            m = self._read(timeout)
            if m is None:
                return
            if "event" in m:
                yield m

    def watch(self, timeout=None):
        """Subscribe this connection to every event it may see (its uid's jobs and the devices; an admin's: all),
        now, and return the iterator over them (events())."""
        self.request("watch")
        return self.events(timeout)

    def wait(self, request_id=None, timeout=None):
        """The events of the jobs a request started (default: the last request), as a generator that ends when
        they have all ended: a capture or calibration and every reconstruction it queued, or a reconstruction
        (as scicap ... --wait)."""
        rid = self.last_id if request_id is None else request_id
        main_open, recon_open = None, 0
        for ev in self.events(timeout):
            if ev.get("id") != rid:
                continue
            yield ev
            name = ev["event"]
            if main_open is None:  # the first event says what the request started
                main_open = not name.startswith("recon.")
                recon_open = 0 if main_open or name == "recon.queued" else 1
            if name == "recon.queued":
                recon_open += 1
            elif name in MAIN_END_EVENTS:
                main_open = False
            elif name in RECON_END_EVENTS:
                recon_open -= name != "recon.rejected"
            if not main_open and recon_open <= 0:
                return
