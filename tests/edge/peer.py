"""A tiny real HTTP peer with the server's telemetry and device-job semantics.

Used until the full FieldRx server test exists: dedupe by (machine, seq),
acknowledge the highest contiguous seq, ETag on packages, bearer device token.
"""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any


class _PeerServer(ThreadingHTTPServer):
    peer: Peer


class _Handler(BaseHTTPRequestHandler):
    """The peer's HTTP side: device jobs and packages (GET), telemetry and job states (POST)."""

    @property
    def peer(self) -> Peer:
        assert isinstance(self.server, _PeerServer)
        return self.server.peer

    def log_message(self, *a: Any) -> None:
        pass

    def _json(self, code: int, obj: Any, headers: dict[str, str] | None = None) -> None:
        body = json.dumps(obj).encode()
        self.send_response(code)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        self.end_headers()
        self.wfile.write(body)

    def _auth(self) -> bool:
        if self.headers.get("Authorization") != f"Bearer {self.peer.token}":
            self._json(401, {"detail": "bad token"})
            return False
        return True

    def do_GET(self) -> None:
        if not self._auth():
            return
        parts = self.path.strip("/").split("/")
        if self.path == "/api/v1/device/jobs":
            self._json(200, [{"id": k} for k in sorted(self.peer.packages)])
            return
        if len(parts) == 6 and parts[5] == "package":
            self._package(int(parts[4]))
            return
        self._json(404, {"detail": "not found"})

    def _package(self, jid: int) -> None:
        data = self.peer.packages.get(jid)
        if data is None:
            self._json(404, {"detail": "no such job"})
            return
        etag = f'"{jid}-{len(data)}-{hash(data) & 0xFFFF:x}"'
        if self.headers.get("If-None-Match") == etag:
            self.send_response(304)
            self.send_header("ETag", etag)
            self.end_headers()
            return
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("ETag", etag)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def do_POST(self) -> None:
        if not self._auth():
            return
        peer = self.peer
        n = int(self.headers.get("Content-Length", 0))
        body = json.loads(self.rfile.read(n) or b"{}")
        parts = self.path.strip("/").split("/")
        if self.path == "/api/v1/telemetry":
            with peer.lock:
                if peer.fail_next > 0:
                    peer.fail_next -= 1
                    self._json(503, {"detail": "try later"})
                    return
                self._json(200, peer.ingest(body["records"]))
            return
        if len(parts) == 6 and parts[5] == "state":
            peer.states.append((int(parts[4]), body["state"]))
            self._json(200, {"ok": True})
            return
        self._json(404, {"detail": "not found"})


class Peer:
    def __init__(self, token: str = "dev-token", port: int = 0) -> None:
        self.token = token
        self.records: dict[tuple[int, int], dict[str, Any]] = {}
        self.deliveries = 0
        self.duplicates = 0
        self.conflicts = 0  # same seq, different content: must never happen
        self.packages: dict[int, bytes] = {}
        self.states: list[tuple[int, str]] = []
        self.fail_next = 0  # answer 503 to this many telemetry posts
        self.lock = threading.Lock()
        self.httpd = _PeerServer(("127.0.0.1", port), _Handler)
        self.httpd.peer = self
        self.port = self.httpd.server_address[1]
        self.url = f"http://127.0.0.1:{self.port}"
        self._th = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    def ingest(self, records: list[dict[str, Any]]) -> dict[str, Any]:
        stored = dup = 0
        machine = records[0]["machine_id"] if records else 0
        for r in records:
            key = (r["machine_id"], r["seq"])
            self.deliveries += 1
            if key in self.records:
                dup += 1
                self.duplicates += 1
                if self.records[key] != r:
                    self.conflicts += 1
            else:
                self.records[key] = r
                stored += 1
        return {
            "machine_id": machine,
            "acked_seq": self.acked(machine),
            "stored": stored,
            "duplicates": dup,
            "rejected": [],
        }

    def acked(self, machine: int) -> int:
        s = 0
        while (machine, s + 1) in self.records:
            s += 1
        return s

    def start(self) -> Peer:
        self._th.start()
        return self

    def stop(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
