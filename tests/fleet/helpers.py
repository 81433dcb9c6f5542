"""Fleet test data: a machine with a device token and a job on a small path-ordered grid.

Rows are written with the ORM directly, so these tests do not depend on the
planning and prescription endpoints.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, field
from typing import Any

from pyproj import Transformer
from shapely.geometry import MultiPolygon, Polygon

EPSG = 32649  # UTM 49N, the demo plot near 112.32E 32.13N
LON0, LAT0 = 112.32005, 32.13005
CELL_L = 5.0
CELL_W = 3.0
N_SWATH = 2
N_PER_SWATH = 4
RATES = [300.0, 250.0, 200.0, 150.0, 310.0, 260.0, 210.0, 160.0]

# Citus names a shard after its table and shard id: telemetry_p2026_11_28_102345
_SHARD = re.compile(r"\b(\w+?)_\d{6,}\b")


def unshard(name: str) -> str:
    """A table name as the schema names it, also when Citus answered with its shard's."""
    return _SHARD.sub(r"\1", name)


def on_citus(conn: Any) -> bool:
    """Whether ``conn`` (psycopg or SQLAlchemy) is to a Citus coordinator's database."""
    sql = "SELECT EXISTS (SELECT 1 FROM pg_extension WHERE extname = 'citus')"
    if hasattr(conn, "scalar"):
        from sqlalchemy import text

        return bool(conn.scalar(text(sql)))
    return bool(conn.execute(sql).fetchone()[0])


def shard_free_plan(plan: str) -> str:
    """EXPLAIN text with Citus's shard suffixes removed, so tests read table and partition
    names the same on one node and on a Citus coordinator; there the plan must be a
    single-shard (router) one: the query names its machine."""
    if "Custom Scan (Citus" in plan:
        assert "Task Count: 1\n" in plan + "\n", f"not a single-shard plan:\n{plan}"
    return _SHARD.sub(r"\1", plan)


@dataclass
class JobFixture:
    org_id: int
    machine_id: int
    device_token: str
    job_id: int
    prescription_id: int
    plan_id: int
    field_id: int
    cells: list[dict[str, Any]] = field(default_factory=list)  # seq, rate, centre lon/lat, area

    @property
    def device_headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.device_token}"}


def grid() -> list[dict[str, Any]]:
    """8 cells 5 m x 3 m, 2 swaths, boustrophedon path order (seq 0-based)."""
    fwd = Transformer.from_crs(4326, EPSG, always_xy=True)
    inv = Transformer.from_crs(EPSG, 4326, always_xy=True)
    x0, y0 = fwd.transform(LON0, LAT0)
    cells = []
    seq = 0
    for s in range(N_SWATH):
        order = range(N_PER_SWATH) if s % 2 == 0 else range(N_PER_SWATH - 1, -1, -1)
        for i in order:
            xa, xb = x0 + i * CELL_L, x0 + (i + 1) * CELL_L
            ya, yb = y0 + s * CELL_W, y0 + (s + 1) * CELL_W
            corners = [(xa, ya), (xb, ya), (xb, yb), (xa, yb)]
            ll = [inv.transform(x, y) for x, y in corners]
            cx, cy = inv.transform((xa + xb) / 2, (ya + yb) / 2)
            cells.append(
                {
                    "seq": seq,
                    "swath": s,
                    "index": i,
                    "rate": RATES[seq],
                    "corners_utm": [c for xy in corners for c in xy],
                    "poly": Polygon(ll),
                    "lon": cx,
                    "lat": cy,
                    "area_m2": CELL_L * CELL_W,
                }
            )
            seq += 1
    return cells


def make_job(org_id: int, state: str = "planned", **machine_kw: Any) -> JobFixture:
    from fieldrx.auth.service import issue_device_token
    from fieldrx.db.models import (
        Field,
        Job,
        Machine,
        Plan,
        PlanCell,
        Prescription,
        PrescriptionRate,
        PrescriptionVersion,
    )
    from fieldrx.db.session import get_sessionmaker
    from fieldrx_edge.metering import SEED001_CALIBRATION
    from geoalchemy2.shape import from_shape
    from shapely.geometry import LineString

    cells = grid()
    boundary = MultiPolygon([Polygon.from_bounds(112.3200, 32.1300, 112.32037, 32.13021)])
    with get_sessionmaker()() as s:
        kw: dict[str, Any] = {
            "name": f"tractor-{time.monotonic_ns()}",
            "width_m": CELL_W,
            "lag_s": 1.52,
            "calibration": SEED001_CALIBRATION.to_dict(),
            "controller": {"name": "ladrc", "params": {}, "period_s": 0.01},
        }
        m = Machine(organisation_id=org_id, **{**kw, **machine_kw})
        f = Field(
            organisation_id=org_id,
            name="plot",
            boundary=from_shape(boundary, 4326),
            utm_epsg=EPSG,
            area_m2=37 * 23.0,
        )
        s.add_all([m, f])
        s.flush()
        p = Plan(
            organisation_id=org_id,
            field_id=f.id,
            params={"swath_width_m": CELL_W, "cell_length_m": CELL_L},
            metrics={},
            heading_deg=90.0,
            n_cells=len(cells),
            route=from_shape(LineString([(c["lon"], c["lat"]) for c in cells]), 4326),
        )
        s.add(p)
        s.flush()
        for c in cells:
            s.add(
                PlanCell(
                    plan_id=p.id,
                    seq=c["seq"],
                    swath=c["swath"],
                    index_in_swath=c["index"],
                    area_m2=c["area_m2"],
                    corners_utm=c["corners_utm"],
                    geom=from_shape(c["poly"], 4326),
                )
            )
        rx = Prescription(organisation_id=org_id, plan_id=p.id, model="uniform", name="rx")
        s.add(rx)
        s.flush()
        v = PrescriptionVersion(prescription_id=rx.id, version=1)
        s.add(v)
        s.flush()
        for c in cells:
            s.add(PrescriptionRate(version_id=v.id, seq=c["seq"], rate_kg_ha=c["rate"], flags=[]))
        job = Job(
            organisation_id=org_id,
            prescription_id=rx.id,
            prescription_version=1,
            machine_id=m.id,
            name="job",
            state=state,
            n_cells=len(cells),
        )
        s.add(job)
        s.flush()
        token = issue_device_token(s, m.id, org_id)
        s.commit()
        return JobFixture(org_id, m.id, token, job.id, rx.id, p.id, f.id, cells)


def record(
    fx: JobFixture, seq: int, t: float | None = None, cell: int | None = 0, **kw: Any
) -> dict[str, Any]:
    """A plausible record in ``cell`` (its centre), on target unless overridden."""
    c = fx.cells[cell if cell is not None else 0]
    rec: dict[str, Any] = {
        "machine_id": fx.machine_id,
        "seq": seq,
        "t": t if t is not None else 1_790_000_000.0 + seq * 0.1,
        "lon": c["lon"],
        "lat": c["lat"],
        "fix_quality": 4,
        "hdop": 0.8,
        "speed_raw_m_s": 1.5,
        "speed_filtered_m_s": 1.5,
        "heading_deg": 90.0,
        "job_id": fx.job_id,
        "cell_seq": cell,
        "target_rate_kg_ha": c["rate"],
        "applied_rate_kg_ha": c["rate"],
        "target_shaft_rpm": 30.0,
        "actual_shaft_rpm": 30.0,
        "duty": 40.0,
        "implement_down": True,
        "alarms": [],
        "queue_backlog": 0,
    }
    rec.update(kw)
    return rec
