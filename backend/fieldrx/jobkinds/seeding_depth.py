"""Seed 002's depth-controlled seeding on the server: the report's depth table (seed 002
Table 3, GB/T 20865 band), the live low-qualified alert and its check at the job's end."""

from __future__ import annotations

from typing import Any

from fieldrx_edge.depth import qualified_band_mm
from fieldrx_edge.jobkinds.figures import depth_table, qualified_alert

from fieldrx.fleet.seed_alerts import depth_window
from fieldrx.fleet.seed_reports import depth_job_end
from fieldrx.jobkinds.registry import ServerHooks, register


def report(
    rows: list[dict[str, Any]], s: dict[str, Any], out: dict[str, Any]
) -> tuple[float, float]:
    """Seed 002 Table 3 per speed band and the trailing-window qualified check."""
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
    return lo, hi


register(
    ServerHooks(
        "seeding_depth",
        report=report,
        cell_columns=("depth_mm", "qualified_pct"),
        live_alerts=depth_window,
        job_end=depth_job_end,
    )
)
