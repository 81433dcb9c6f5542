"""Seed 000's NDVI topdressing on the server: the width from the machine, the rate curve
against the machine's meter, and the report's shaft-speed table (seed 000 Table 3)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from fieldrx_edge.jobkinds.figures import shaft_table
from fieldrx_edge.jobkinds.registry import kind_of
from fieldrx_edge.jobkinds.settings import SettingsError

from fieldrx.agronomy.prescription import application_outcome
from fieldrx.jobkinds.registry import ServerHooks, register

NAME = "ndvi_topdress"


def prepare(given: dict[str, Any], machine: Any) -> tuple[dict[str, Any], str]:
    """The implement width is the machine's: a different one is refused, an absent one is
    taken from the machine and the note says so."""
    default_w = kind_of(NAME).defaults["implement_width_m"]
    note = ""
    w = given.get("implement_width_m")
    if w is None:
        given["implement_width_m"] = machine.width_m
        if abs(machine.width_m - default_w) > 1e-9:
            note = (
                f"implement width {machine.width_m:g} m from machine '{machine.name}'"
                f" (seed 000's default is {default_w:g} m)"
            )
    elif isinstance(w, int | float) and abs(float(w) - machine.width_m) > 1e-6:
        raise SettingsError(
            "implement_width_m",
            f"{w:g} m differs from machine '{machine.name}'"
            f" ({machine.width_m:g} m): the rate is metered over the machine's width",
        )
    return given, note


def curve_meter_conflict(settings: dict[str, Any], machine: Any) -> dict[str, Any] | None:
    """Where an NDVI job's rate curve (seed 000: 375 kg/ha at NDVI 0.24 down to 180 at
    0.65) leaves what the machine can meter over its speed range (seed 001 eq. 1-3, the
    check a prescription job's cells get): the curve's range, the meter's and a sentence;
    None when the whole curve is meterable or the machine has no calibration to check."""
    # the meter's range is the prescription service's one definition; imported here, at
    # job creation, so the report and ingest paths do not load the service layer
    from fieldrx.services.prescriptions.meter import MeterSpec

    if not machine.calibration:
        return None
    curve = settings["rate_curve"]
    lo = min(curve["rate_at_lo_kg_ha"], curve["rate_at_hi_kg_ha"])
    hi = max(curve["rate_at_lo_kg_ha"], curve["rate_at_hi_kg_ha"])
    spec = MeterSpec(
        dict(machine.calibration), machine.width_m, machine.speed_min_m_s, machine.speed_max_m_s
    )
    try:
        meter = spec.describe()
    except ValueError as exc:
        return {"curve_kg_ha": [lo, hi], "meter": None, "message": str(exc)}
    m_lo, m_hi = meter["rate_min_kg_ha"], meter["rate_max_kg_ha"]
    if m_lo <= lo and hi <= m_hi:
        return None
    parts = []
    if lo < m_lo:
        parts.append(
            f"below {m_lo:.1f} kg/ha it applies {m_lo:.1f} kg/ha or more (over-application)"
        )
    if hi > m_hi:
        parts.append(f"above {m_hi:.1f} kg/ha it applies at most {m_hi:.1f} kg/ha")
    message = (
        f"the NDVI rate curve asks for {lo:.1f}..{hi:.1f} kg/ha but '{machine.name}' can meter "
        f"only {m_lo:.1f}..{m_hi:.1f} kg/ha at {meter['speed_min_kmh']:g}.."
        f"{meter['speed_max_kmh']:g} km/h: " + "; ".join(parts)
    )
    return {"curve_kg_ha": [lo, hi], "meter": meter, "message": message}


def report(
    rows: list[dict[str, Any]], s: dict[str, Any], out: dict[str, Any]
) -> tuple[float, float]:
    """Seed 000 Table 3: theoretical vs monitored shaft speed per test speed."""
    out["shaft_table"] = shaft_table(rows, list(s["speed_bands_kmh"]))
    out["mean_relative_error_pct"] = out["shaft_table"]["mean_relative_error_pct"]
    out["paper"] = {
        "source": "seed 000 Table 3",
        "relative_error_pct": [2.0, 3.6, 3.8, 4.0],
        "mean_relative_error_pct": 3.35,
    }
    return 0.0, 0.0


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


register(
    ServerHooks(
        NAME,
        prepare=prepare,
        meter_conflict=curve_meter_conflict,
        report=report,
        cell_columns=("ndvi", "ndvi_raw", "target_rate_kg_ha", "applied_rate_kg_ha"),
        outcome=ndvi_outcome,
    )
)
