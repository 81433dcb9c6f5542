"""Store-and-forward telemetry queue: SQLite in WAL mode, never loses a record.

Every record is numbered (machine, seq) and committed to disk before anything
tries to send it; the sender trims the queue only up to the sequence number
the server acknowledged (highest contiguous seq stored). ``seq`` is assigned in
the same transaction as the insert, so a kill -9 can neither lose nor reuse a
number. One connection per thread: the runtime writes while the sender reads.
"""

from __future__ import annotations

import json
import sqlite3
import threading
from pathlib import Path
from typing import Any

_SCHEMA = """
CREATE TABLE IF NOT EXISTS records (seq INTEGER PRIMARY KEY, body TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);
INSERT OR IGNORE INTO meta VALUES ('last_seq', 0), ('acked_seq', 0), ('rejected', 0);
"""


class TelemetryQueue:
    """Durable FIFO of telemetry records for one machine."""

    def __init__(self, path: str | Path, machine_id: int, synchronous: str = "NORMAL") -> None:
        self.path = str(path)
        self.machine_id = machine_id
        self._sync = synchronous  # NORMAL survives process kills; FULL also power loss
        self._local = threading.local()
        Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        con = self._con()
        with con:
            con.executescript(_SCHEMA)
        stored = con.execute("SELECT value FROM meta WHERE key='machine_id'").fetchone()
        if stored is None:
            with con:
                con.execute("INSERT INTO meta VALUES ('machine_id', ?)", (machine_id,))
        elif stored[0] != machine_id:
            raise ValueError(f"queue {self.path} belongs to machine {stored[0]}, not {machine_id}")

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

    def put(self, record: dict[str, Any]) -> int:
        """Number the record (seq = last + 1), store it durably, return seq."""
        return self.put_many([record])[-1]

    def put_many(self, records: list[dict[str, Any]]) -> list[int]:
        """Store several records in one transaction (the bench and NDVI bursts)."""
        con = self._con()
        con.execute("BEGIN IMMEDIATE")
        try:
            last = self._meta(con, "last_seq")
            seqs = []
            rows = []
            for rec in records:
                last += 1
                rec["seq"] = last
                rec["machine_id"] = self.machine_id
                seqs.append(last)
                rows.append((last, json.dumps(rec, separators=(",", ":"))))
            con.executemany("INSERT INTO records VALUES (?, ?)", rows)
            con.execute("UPDATE meta SET value=? WHERE key='last_seq'", (last,))
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            raise
        return seqs

    def pending(self, limit: int = 500, after: int | None = None) -> list[dict[str, Any]]:
        """Oldest unacknowledged records (seq > ``after``, default the acked seq)."""
        con = self._con()
        start = self._meta(con, "acked_seq") if after is None else after
        rows = con.execute(
            "SELECT body FROM records WHERE seq > ? ORDER BY seq LIMIT ?", (start, limit)
        ).fetchall()
        return [json.loads(r[0]) for r in rows]

    def ack(self, acked_seq: int, rejected: int = 0) -> int:
        """Trim up to the server's ``acked_seq`` (never beyond what was stored). Returns trimmed."""
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
            if rejected:
                con.execute("UPDATE meta SET value=value+? WHERE key='rejected'", (rejected,))
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

    def stats(self) -> dict[str, int]:
        con = self._con()
        return {
            "last_seq": self._meta(con, "last_seq"),
            "acked_seq": self._meta(con, "acked_seq"),
            "rejected": self._meta(con, "rejected"),
            "backlog": self._meta(con, "last_seq") - self._meta(con, "acked_seq"),
        }
