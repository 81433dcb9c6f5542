"""Store-and-forward telemetry queue: SQLite in WAL mode, never loses a record.

Every record is numbered (seq) and committed to disk before anything tries to
send it; the sender trims the queue only up to the sequence number the server
acknowledged (highest contiguous seq stored). ``seq`` is assigned in the same
transaction as the insert, so a kill -9 can neither lose nor reuse a number.
One connection per thread: the runtime writes while the sender reads.

Streams (telemetry format 2, ``fieldrx_edge.protocol``): a queue creates a
random stream id with itself and every batch names it, so the server
deduplicates by (machine, stream, seq). A queue that is lost (new tablet,
wiped state dir, ``simulate`` without ``--state-dir``) starts a new stream at
seq 1 instead of colliding with numbers the server already holds. A queue
database written before streams existed is migrated when opened: it gets a
stream that starts after its acknowledged seq, so its pending records are sent
and nothing already stored is sent again. If the server reports that this
stream's numbers are already taken by other records (restored or cloned state),
``new_stream`` moves everything not yet acknowledged to a fresh stream.

Nothing the protocol forbids is queued: ``put_many`` runs
``protocol.sanitize_record`` on each record and counts what it changed or
dropped (``stats()["sanitized"]``, ``["dropped"]``, ``reasons()``).
"""

from __future__ import annotations

import json
import logging
import sqlite3
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fieldrx_edge.cell_records import cell_batch_json, sanitize_cell_record
from fieldrx_edge.protocol import new_stream_id, sanitize_record, telemetry_batch_json

log = logging.getLogger(__name__)

_SCHEMA = """
CREATE TABLE IF NOT EXISTS records (seq INTEGER PRIMARY KEY, body TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);
INSERT OR IGNORE INTO meta VALUES ('last_seq', 0), ('acked_seq', 0), ('rejected', 0);
INSERT OR IGNORE INTO meta VALUES ('sanitized', 0), ('dropped', 0), ('stream_start', 1);
CREATE TABLE IF NOT EXISTS info (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS reasons (
    kind TEXT NOT NULL, reason TEXT NOT NULL, n INTEGER NOT NULL, PRIMARY KEY (kind, reason)
);
"""
_MAX_REASON = 200  # characters of a reason kept (server texts can be long)


# what a queue holds: its record rules and its batch format
_KINDS: dict[str, tuple[Callable[[dict[str, Any]], list[str]], Callable[..., bytes]]] = {
    "telemetry": (sanitize_record, telemetry_batch_json),
    "cells": (sanitize_cell_record, cell_batch_json),  # uplink profile thin (CellRecord)
}


class TelemetryQueue:
    """Durable FIFO of telemetry records for one machine, on one stream at a time.

    ``kind`` "cells" holds the thin profile's cell records (``cell_records.CellRecord``,
    sent as cell batches) under the same numbering, acknowledgement and stream rules."""

    def __init__(
        self,
        path: str | Path,
        machine_id: int,
        synchronous: str = "NORMAL",
        kind: str = "telemetry",
    ) -> None:
        self.path = str(path)
        self.machine_id = machine_id
        self.kind = kind
        self._sanitize, self._batch_json = _KINDS[kind]
        self._sync = synchronous  # NORMAL survives process kills; FULL also power loss
        self._local = threading.local()
        Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        con = self._con()
        con.executescript(_SCHEMA)  # idempotent
        con.execute("BEGIN IMMEDIATE")
        try:
            stored = con.execute("SELECT value FROM meta WHERE key='machine_id'").fetchone()
            if stored is None:
                con.execute("INSERT INTO meta VALUES ('machine_id', ?)", (machine_id,))
            elif stored[0] != machine_id:
                raise ValueError(
                    f"queue {self.path} belongs to machine {stored[0]}, not {machine_id}"
                )
            if con.execute("SELECT 1 FROM info WHERE key='stream'").fetchone() is None:
                # a new queue, or one written before streams: start a stream after what the
                # server already acknowledged (its pending records go on the new stream)
                start = self._meta(con, "acked_seq") + 1
                con.execute("INSERT INTO info VALUES ('stream', ?)", (new_stream_id(),))
                con.execute("UPDATE meta SET value=? WHERE key='stream_start'", (start,))
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            raise

    def _con(self) -> sqlite3.Connection:
        con = getattr(self._local, "con", None)
        if con is None:
            con = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
            con.execute("PRAGMA journal_mode=WAL")
            con.execute(f"PRAGMA synchronous={self._sync}")
            con.execute("PRAGMA busy_timeout=30000")
            self._local.con = con
        return con

    def close(self) -> None:
        con = getattr(self._local, "con", None)
        if con is not None:
            con.close()
            self._local.con = None

    def _meta(self, con: sqlite3.Connection, key: str) -> int:
        return int(con.execute("SELECT value FROM meta WHERE key=?", (key,)).fetchone()[0])

    @staticmethod
    def _count(con: sqlite3.Connection, kind: str, reason: str, n: int = 1) -> None:
        con.execute(
            "INSERT INTO reasons VALUES (?, ?, ?)"
            " ON CONFLICT (kind, reason) DO UPDATE SET n = n + excluded.n",
            (kind, reason[:_MAX_REASON], n),
        )

    def put(self, record: dict[str, Any]) -> int:
        """Number the record (seq = last + 1), store it durably, return seq (0: dropped)."""
        seqs = self.put_many([record])
        return seqs[-1] if seqs else 0

    def put_many(
        self, records: list[dict[str, Any]], info: dict[str, str] | None = None
    ) -> list[int]:
        """Store several records in one transaction (the bench and NDVI bursts).

        Each record is first made to follow the protocol (``sanitize_record``):
        what was nulled or clamped is counted as ``sanitized``, a record that
        cannot be repaired is not queued and counted as ``dropped``, both with
        their reasons. ``info``: key/values stored in the same transaction (the
        thin uplink's count of cell records emitted per job, so a restarted agent
        neither loses nor repeats one). Returns the seqs of the records queued."""
        con = self._con()
        con.execute("BEGIN IMMEDIATE")
        try:
            last = self._meta(con, "last_seq")
            seqs = []
            rows = []
            fixed = dropped = 0
            for key, value in (info or {}).items():
                con.execute("INSERT OR REPLACE INTO info VALUES (?, ?)", (key, value))
            for rec in records:
                rec["machine_id"] = self.machine_id
                rec["seq"] = last + 1
                reasons = self._sanitize(rec)
                if reasons:
                    kind = "dropped" if reasons[0].startswith("drop:") else "sanitized"
                    for r in reasons:
                        self._count(con, kind, r.split(":", 1)[0] if kind == "sanitized" else r)
                    log.warning("telemetry record %s: %s", kind, "; ".join(reasons))
                    if kind == "dropped":
                        dropped += 1
                        continue
                    fixed += 1
                last += 1
                seqs.append(last)
                rows.append((last, json.dumps(rec, separators=(",", ":"), allow_nan=False)))
            con.executemany("INSERT INTO records VALUES (?, ?)", rows)
            con.execute("UPDATE meta SET value=? WHERE key='last_seq'", (last,))
            if fixed:
                con.execute("UPDATE meta SET value=value+? WHERE key='sanitized'", (fixed,))
            if dropped:
                con.execute("UPDATE meta SET value=value+? WHERE key='dropped'", (dropped,))
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            raise
        return seqs

    def _pending_rows(self, limit: int, after: int | None) -> list[tuple[int, str]]:
        con = self._con()
        start = self._meta(con, "acked_seq") if after is None else after
        return con.execute(
            "SELECT seq, body FROM records WHERE seq > ? ORDER BY seq LIMIT ?", (start, limit)
        ).fetchall()

    def pending(self, limit: int = 500, after: int | None = None) -> list[dict[str, Any]]:
        """Oldest unacknowledged records (seq > ``after``, default the acked seq)."""
        return [json.loads(r[1]) for r in self._pending_rows(limit, after)]

    def pending_batch(self, limit: int = 500, after: int | None = None) -> tuple[bytes, int, int]:
        """The next batch as wire bytes (format 2: stream, stream_start, records), its number
        of records and its last seq; (b"", 0, after) when nothing is pending.

        The stored JSON texts go out as they are: a record queued by an older agent
        with a NaN in it reaches the server, which rejects it alone and acknowledges
        past it, instead of blocking this queue."""
        rows = self._pending_rows(limit, after)
        if not rows:
            return b"", 0, after if after is not None else self.acked_seq
        stream, start = self.stream
        return self._batch_json(stream, start, [r[1] for r in rows]), len(rows), rows[-1][0]

    def info(self, key: str) -> str | None:
        """A value stored with ``put_many(..., info=...)``."""
        row = self._con().execute("SELECT value FROM info WHERE key=?", (key,)).fetchone()
        return None if row is None else str(row[0])

    @property
    def stream(self) -> tuple[str, int]:
        """(current stream id, its first seq)."""
        con = self._con()
        sid = con.execute("SELECT value FROM info WHERE key='stream'").fetchone()[0]
        return str(sid), self._meta(con, "stream_start")

    def new_stream(self) -> str:
        """Continue on a fresh stream from the first unacknowledged seq (the server said this
        stream's numbers are taken by other records). Returns the new stream id."""
        con = self._con()
        con.execute("BEGIN IMMEDIATE")
        try:
            sid = new_stream_id()
            con.execute("UPDATE info SET value=? WHERE key='stream'", (sid,))
            con.execute(
                "UPDATE meta SET value=? WHERE key='stream_start'",
                (self._meta(con, "acked_seq") + 1,),
            )
            self._count(con, "stream", "stream conflict: switched to a new stream")
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            raise
        log.error(
            "telemetry: the server holds other records under this stream's seqs;"
            " continuing on new stream %s",
            sid,
        )
        return sid

    def ack(
        self,
        acked_seq: int,
        rejected: int | list[dict[str, Any]] = 0,
        stream: str | None = None,
    ) -> int:
        """Trim up to the server's ``acked_seq`` (never beyond what was stored). Returns trimmed.

        ``rejected``: a count, or the server's rejects (``{"seq", "reason"}``), whose
        reasons are counted and logged. An ack for another ``stream`` than the
        current one (a late ack of a stream this queue left, or another agent's on a
        shared MQTT ack topic) trims nothing."""
        if stream is not None and stream != self.stream[0]:
            return 0
        reasons: list[str] = []
        if isinstance(rejected, list):
            reasons = [str(r.get("reason", "")) for r in rejected if isinstance(r, dict)]
            n_rejected = len(rejected)
        else:
            n_rejected = int(rejected)
        con = self._con()
        con.execute("BEGIN IMMEDIATE")
        try:
            last = self._meta(con, "last_seq")
            acked = min(int(acked_seq), last)
            old = self._meta(con, "acked_seq")
            n = 0
            if acked > old:
                n = con.execute("DELETE FROM records WHERE seq <= ?", (acked,)).rowcount
                con.execute("UPDATE meta SET value=? WHERE key='acked_seq'", (acked,))
            if n_rejected:
                con.execute("UPDATE meta SET value=value+? WHERE key='rejected'", (n_rejected,))
            for r in reasons:
                self._count(con, "rejected", r)
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            raise
        return n

    @property
    def last_seq(self) -> int:
        return self._meta(self._con(), "last_seq")

    @property
    def acked_seq(self) -> int:
        return self._meta(self._con(), "acked_seq")

    def backlog(self) -> int:
        return self.last_seq - self.acked_seq

    def reasons(self) -> dict[str, dict[str, int]]:
        """kind (sanitized | dropped | rejected | stream) -> reason -> count."""
        out: dict[str, dict[str, int]] = {}
        for kind, reason, n in self._con().execute("SELECT kind, reason, n FROM reasons"):
            out.setdefault(kind, {})[reason] = n
        return out

    def stats(self) -> dict[str, Any]:
        con = self._con()
        last, acked = self._meta(con, "last_seq"), self._meta(con, "acked_seq")
        return {
            "last_seq": last,
            "acked_seq": acked,
            "rejected": self._meta(con, "rejected"),
            "sanitized": self._meta(con, "sanitized"),
            "dropped": self._meta(con, "dropped"),
            "backlog": last - acked,
            "stream": self.stream[0],
            "reasons": self.reasons(),  # what `run` / `simulate` print: why records changed
        }
