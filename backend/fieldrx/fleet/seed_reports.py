"""Reports of the sensor job kinds, from the job's stored telemetry.

* ``ndvi_topdress`` (seed 000): the NDVI map (raw and window-filtered NDVI per plan cell),
  the applied-rate map (target and applied kg/ha per cell) and the paper's Table 3:
  theoretical vs monitored shaft speed and relative error per test speed.
* ``seeding_depth`` (seed 002): the depth map (mean measured depth and qualified share per
  cell), the paper's Table 3 per speed band and for the job (mean depth, qualified %, SD,
  CV; GB/T 20865 band) and the low-qualified-share check over the trailing N metres.

Tables come from ``fieldrx_edge.jobkinds.figures``, the definition the simulator uses, so
a simulated job's report can be checked against the simulator's own figures. Records are
placed in plan cells by position (PostGIS), so the maps need no cell id from the agent.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from typing import Any

import numpy as np
from fieldrx_edge.jobkinds.figures import depth_table, qualified_alert, shaft_table
from sqlalchemy import text
from sqlalchemy.orm import Session

from fieldrx.agronomy.prescription import application_outcome
from fieldrx.db.models import Alert, Job
from fieldrx.fleet.operator_events import operator_events
from fieldrx.fleet.partitions import job_window

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
    """The report of a sensor-kind job (see the module doc)."""
    from fieldrx_edge.depth import qualified_band_mm

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
    lo, hi = (0.0, 0.0)
    if job.kind == "ndvi_topdress":
        out["shaft_table"] = shaft_table(rows, list(s["speed_bands_kmh"]))
        out["mean_relative_error_pct"] = out["shaft_table"]["mean_relative_error_pct"]
        out["paper"] = {
            "source": "seed 000 Table 3",
            "relative_error_pct": [2.0, 3.6, 3.8, 4.0],
            "mean_relative_error_pct": 3.35,
        }
    else:
        target = float(s["target_depth_mm"])
        lo, hi = qualified_band_mm(target)
        out["depth_table"] = depth_table(rows, s["speed_bands_kmh"], target)
        out["qualified_alert"] = qualified_alert(
            rows, target, float(s["alert_window_m"]), float(s["alert_min_qualified_pct"])
        )
        out["paper"] = {
            "source": "seed 002 Table 3 (1-3 / 3-5 / 5-7 km/h)",
            "mean_mm": [31.49, 30.13, 31.75],
            "qualified_pct": [92, 93, 91],
            "sd_mm": [0.26, 0.18, 0.21],
            "cv_pct": [3.51, 2.93, 3.26],
        }
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
        keep = (
            ("ndvi", "ndvi_raw", "target_rate_kg_ha", "applied_rate_kg_ha")
            if job.kind == "ndvi_topdress"
            else ("depth_mm", "qualified_pct")
        )
        rows_c = res.all()
        out["cells"] = [
            {"seq": r.seq, "n": r.n, "area_m2": r.area_m2, **{k: getattr(r, k) for k in keep}}
            for r in rows_c
        ]
        if job.kind == "ndvi_topdress":
            out["outcome"] = ndvi_outcome(rows_c)
    return out


def ndvi_outcome(cells: Sequence[Any]) -> dict[str, Any]:
    """What the NDVI job delivered against what its curve asked for, over the cells it
    worked (``agronomy.prescription.application_outcome``): the report's headline. The
    shaft-speed table (seed 000 Table 3) can look perfect while the meter sits at its floor
    above the curve; this says so in kg and kg/ha."""
    return application_outcome(
        np.array([r.target_rate_kg_ha or 0.0 for r in cells], dtype=float),
        np.array([r.applied_rate_kg_ha or 0.0 for r in cells], dtype=float),
        np.array([r.area_m2 for r in cells], dtype=float),
    )


def alert_kind_job_end(session: Session, job: Job) -> Alert | None:
    """Seeding job ended: the live ``depth_qualified_low`` alert (fleet.seed_alerts) ends with
    the job; when none was raised live (records replayed late, or a window the live check
    never saw whole), the whole job's records are checked once and an alert says where the
    qualified share over the trailing window fell below the job's threshold."""
    if job.kind != "seeding_depth":
        return None
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
