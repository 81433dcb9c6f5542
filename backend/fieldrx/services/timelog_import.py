"""Store other terminals' as-applied logs (ISO 11783-10 TimeLogs, as-applied tables): the
records become a completed job on a prescription, on a machine created for the import.
``timelog_in_worker`` previews and stores spooled TimeLogs in a ``services.bounded``
child, refusing logs with no record on the prescription's field.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

import numpy as np
from sqlalchemy import insert, text
from sqlalchemy.orm import Session

from fieldrx.db.models import Job, Machine, Prescription, Telemetry
from fieldrx.db.session import limit_session, raw_dsn
from fieldrx.fleet.db import raw_connection
from fieldrx.fleet.partitions import PG_EPOCH_DT, ensure_days, record_job_spans
from fieldrx.formats import FormatError
from fieldrx.formats.timelog import TimeLog
from fieldrx.services.imports import IMPORTED_IMPLEMENT, read_spooled


def store_timelogs(
    session: Session,
    logs: list[TimeLog],
    rx: Prescription,
    organisation_id: int,
    user_id: int | None,
    width_m: float,
    source_name: str,
) -> dict[str, Any]:
    """As-applied records of other terminals as a completed job on ``rx`` (flush only).

    The records go to a machine created for the import (named after the
    file), never to a real machine: telemetry is deduplicated per machine and
    sequence number, so imported rows must not share a tractor's sequence.
    The machine has no calibration, so the report meters each record as
    applied rate x width x speed (``fleet.reports``), and lag 0: logged
    positions are where the terminal says product was applied.
    """
    machine = Machine(
        organisation_id=organisation_id,
        name=f"Imported: {source_name}"[:200],
        implement_type=IMPORTED_IMPLEMENT,
        width_m=width_m,
        lag_s=0.0,
        calibration={},
        antenna_forward_m=0.0,
    )
    session.add(machine)
    session.flush()
    job = Job(
        organisation_id=organisation_id,
        prescription_id=rx.id,
        prescription_version=rx.current_version,
        machine_id=machine.id,
        name=f"As-applied {source_name}"[:200],
        state="completed",
        created_by=user_id,
    )
    session.add(job)
    session.flush()
    rows: list[dict[str, Any]] = []
    seq = 0
    for log in logs:
        applied = log.series(7, 0.01)
        target = log.series(6, 0.01)
        speed = log.series(397, 0.001)
        state = log.series(141)
        down = np.where(np.isfinite(state), state == 1, np.nan_to_num(applied) > 0)
        ok = np.isfinite(log.lat) & np.isfinite(log.lon) & (np.nan_to_num(log.status, nan=1) != 0)
        for i in np.flatnonzero(ok).tolist():
            seq += 1
            rows.append(
                {
                    "machine_id": machine.id,
                    "seq": seq,
                    "t": dt.datetime.fromtimestamp(float(log.t[i]), dt.UTC),
                    "job_id": job.id,
                    "geom": f"SRID=4326;POINT({log.lon[i]:.9f} {log.lat[i]:.9f})",
                    "fix_quality": 1,
                    "speed_raw_m_s": None if not np.isfinite(speed[i]) else float(speed[i]),
                    "target_rate_kg_ha": None if not np.isfinite(target[i]) else float(target[i]),
                    "applied_rate_kg_ha": float(np.nan_to_num(applied[i])),
                    "implement_down": bool(down[i]),
                    "alarms": [],
                }
            )
    if not rows:
        raise FormatError(f"{source_name}: no time log record has a position")
    # the records' daily partitions (a task log may be years old), made and committed on
    # a connection of their own; then the rows and the job's time span (fleet.partitions)
    t_us = [(r["t"] - PG_EPOCH_DT) // dt.timedelta(microseconds=1) for r in rows]
    bind_url = session.get_bind().engine.url.render_as_string(hide_password=False)
    with raw_connection(raw_dsn(bind_url)) as c:
        ensure_days(c, t_us)
    session.execute(insert(Telemetry), rows)
    with session.connection().connection.dbapi_connection.cursor() as cur:  # type: ignore[union-attr]
        record_job_spans(cur, machine.id, t_us, [job.id] * len(rows))
    window = {"m": machine.id, "t0": min(r["t"] for r in rows), "t1": max(r["t"] for r in rows)}
    plan_id = rx.plan_id
    session.execute(
        text(
            "UPDATE telemetry t SET cell_seq = pc.seq FROM plan_cells pc"
            " WHERE t.machine_id = :m AND t.t BETWEEN :t0 AND :t1 AND pc.plan_id = :p"
            " AND ST_Intersects(pc.geom, t.geom)"
        ),
        {**window, "p": plan_id},
    )
    session.execute(
        text(
            "INSERT INTO job_cells_applied (machine_id, job_id, seq, n_records,"
            " target_rate_sum, applied_rate_sum, first_t, last_t)"
            " SELECT :m, :j, cell_seq, count(*), sum(coalesce(target_rate_kg_ha, 0)),"
            " sum(applied_rate_kg_ha), min(t), max(t) FROM telemetry"
            " WHERE machine_id = :m AND t BETWEEN :t0 AND :t1 AND cell_seq IS NOT NULL"
            " AND implement_down GROUP BY cell_seq"
        ),
        {**window, "j": job.id},
    )
    session.flush()
    return {"job_id": job.id, "machine_id": machine.id, "records": len(rows)}


@dataclass
class TimelogRequest:
    """One TimeLog import for ``timelog_in_worker``: the spooled files (name, path), the
    prescription (already scoped to the caller) and, for a confirm, who stores it."""

    database_url: str
    files: list[tuple[str, str]]
    source_name: str
    prescription_id: int
    organisation_id: int
    user_id: int | None
    width_m: float | None = None
    confirm: bool = False
    time_limit_s: float = 120.0


def _read_timelogs(files: list[tuple[str, str]], names: str) -> list[TimeLog]:
    from fieldrx.formats.timelog import read_timelog

    data = read_spooled(files)
    by_upper = {k.rsplit("/", 1)[-1].upper(): v for k, v in data.items()}
    heads = sorted(k[:-4] for k in by_upper if k.startswith("TLG") and k.endswith(".XML"))
    if not heads:
        raise FormatError(f"no TLGxxxxx.XML time log header in the upload ({names})")
    logs = []
    for h in heads:
        if f"{h}.BIN" not in by_upper:
            raise FormatError(f"{h}.XML: its binary {h}.BIN is missing from the upload")
        logs.append(read_timelog(h, by_upper[f"{h}.XML"], by_upper[f"{h}.BIN"]))
    return logs


def timelog_in_worker(req: TimelogRequest) -> dict[str, Any]:
    """Inflate, decode and preview spooled TimeLogs and, on confirm, store them as a job
    and commit, in a ``services.bounded`` child (an archive never inflates in the server's
    memory). Returns ``{"timelogs", "width_m", "refused", "created"?}``: each log's summary
    with where its records lie against the prescription's field; logs with no record on
    the field are refused. A confirm with refused logs, or without a width (none given,
    none logged), is a ``FormatError`` and stores nothing."""
    from fieldrx.db.session import make_engine
    from fieldrx.formats.timelog import timelog_summary
    from fieldrx.services.bounded import ensure_caller_alive
    from fieldrx.services.import_checks import fmt_distance, points_placement
    from fieldrx.services.prescriptions.versions import field_boundary_wgs84

    logs = _read_timelogs(req.files, req.source_name)
    engine = make_engine(req.database_url)
    try:
        with Session(engine) as session:
            limit_session(session, req.time_limit_s)
            rx = session.get(Prescription, req.prescription_id)
            if rx is None:
                raise FormatError(f"prescription {req.prescription_id} was deleted meanwhile")
            fb = field_boundary_wgs84(session, rx)
            pre: list[dict[str, Any]] = []
            for log in logs:
                entry = timelog_summary(log)
                if fb is not None:
                    entry["placement"] = points_placement(fb[1], log.lon, log.lat)
                pre.append(entry)
            width = req.width_m
            if width is None:
                logged = [float(p["logged_width_m"]) for p in pre if p["logged_width_m"]]
                width = float(np.median(logged)) if logged else None
            off = [
                p
                for p in pre
                if p.get("placement", {}).get("on_field") == 0 and p["with_position"]
            ]
            refused = [
                f"{p['timelog']}: no record lies on the prescription's field; the nearest is "
                f"{fmt_distance(p['placement']['distance_m'])} away"
                for p in off
            ]
            out: dict[str, Any] = {"timelogs": pre, "width_m": width, "refused": refused}
            if not req.confirm:
                return out
            if refused:
                raise FormatError("; ".join(refused) + ": nothing stored")
            if width is None:
                raise FormatError("the logs carry no working width (DDI 67): give width_m")
            out["created"] = store_timelogs(
                session, logs, rx, req.organisation_id, req.user_id, width, req.source_name
            )
            ensure_caller_alive("the TimeLog import")
            session.commit()
    finally:
        engine.dispose()
    return out
