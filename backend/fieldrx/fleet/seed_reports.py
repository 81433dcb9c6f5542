"""Reports of the sensor job kinds, from the job's stored telemetry.

* NDVI topdressing (seed 000): the NDVI map (raw and window-filtered NDVI per plan cell),
  the applied-rate map (target and applied kg/ha per cell) and the paper's Table 3:
  theoretical vs monitored shaft speed and relative error per test speed.
* depth-controlled seeding (seed 002): the depth map (mean measured depth and qualified
  share per cell), the paper's Table 3 per speed band and for the job (mean depth,
  qualified %, SD, CV; GB/T 20865 band) and the low-qualified-share check over the
  trailing N metres.

Each kind's figures are its server hooks' (``fieldrx.jobkinds``). Tables come from
``fieldrx_edge.jobkinds.figures``, the definition the simulator uses, so a simulated job's
report can be checked against the simulator's own figures. Records are placed in plan
cells by position (PostGIS), so the maps need no cell id from the agent.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from fieldrx_edge.jobkinds.figures import qualified_alert
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.db.models import Alert, Job
from fieldrx.fleet.operator_events import operator_events
from fieldrx.fleet.partitions import job_window
from fieldrx.jobkinds.registry import hooks

_ROWS_SQL = text(
    """
    SELECT seq, extract(epoch FROM t) AS ts, speed_filtered_m_s, implement_down,
           target_shaft_rpm, actual_shaft_rpm, depth_mm, alarms
    FROM telemetry WHERE machine_id = :m AND job_id = :j AND t BETWEEN :t0 AND :t1
    ORDER BY t, seq
    """
)

_CELLS_SQL = text(
    """
    SELECT pc.seq, pc.area_m2, count(*) AS n,
           avg(t.ndvi) AS ndvi, avg(t.ndvi_raw) AS ndvi_raw,
           avg(t.target_rate_kg_ha) AS target_rate_kg_ha,
           avg(t.applied_rate_kg_ha) AS applied_rate_kg_ha,
           avg(t.depth_mm) AS depth_mm,
           -- float8: a numeric average reaches the JSON as a decimal string
           (100.0 * avg(CASE WHEN t.depth_mm BETWEEN :lo AND :hi THEN 1.0 ELSE 0.0 END)
               FILTER (WHERE t.depth_mm IS NOT NULL))::float8 AS qualified_pct
    FROM telemetry t
    JOIN plan_cells pc ON pc.plan_id = :plan AND ST_Intersects(pc.geom, t.geom)
    WHERE t.machine_id = :m AND t.job_id = :j AND t.t BETWEEN :t0 AND :t1
      AND t.implement_down AND t.geom IS NOT NULL
    GROUP BY pc.seq, pc.area_m2 ORDER BY pc.seq
    """
)


def _rows(session: Session, job: Job) -> list[dict[str, Any]]:
    res = session.execute(
        _ROWS_SQL, {"m": job.machine_id, "j": job.id, **job_window(session, job.machine_id, job.id)}
    )
    return [
        {
            "seq": r.seq,
            "t": float(r.ts),
            "speed": r.speed_filtered_m_s,
            "down": r.implement_down,
            "target_rpm": r.target_shaft_rpm,
            "actual_rpm": r.actual_shaft_rpm,
            "depth_mm": r.depth_mm,
            "alarms": list(r.alarms or ()),
        }
        for r in res
    ]


def kind_report(session: Session, job: Job, cells: bool = True) -> dict[str, Any]:
    """The report of a sensor-kind job (see the module doc); the kind's own figures come
    from its server hooks (``fieldrx.jobkinds``)."""
    h = hooks(job.kind)
    s = dict(job.settings or {})
    rows = _rows(session, job)
    out: dict[str, Any] = {
        "job_id": job.id,
        "kind": job.kind,
        "state": job.state,
        "settings": s,
        "n_records": len(rows),
        "sensor_alarm_records": {
            a: sum(1 for r in rows if a in r["alarms"]) for a in ("sensor_fault", "sensor_lost")
        },
        "operator": operator_events(session, job.machine_id, job.id),
    }
    lo, hi = h.report(rows, s, out) if h.report is not None else (0.0, 0.0)
    if cells:
        res = session.execute(
            _CELLS_SQL,
            {
                "m": job.machine_id,
                "j": job.id,
                "plan": job.plan_id,
                "lo": lo,
                "hi": hi,
                **job_window(session, job.machine_id, job.id),
            },
        )
        rows_c = res.all()
        out["cells"] = [
            {
                "seq": r.seq,
                "n": r.n,
                "area_m2": r.area_m2,
                **{k: getattr(r, k) for k in h.cell_columns},
            }
            for r in rows_c
        ]
        if h.outcome is not None:
            out["outcome"] = h.outcome(rows_c)
    return out


def depth_job_end(session: Session, job: Job) -> Alert | None:
    """Seeding job ended: the live ``depth_qualified_low`` alert (fleet.seed_alerts) ends with
    the job; when none was raised live (records replayed late, or a window the live check
    never saw whole), the whole job's records are checked once and an alert says where the
    qualified share over the trailing window fell below the job's threshold."""
    session.flush()
    now = dt.datetime.now(dt.UTC)
    raised = session.execute(
        text(
            "UPDATE alerts SET ended_at = coalesce(ended_at, :now)"
            " WHERE job_id = :j AND kind = 'depth_qualified_low' RETURNING id"
        ),
        {"j": job.id, "now": now},
    ).all()
    if raised:
        return None
    s = job.settings
    from fieldrx_edge.depth import qualified_band_mm

    qa = qualified_alert(
        _rows(session, job),
        float(s["target_depth_mm"]),
        float(s["alert_window_m"]),
        float(s["alert_min_qualified_pct"]),
    )
    if not qa["triggered"]:
        return None
    lo, hi = qualified_band_mm(float(s["target_depth_mm"]))
    f = qa["first"]
    a = Alert(
        organisation_id=job.organisation_id,
        machine_id=job.machine_id,
        job_id=job.id,
        kind="depth_qualified_low",
        message=(
            f"sowing depth qualified ({lo:g}-{hi:g} mm) only {f['qualified_pct']:.1f} % over"
            f" {qa['window_m']:g} m at record {f['seq']} ({f['at_m']:.0f} m worked); worst"
            f" {qa['worst_qualified_pct']:.1f} %, threshold {qa['min_qualified_pct']:g} %"
        ),
        value=float(qa["worst_qualified_pct"]),
        started_at=now,
        ended_at=now,
    )
    session.add(a)
    return a
