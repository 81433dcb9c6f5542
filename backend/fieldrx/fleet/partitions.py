"""Telemetry's daily partitions (migration 0010): made for the days records arrive for,
kept by pg_partman, and each job's time span so a job's queries touch only its days.

* ``ensure_days``: before a batch is stored, the UTC day of every record needs its
  partition. Premade days (today and 4 ahead) are the common case, answered from a
  per-process cache. An agent uploading days-old records after offline work, or an
  import of an old task log, needs a past day: it is made on demand with pg_partman's
  ``create_partition_time`` (an ATTACH: a SHARE UPDATE EXCLUSIVE lock on ``telemetry``,
  so stores and reads of other days go on). If that cannot be done at once (lock
  timeout, a race with maintenance), the records go to the default partition: nothing is
  lost, and ``maintain`` moves them into their day later.
* ``maintain`` (``fieldrx telemetry-maintenance``, and every ``maintenance_s`` in
  ``fieldrx worker``): moves rows out of the default partition (never those older than
  ``ON_DEMAND_DAYS``: they stay there, as ingest flags them), then pg_partman's
  ``run_maintenance`` premakes days ahead and drops days older than the retention
  (``FIELDRX_TELEMETRY_RETENTION_DAYS``; 0 keeps everything). Only raw records expire:
  per-cell results (``job_cells_applied``) live in their own tables and are kept.
* ``record_job_spans`` / ``job_window``: the first and last record time per (machine,
  job), kept by every writer of telemetry (ingest, imports), read by every job query.

All pg_partman calls run with ``timezone = UTC``: day boundaries are UTC midnights, as
pg_partman's documentation asks (a session in another zone would shift them).
"""

from __future__ import annotations

import datetime as dt
import logging
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import psycopg
from sqlalchemy import text
from sqlalchemy.orm import Session

log = logging.getLogger(__name__)

PARENT = "public.telemetry"
DAY_US = 86_400_000_000
PG_EPOCH_DT = dt.datetime(2000, 1, 1, tzinfo=dt.UTC)  # t as int8 us counts from here
CREATE_LOCK_TIMEOUT = "1s"  # creating a day never stalls ingest for longer than this
RETRY_AFTER_S = 60.0  # a day that could not be made now goes to the default partition
# On-demand days are bounded: a batch makes at most MAX_NEW_DAYS past days (the newest of
# those it needs), and never one older than ON_DEMAND_DAYS before today; the other records
# go to the default partition (a device naming a day per record of 2000-2003 made one
# partition per record). Agents back from weeks of offline work still get their days.
MAX_NEW_DAYS = 4
ON_DEMAND_DAYS = 400
FAR_PAST_REASON = (
    f"record time is more than {ON_DEMAND_DAYS} days in the past: stored in the default"
    " partition (no day partition is made for it), check the device clock"
)
_LOCK_NS = 7002  # advisory lock namespace: partition creation (7001 is ingest's)

_known: set[tuple[str, int]] = set()  # (database, UTC day number) with a partition
_failed: dict[tuple[str, int], float] = {}  # (database, day) -> monotonic time of failure
_partman: dict[str, tuple[str, int]] = {}  # database -> (schema, major version)
_cache_lock = threading.Lock()


def _db(conn: psycopg.Connection[Any]) -> str:
    i = conn.info
    return f"{i.host}:{i.port}/{i.dbname}"


def day_start(day: int) -> dt.datetime:
    """UTC day number (days since 2000-01-01) -> its first instant."""
    return PG_EPOCH_DT + dt.timedelta(days=day)


def partman(conn: psycopg.Connection[Any]) -> tuple[str, int]:
    """pg_partman's schema (``partman`` as the bootstrap creates it) and major version:
    Debian 12 ships 4.7; the PGDG image of docker-compose may bring 5, whose
    ``create_partition_time`` has no ``p_analyze`` argument."""
    key = _db(conn)
    s = _partman.get(key)
    if s is None:
        with conn.transaction():  # never leave the caller's connection inside a transaction
            row = conn.execute(
                "SELECT extnamespace::regnamespace::text, extversion FROM pg_extension"
                " WHERE extname = 'pg_partman'"
            ).fetchone()
        if row is None:
            raise RuntimeError("pg_partman is not installed in this database (migration 0010)")
        s = _partman[key] = (str(row[0]), int(str(row[1]).split(".")[0]))
    return s


def create_days_sql(schema: str, major: int) -> str:
    """``create_partition_time`` for a timestamptz[] parameter, without an ANALYZE of the
    whole set (v4: ``p_analyze`` false; v5 never analyzes there)."""
    analyze = ", p_analyze := false" if major < 5 else ""
    return f"SELECT {schema}.create_partition_time(%s, %s::timestamptz[]{analyze})"


def ensure_days(conn: psycopg.Connection[Any], t_us: Iterable[int]) -> list[int]:
    """Make the partitions of the UTC days of these record times (int8 us since
    2000-01-01, the COPY rows' ``t``); the days made. ``conn`` must not be inside a
    transaction: a day is made and committed on its own, before the batch's transaction.
    A day that cannot be made now is left to the default partition (logged)."""
    if conn.info.transaction_status != psycopg.pq.TransactionStatus.IDLE:
        return []  # inside the caller's transaction: the default partition takes them
    key = _db(conn)
    days = {t // DAY_US for t in t_us}
    missing = [d for d in days if (key, d) not in _known]
    if not missing:
        return []
    missing = _bounded(missing)
    if not missing:
        return []
    now = time.monotonic()
    with _cache_lock:
        missing = [
            d for d in missing if now - _failed.get((key, d), -RETRY_AFTER_S) >= RETRY_AFTER_S
        ]
    if not missing:
        return []
    made: list[int] = []
    try:
        pm, major = partman(conn)
        with conn.transaction(), conn.cursor() as cur:
            cur.execute("SET LOCAL timezone = 'UTC'")
            cur.execute(f"SET LOCAL lock_timeout = '{CREATE_LOCK_TIMEOUT}'")
            cur.execute("SELECT pg_advisory_xact_lock(%s, 0)", (_LOCK_NS,))
            for d in sorted(missing):
                cur.execute(
                    f"SELECT table_exists FROM {pm}.show_partition_name(%s, %s)",
                    (PARENT, day_start(d).isoformat()),
                )
                row = cur.fetchone()
                if row is not None and not row[0]:
                    made.append(d)
            if made:
                cur.execute(create_days_sql(pm, major), (PARENT, [day_start(d) for d in made]))
    except psycopg.Error as exc:
        log.warning(
            "telemetry partitions for %s not made now (%s): their records go to the default"
            " partition until maintenance moves them",
            ", ".join(day_start(d).date().isoformat() for d in sorted(missing)),
            str(exc).strip(),
        )
        with _cache_lock:
            _failed.update({(key, d): now for d in missing})
        return []
    with _cache_lock:
        _known.update((key, d) for d in missing)
        for d in missing:
            _failed.pop((key, d), None)
    return made


def oldest_day() -> int:
    """The oldest UTC day number that gets its own partition (ingest or maintenance):
    records before it stay in the default partition and are flagged."""
    return int((time.time() - PG_EPOCH_DT.timestamp()) // 86_400) - ON_DEMAND_DAYS


def is_far_past(t_us: int) -> bool:
    """A record time (int8 us since 2000-01-01) before ``oldest_day``."""
    return t_us // DAY_US < oldest_day()


def _bounded(days: list[int]) -> list[int]:
    """The days a batch may make (see MAX_NEW_DAYS); logs the rest (default partition)."""
    oldest = oldest_day()
    recent = sorted((d for d in days if d >= oldest), reverse=True)
    keep = recent[:MAX_NEW_DAYS]
    if len(keep) < len(days):
        log.warning(
            "telemetry of %d day(s) (from %s) goes to the default partition: a batch makes at"
            " most %d past days, none older than %d days",
            len(days) - len(keep),
            day_start(min(days)).date().isoformat(),
            MAX_NEW_DAYS,
            ON_DEMAND_DAYS,
        )
    return keep


def forget_days(conn: psycopg.Connection[Any]) -> None:
    """Drop this process's cache of made days for ``conn``'s database (after maintenance
    dropped some): the next batch for a dropped day checks again."""
    key = _db(conn)
    with _cache_lock:
        _known.difference_update({k for k in _known if k[0] == key})


def record_job_spans(
    cur: psycopg.Cursor[Any], machine_id: int, t_us: Iterable[int], job_ids: Iterable[int | None]
) -> None:
    """Widen the (machine, job) time spans by these stored records (int8 us ``t`` and their
    ``job_id``; records without a job are skipped). Every writer of telemetry calls this
    (or runs ``job_spans_sql`` itself) in the transaction that stores the rows: job
    queries read only inside the span."""
    stmt = job_spans_sql(machine_id, t_us, job_ids)
    if stmt is not None:
        cur.execute(*stmt)


def job_spans_sql(
    machine_id: int, t_us: Iterable[int], job_ids: Iterable[int | None]
) -> tuple[str, tuple[Any, ...]] | None:
    """``record_job_spans``'s statement and its (positional) parameters; None: no job."""
    spans: dict[int, list[int]] = {}
    for t, j in zip(t_us, job_ids, strict=True):
        if j is None:
            continue
        s = spans.get(j)
        if s is None:
            spans[j] = [t, t, 1]
        else:
            if t < s[0]:
                s[0] = t
            elif t > s[1]:
                s[1] = t
            s[2] += 1
    if not spans:
        return None
    ids = sorted(spans)
    return (
        # the spans join their jobs on the machine: on Citus an INSERT ... SELECT reading a
        # co-located table by its distribution column is one router plan on the machine's
        # shard (from the arrays alone it is pulled through the coordinator)
        "INSERT INTO telemetry_job_spans AS s (machine_id, job_id, first_t, last_t, n_records)"
        " SELECT jb.machine_id, j, t0, t1, n FROM unnest(%s::int[], %s::timestamptz[],"
        " %s::timestamptz[], %s::int8[]) AS u(j, t0, t1, n)"
        " JOIN jobs jb ON jb.machine_id = %s AND jb.id = u.j"
        " ON CONFLICT (machine_id, job_id) DO UPDATE SET"
        " first_t = least(s.first_t, excluded.first_t),"
        " last_t = greatest(s.last_t, excluded.last_t),"
        " n_records = s.n_records + excluded.n_records",
        (
            ids,
            [PG_EPOCH_DT + dt.timedelta(microseconds=spans[j][0]) for j in ids],
            [PG_EPOCH_DT + dt.timedelta(microseconds=spans[j][1]) for j in ids],
            [spans[j][2] for j in ids],
            machine_id,
        ),
    )


def job_window(session: Session, machine_id: int, job_id: int) -> dict[str, Any]:
    """``{"t0": first, "t1": last}`` record time of the machine's records of the job, as
    bind parameters for ``t BETWEEN :t0 AND :t1`` (both None when it has none: the
    comparison is then null and the query reads no partition)."""
    row = session.execute(
        text(
            "SELECT first_t, last_t FROM telemetry_job_spans WHERE machine_id = :m AND job_id = :j"
        ),
        {"m": machine_id, "j": job_id},
    ).first()
    return {"t0": row[0], "t1": row[1]} if row is not None else {"t0": None, "t1": None}


DEFAULT_WINDOW_S = 86_400.0  # a machine query without a range: its latest day of records


def machine_window(
    session: Session,
    machine_id: int,
    frm: dt.datetime | None,
    to: dt.datetime | None,
    default_s: float = DEFAULT_WINDOW_S,
) -> dict[str, Any]:
    """``{"t0", "t1"}`` bind parameters for ``t BETWEEN :t0 AND :t1`` of a machine's
    telemetry query (track, chart series): never open-ended, so PostgreSQL plans and reads
    only the days in it, not every day of the table (50 ms of planning alone at 400 days).

    The open ends come from the machine's stored span: every record it stored lies between
    the first and last record time of its streams (``telemetry_streams``) and its jobs
    (``telemetry_job_spans``, which imports widen too). A range given in full is used as
    it is; ``from`` alone runs to the machine's last record and ``to`` alone from its first
    (the same records as an open range); no range at all is the ``default_s`` up to its
    last record (its latest working day; the UI shows the newest points). Both None when
    the machine has no record: the comparison is null and no partition is read."""
    if frm is not None and to is not None:
        return {"t0": frm, "t1": to}
    first, last = session.execute(
        text(
            "SELECT min(first_t), max(last_t) FROM ("
            " SELECT first_t, last_t FROM telemetry_streams WHERE machine_id = :m"
            " UNION ALL"
            " SELECT first_t, last_t FROM telemetry_job_spans WHERE machine_id = :m) s"
        ),
        {"m": machine_id},
    ).one()
    if first is None or last is None:
        return {"t0": None, "t1": None}
    if frm is None and to is None:
        return {"t0": last - dt.timedelta(seconds=default_s), "t1": last}
    return {"t0": first if frm is None else frm, "t1": last if to is None else to}


@dataclass
class MaintenanceResult:
    moved_rows: int  # rows moved out of the default partition into their day
    far_past_rows: int  # rows left in the default partition: older than ON_DEMAND_DAYS
    created: list[str]  # partitions made (premake, or days of moved rows)
    dropped: list[str]  # partitions dropped by the retention
    partitions: int  # day partitions after the run
    retention_days: int  # 0: keep everything
    seconds: float


def _children(conn: psycopg.Connection[Any]) -> set[str]:
    with conn.transaction():
        rows = conn.execute(
            "SELECT c.relname FROM pg_inherits i JOIN pg_class c ON c.oid = i.inhrelid"
            " WHERE i.inhparent = 'public.telemetry'::regclass"
            " AND c.relname <> 'telemetry_default'"
        ).fetchall()
    return {r[0] for r in rows}


def _move_default_rows(conn: psycopg.Connection[Any], pm: str, lock_wait_s: int) -> int:
    """Move the default partition's rows into their days, newest day first, down to
    ``oldest_day`` (pg_partman's ``p_order`` DESC takes the newest day left each call)."""
    moved = 0
    while True:
        with conn.transaction(), conn.cursor() as cur:
            cur.execute("SET LOCAL timezone = 'UTC'")
            cur.execute(f"SET LOCAL lock_timeout = '{lock_wait_s}s'")
            cur.execute(
                "SELECT EXISTS (SELECT 1 FROM telemetry_default WHERE t >= %s)",
                (day_start(oldest_day()),),
            )
            if not cur.fetchone()[0]:  # type: ignore[index]
                break
            cur.execute(
                f"SELECT {pm}.partition_data_time(%s, p_order := 'DESC', p_analyze := false)",
                (PARENT,),
            )
            n = int(cur.fetchone()[0] or 0)  # type: ignore[index]
        moved += n
        if n == 0:
            break
    return moved


def maintain(
    conn: psycopg.Connection[Any], retention_days: int = 0, wait: bool = True, lock_wait_s: int = 5
) -> MaintenanceResult | None:
    """One maintenance run; None when another run holds the lock and ``wait`` is false.

    1. rows in the default partition move into their day (``partition_data_time``
       makes the day; one day per transaction, newest first): a batch whose day could
       not be made at once is now in place. Rows older than ``ON_DEMAND_DAYS`` stay:
       moving them would make the old days ingest refused to make (a day per record a
       device names), so maintenance keeps the same bound;
    2. the retention is written into pg_partman's config (``retention_days`` days; 0:
       none) and ``run_maintenance`` premakes days ahead and drops whole days older than
       the retention.

    Idempotent. ``conn`` must not be inside a transaction; each step commits on its own
    (short locks), one run at a time per database (a session advisory lock).
    """
    t0 = time.perf_counter()
    pm, _ = partman(conn)
    if wait:
        conn.execute("SELECT pg_advisory_lock(%s, 1)", (_LOCK_NS,))
    elif not conn.execute("SELECT pg_try_advisory_lock(%s, 1)", (_LOCK_NS,)).fetchone()[0]:  # type: ignore[index]
        conn.commit()
        return None
    conn.commit()
    try:
        before = _children(conn)
        moved = _move_default_rows(conn, pm, lock_wait_s)
        with conn.transaction(), conn.cursor() as cur:
            cur.execute("SET LOCAL timezone = 'UTC'")
            cur.execute(f"SET LOCAL lock_timeout = '{lock_wait_s}s'")
            cur.execute(
                f"UPDATE {pm}.part_config SET retention = %s, retention_keep_table = false,"
                " infinite_time_partitions = true WHERE parent_table = %s",
                (f"{retention_days} days" if retention_days > 0 else None, PARENT),
            )
            cur.execute(
                f"SELECT {pm}.run_maintenance(%s, p_analyze := false, p_jobmon := false)",
                (PARENT,),
            )
        after = _children(conn)
    finally:
        conn.execute("SELECT pg_advisory_unlock(%s, 1)", (_LOCK_NS,))
        conn.commit()
    if before - after:
        forget_days(conn)
    with conn.transaction():
        far = conn.execute(
            "SELECT count(*) FROM telemetry_default WHERE t < %s", (day_start(oldest_day()),)
        ).fetchone()
    return MaintenanceResult(
        moved_rows=moved,
        far_past_rows=int(far[0]) if far is not None else 0,
        created=sorted(after - before),
        dropped=sorted(before - after),
        partitions=len(after),
        retention_days=retention_days,
        seconds=time.perf_counter() - t0,
    )
