"""Ingest stage 3, deduplicate: which of a batch's valid rows are new on their stream.

Records are keyed by (machine, stream, seq). A seq already stored on the stream is a
duplicate only if it is the same record (same fix time); if it holds another record the
stream's numbering went backwards (restored or cloned queue): nothing from that seq on is
stored or acknowledged, and the ack says ``stream_conflict`` so the agent moves to a new
stream. Runs under the machine's lock, so what it reads stays true until the COPY.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import psycopg

from fieldrx.fleet.ingest.model import IngestResult, MachineInfo, t_us, ts
from fieldrx.fleet.telemetry_row import TelemetryRow


@dataclass
class Deduped:
    """What is left of a batch once its stored seqs are known."""

    new: list[TelemetryRow]  # to COPY, in seq order
    rows: dict[int, TelemetryRow]  # the valid rows below a conflict (all of them without one)
    dead: set[int]  # rejected for good, below a conflict
    conflict: int | None = None  # the first seq that holds another record


def deduplicate(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    stream: str,
    info: MachineInfo,
    rows: dict[int, TelemetryRow],
    dead: set[int],
    result: IngestResult,
) -> Deduped:
    """Sort out duplicates and a stream conflict; counts and rejects go into ``result``."""
    out = Deduped([], rows, dead)
    if rows:
        existing = stored(cur, machine_id, stream, info, rows)
        if existing:
            same = [q for q, us in existing.items() if q in rows and rows[q].t == us]
            result.duplicates += len(same)
            clash = [q for q in existing if q in rows and rows[q].t != existing[q]]
            if clash:
                conflict = out.conflict = min(clash)
                result.stream_conflict = True
                for q in sorted(rows):
                    if (q >= conflict and q not in existing) or q in clash:
                        result.rejected.append(
                            {"seq": q, "reason": conflict_reason(q, stream, q in clash)}
                        )
                out.rows = {q: r for q, r in rows.items() if q < conflict}
                out.dead = {q for q in dead if q < conflict}
        out.new = [out.rows[s] for s in sorted(out.rows) if s not in existing]
    result.stored = len(out.new)
    return out


def stored(
    cur: psycopg.Cursor[Any],
    machine_id: int,
    stream: str,
    info: MachineInfo,
    rows: Mapping[int, tuple[Any, ...]],
) -> dict[int, int]:
    """Stored records of the stream holding a seq of this batch: seq -> t (int8 us).

    Only seqs up to the stream's highest stored seq can be stored; a batch above it (new
    records in order, the common case) needs no lookup. A resend holds the same records,
    so its stored copies lie within the batch's own time range: looked up there first
    (one or two days). What is still unmatched (records stored out of order, or another
    record under the same seq: a restored queue) is looked up over the stream's first to
    last record time, which holds every stored record of the stream.
    """
    if info.acked_seq is None or info.max_seq is None:  # a new stream holds nothing yet
        return {}
    cand = [q for q in rows if q <= info.max_seq]
    if not cand:
        return {}
    sql = (
        "SELECT seq, t FROM telemetry WHERE machine_id = %s AND stream = %s"
        " AND seq BETWEEN %s AND %s AND t BETWEEN %s AND %s"
    )
    times = [rows[q][2] for q in cand]
    cur.execute(sql, (machine_id, stream, min(cand), max(cand), ts(min(times)), ts(max(times))))
    found = {seq: t_us(t) for seq, t in cur.fetchall()}
    rest = [q for q in cand if q not in found]
    if rest and info.first_us is not None and info.last_us is not None:
        cur.execute(
            sql,
            (machine_id, stream, min(rest), max(rest), ts(info.first_us), ts(info.last_us)),
        )
        found.update((seq, t_us(t)) for seq, t in cur.fetchall())
    return found


def conflict_reason(seq: int, stream: str, clash: bool) -> str:
    what = "holds a different record" if clash else "follows a seq that does"
    return (
        f"seq {seq} on stream {stream or '(legacy)'} {what}: this queue's numbering went"
        " backwards (restored or cloned state?); not stored, continue on a new stream"
    )
