"""The cab display's HTTP server, inside the agent: the standard library's threading HTTP
server, the page's assets from this package (no CDN, no internet), the session's live
state pushed as Server-Sent Events, and the operator's buttons as POSTs to the same
session (there is no second loop).

Bound to 127.0.0.1 by default. Bound to any other address (the tractor's Wi-Fi), every
request must carry the pairing token (``?token=`` once, then the cookie the page gets, or
the ``X-Cab-Token`` header); without it the answer is 401 and nothing else.
"""

from __future__ import annotations

import hmac
import ipaddress
import json
import logging
import secrets
import sys
import threading
import time
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlparse

from fieldrx_edge.cab.control import Control, ControlError
from fieldrx_edge.cab.live import CabLimits, LiveState
from fieldrx_edge.cab.operator import OperatedMotor, Operator

log = logging.getLogger(__name__)

STATIC = Path(__file__).parent / "static"
TYPES = {".html": "text/html", ".js": "text/javascript", ".css": "text/css", ".wav": "audio/wav"}
PUSH_HZ = 10.0  # the screen gets a state at least this often, and at once on a new record
MIN_GAP_S = 0.04  # ... but not more than 25 times a second


@dataclass
class CabOptions:
    host: str = "127.0.0.1"
    port: int = 0
    token: str | None = None
    backlog_alarm: int = 3000
    linger_s: float = 0.0  # after the job ends, serve the summary this long (or until Close)
    wait_start: bool = False  # the loop waits for the screen's Start


def parse_bind(spec: str) -> tuple[str, int]:
    """``PORT`` or ``HOST:PORT`` -> (host, port); a clear error otherwise."""
    host, _, port = spec.rpartition(":")
    try:
        n = int(port)
    except ValueError:
        raise SystemExit(f"--cab {spec!r}: expected PORT or HOST:PORT") from None
    if not 0 <= n <= 65535:
        raise SystemExit(f"--cab {spec!r}: port {n} outside 0..65535")
    return host or "127.0.0.1", n


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class CabServer:
    def __init__(self, live: LiveState, control: Control, opts: CabOptions) -> None:
        self.live = live
        self.control = control
        self.opts = opts
        self.token = opts.token
        if not is_loopback(opts.host) and not self.token:
            self.token = secrets.token_urlsafe(9)  # never open beyond localhost without one
        self.geometry = json.dumps(live.geo.to_json()).encode()
        self.httpd = ThreadingHTTPServer((opts.host, opts.port), _handler(self))
        self.httpd.daemon_threads = True
        self.port = self.httpd.server_address[1]
        self.closing = threading.Event()
        self._thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    @property
    def url(self) -> str:
        q = f"?token={self.token}" if self.token else ""
        return f"http://{self.opts.host}:{self.port}/{q}"

    def start(self) -> None:
        self._thread.start()
        # the operator (or a test) reads where the screen is from stderr
        print(json.dumps({"cab": self.url, "port": self.port}), file=sys.stderr, flush=True)

    def close(self) -> None:
        self.closing.set()
        with self.live.lock:
            self.live.changed.notify_all()
        self.httpd.shutdown()
        self.httpd.server_close()

    def authorised(self, h: BaseHTTPRequestHandler, query: dict[str, list[str]]) -> bool:
        if not self.token:
            return True
        given = (query.get("token") or [""])[0] or h.headers.get("X-Cab-Token")
        if not given:
            for part in (h.headers.get("Cookie") or "").split(";"):
                k, _, v = part.strip().partition("=")
                if k == "cab_token":
                    given = v
        return bool(given) and hmac.compare_digest(str(given), self.token)

    def events(self, h: BaseHTTPRequestHandler) -> None:
        """Server-Sent Events: the live state at once on each record (at most every 40 ms)
        and at least ``PUSH_HZ`` times a second."""
        h.send_response(200)
        h.send_header("Content-Type", "text/event-stream")
        h.send_header("Cache-Control", "no-store")
        h.end_headers()
        live = self.live
        since = 0
        last_n = -1
        while True:
            closing = self.closing.is_set()  # the last state (finished) still goes out
            with live.lock:
                if live.n == last_n and not closing:
                    live.changed.wait(1.0 / PUSH_HZ)
            snap = live.snapshot(since)
            since += len(snap["new_cells"])
            last_n = snap["n"]
            try:
                h.wfile.write(b"data: " + json.dumps(snap).encode() + b"\n\n")
                h.wfile.flush()
            except OSError:
                return  # the screen went away
            if closing:
                return
            time.sleep(MIN_GAP_S)


class CabHandler(BaseHTTPRequestHandler):
    """One request of the screen; ``cab`` is set on the subclass each server makes."""

    protocol_version = "HTTP/1.1"
    cab: CabServer

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
        log.debug("cab: " + format, *args)

    def _send(self, code: int, body: bytes, ctype: str = "application/json") -> None:
        self.send_response(code)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        if self.cab.token:
            self.send_header("Set-Cookie", f"cab_token={self.cab.token}; HttpOnly; SameSite=Strict")
        self.end_headers()
        self.wfile.write(body)

    def _json(self, code: int, obj: Any) -> None:
        self._send(code, json.dumps(obj).encode())

    def _gate(self) -> tuple[str, dict[str, list[str]]] | None:
        u = urlparse(self.path)
        q = parse_qs(u.query)
        if not self.cab.authorised(self, q):
            self.send_response(401)
            body = b"pairing token required: open the address the agent printed (.../?token=...)\n"
            self.send_header("Content-Type", "text/plain")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)
            return None
        return u.path, q

    def do_GET(self) -> None:  # noqa: N802 (the standard library's name)
        g = self._gate()
        if g is None:
            return
        path, q = g
        if path == "/events":
            self.cab.events(self)
            return
        if path == "/api/job":
            self._send(200, self.cab.geometry)
        elif path == "/api/state":
            since = (q.get("since") or ["0"])[0]
            if not since.isdigit():
                self._json(400, {"error": f"since must be a cell count >= 0, got {since!r}"})
                return
            self._json(200, self.cab.live.snapshot(int(since)))
        elif path == "/api/jobs":
            self._json(200, self.cab.control.jobs())
        elif path == "/favicon.ico":
            self._send(204, b"", "image/x-icon")
        else:
            self._static(path)

    def _static(self, path: str) -> None:
        name = "index.html" if path in ("/", "/index.html") else path.removeprefix("/static/")
        f = (STATIC / name).resolve()
        if f.parent != STATIC.resolve() or not f.is_file():
            self._json(404, {"error": f"no such page {path!r}"})
            return
        self._send(200, f.read_bytes(), TYPES.get(f.suffix, "application/octet-stream"))

    def do_POST(self) -> None:  # noqa: N802
        g = self._gate()
        if g is None:
            return
        path, _ = g
        n = int(self.headers.get("Content-Length") or 0)
        try:
            body = json.loads(self.rfile.read(n) or b"{}") if n <= 65536 else None
            if not isinstance(body, dict) or path != "/api/control":
                raise ControlError(f"POST {path}: expected /api/control with a JSON object")
            self._json(200, self.cab.control.act(body))
        except (ControlError, ValueError) as e:
            self._json(400, {"error": str(e)})


def _handler(cab: CabServer) -> type[BaseHTTPRequestHandler]:
    return type("Handler", (CabHandler,), {"cab": cab})


def attach_cab(a: Any, session: Any, store: Any) -> CabServer | None:
    """With ``--cab``: the display watches ``session`` (an observer of its records), its
    operator stands between the runtime and the meter, and its server starts."""
    spec = getattr(a, "cab", None)
    if not spec or session.job is None:
        return None
    host, port = parse_bind(spec)
    opts = CabOptions(
        host=host,
        port=port,
        token=getattr(a, "cab_token", None),
        backlog_alarm=int(getattr(a, "cab_backlog_alarm", 3000)),
        linger_s=float(getattr(a, "cab_linger", 0.0)),
        wait_start=bool(getattr(a, "cab_wait_start", False)),
    )
    job = session.job
    from fieldrx_edge.metering import calibration_from_dict

    cal = calibration_from_dict(job.calibration)
    operator = Operator(cal.min_rpm, cal.max_rpm, int(getattr(a, "sections", 1) or 1))
    live = LiveState(
        job, operator, CabLimits(backlog_alarm=opts.backlog_alarm),
        backlog=session.backlog, uplink=session.uplink_state,
    )  # fmt: skip
    session.observers.append(live.observe)
    control = Control(live, operator, session, store, opts)
    cab = CabServer(live, control, opts)
    session.cab = control
    session.operator = operator
    cab.start()
    control.server = cab
    if opts.wait_start:
        control.wait_for_start()
    return cab


__all__ = ["CabOptions", "CabServer", "OperatedMotor", "attach_cab", "parse_bind"]
