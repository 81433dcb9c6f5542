"""A tiny socketcand-speaking CAN hub on 127.0.0.1: one virtual CAN bus shared by every
TCP client, for running FieldRx's ``--can socketcand:HOST:PORT:CHANNEL`` (python-can's
``socketcand`` interface) without a kernel CAN device. socketcand itself is not packaged
for Debian or PyPI.

Protocol subset (socketcand's ``doc/protocol.md``, raw mode, as python-can's client
speaks it): the hub greets ``< hi >``; ``< open CHANNEL >`` and ``< rawmode >`` are
answered ``< ok >``; ``< send ID DLC B0 B1 .. >`` (hex) puts a frame on the bus, which the
hub sends to every other client in raw mode as ``< frame ID SECONDS.MICROS DATAHEX >``
(like a CAN controller, a sender does not receive its own frame). Every socket has
TCP_NODELAY so the hub adds no Nagle delay of its own.

Run: ``python -m tests.edge.socketcand_hub [--port N]``; prints ``PORT <n>`` when ready.
"""

from __future__ import annotations

import argparse
import selectors
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class _Conn:
    sock: socket.socket
    buf: str = ""
    raw: bool = False
    out: bytearray = field(default_factory=bytearray)


def _frame(msg: str) -> str | None:
    """``< send ID DLC B.. >`` -> ``< frame ID TS HEX >`` (None if malformed)."""
    parts = msg[1:-1].split()
    if len(parts) < 3 or parts[0] != "send":
        return None
    try:
        can_id, dlc = parts[1], int(parts[2], 16)
        data = bytes(int(b, 16) for b in parts[3 : 3 + dlc])
    except ValueError:
        return None
    if len(data) != dlc or dlc > 8:
        return None
    return f"< frame {can_id} {time.time():.6f} {data.hex().upper()} >"


class Hub:
    def __init__(self, port: int = 0) -> None:
        self.sel = selectors.DefaultSelector()
        self.lsock = socket.create_server(("127.0.0.1", port))
        self.lsock.setblocking(False)
        self.port = self.lsock.getsockname()[1]
        self.sel.register(self.lsock, selectors.EVENT_READ)
        self.conns: dict[socket.socket, _Conn] = {}
        self.frames = 0

    def _accept(self) -> None:
        s, _ = self.lsock.accept()
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        s.setblocking(True)
        s.sendall(b"< hi >")
        self.conns[s] = _Conn(s)
        self.sel.register(s, selectors.EVENT_READ)

    def _drop(self, c: _Conn) -> None:
        self.sel.unregister(c.sock)
        self.conns.pop(c.sock, None)
        c.sock.close()

    def _handle(self, c: _Conn, msg: str) -> None:
        if msg.startswith("< open ") or msg == "< rawmode >":
            c.sock.sendall(b"< ok >")
            c.raw = c.raw or msg == "< rawmode >"
            return
        fr = _frame(msg)
        if fr is None:
            c.sock.sendall(b"< error malformed >")
            return
        self.frames += 1
        data = fr.encode("ascii")
        for other in list(self.conns.values()):
            if other is not c and other.raw:
                try:
                    other.sock.sendall(data)
                except OSError:
                    self._drop(other)

    def _read(self, c: _Conn) -> None:
        try:
            chunk = c.sock.recv(65536)
        except OSError:
            chunk = b""
        if not chunk:
            self._drop(c)
            return
        c.buf += chunk.decode("ascii", "replace")
        while True:
            start, end = c.buf.find("<"), c.buf.find(">")
            if start < 0 or end < 0:
                if start < 0:
                    c.buf = ""
                return
            if end < start:
                c.buf = c.buf[start:]
                continue
            msg, c.buf = c.buf[start : end + 1], c.buf[end + 1 :]
            self._handle(c, " ".join(msg.split()))

    def serve(self, stop_after_s: float | None = None) -> None:
        t_end = None if stop_after_s is None else time.monotonic() + stop_after_s
        while t_end is None or time.monotonic() < t_end:
            for key, _ in self.sel.select(timeout=0.5):
                if key.fileobj is self.lsock:
                    self._accept()
                else:
                    c = self.conns.get(key.fileobj)  # type: ignore[call-overload]
                    if c is not None:
                        self._read(c)


def start_hub_process(timeout_s: float = 30.0) -> tuple[subprocess.Popen[str], int]:
    """The hub in its own process; returns it and its port once it listens."""
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.Popen(
        [sys.executable, "-m", "tests.edge.socketcand_hub"],
        cwd=root,
        stdout=subprocess.PIPE,
        text=True,
    )
    sel = selectors.DefaultSelector()
    assert proc.stdout is not None
    sel.register(proc.stdout, selectors.EVENT_READ)
    if not sel.select(timeout_s):
        proc.kill()
        raise RuntimeError(f"socketcand hub did not start within {timeout_s} s")
    line = proc.stdout.readline().split()
    if len(line) != 2 or line[0] != "PORT":
        proc.kill()
        raise RuntimeError(f"socketcand hub said {line!r}")
    return proc, int(line[1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--port", type=int, default=0)
    a = ap.parse_args()
    hub = Hub(a.port)
    print(f"PORT {hub.port}", flush=True)
    try:
        hub.serve()
    except KeyboardInterrupt:
        sys.exit(0)


if __name__ == "__main__":
    main()
