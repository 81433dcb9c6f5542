"""What the implement can meter (seed 001 eq. 1-3): the meter a prescription is checked
against, from the machine or the request, and the cells a job's machine cannot meter.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from fieldrx_edge.metering import calibration_from_dict
from sqlalchemy.orm import Session

from fieldrx.agronomy.cells import FLAG_BITS
from fieldrx.agronomy.prescription import ATTENTION_MASK
from fieldrx.agronomy.rates import MeterCheck, check_meter_range
from fieldrx.db.models import Machine, Plan, Prescription, PrescriptionVersion
from fieldrx.services.prescriptions.params import RxError
from fieldrx.store import load_rates, load_seq_area


@dataclass
class MeterSpec:
    calibration: dict[str, Any]
    width_m: float
    speed_min_m_s: float
    speed_max_m_s: float

    def check(self) -> MeterCheck:
        return MeterCheck(
            calibration_from_dict(self.calibration),
            self.width_m,
            self.speed_min_m_s,
            self.speed_max_m_s,
        )

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def describe(self) -> dict[str, Any]:
        """The range and the speeds it assumes, for summaries (seed 001 eq. 1-3)."""
        lo, hi = self.check().range_kg_ha()
        return {
            "rate_min_kg_ha": round(lo, 3),
            "rate_max_kg_ha": round(hi, 3),
            "speed_min_kmh": round(self.speed_min_m_s * 3.6, 3),
            "speed_max_kmh": round(self.speed_max_m_s * 3.6, 3),
            "width_m": self.width_m,
            "calibration": self.calibration,
        }


def meter_spec(
    machine: Machine | None,
    plan: Plan,
    speed_min_kmh: float | None,
    speed_max_kmh: float | None,
    width_m: float | None,
    calibration: dict[str, Any] | None,
) -> MeterSpec | None:
    """What the implement can meter: the machine's, overridden by explicit values.

    None (no meter check) when neither a machine nor a speed range is given.
    Without a machine the calibration must be given: no meter is assumed.
    """
    if machine is None and speed_min_kmh is None and speed_max_kmh is None:
        return None
    if machine is not None:
        spec = MeterSpec(
            dict(machine.calibration),
            machine.width_m,
            machine.speed_min_m_s,
            machine.speed_max_m_s,
        )
    else:
        if calibration is None:
            raise RxError(
                "a speed range without machine_id needs calibration (the meter's "
                "q0 = a*r + b: slope_g_min_per_rpm, intercept_g_min, min_rpm, max_rpm): "
                "give machine_id or calibration"
            )
        spec = MeterSpec(
            dict(calibration),
            float((plan.params or {}).get("swath_width_m", 2.3)),
            0.8,
            2.5,
        )
    if speed_min_kmh is not None:
        spec.speed_min_m_s = speed_min_kmh / 3.6
    if speed_max_kmh is not None:
        spec.speed_max_m_s = speed_max_kmh / 3.6
    if width_m is not None:
        spec.width_m = width_m
    if calibration is not None:
        spec.calibration = calibration
    if not 0 < spec.speed_min_m_s <= spec.speed_max_m_s:
        raise RxError(
            f"speed range must satisfy 0 < min <= max, got {spec.speed_min_m_s * 3.6:g}.."
            f"{spec.speed_max_m_s * 3.6:g} km/h"
        )
    try:
        spec.check()
    except (KeyError, TypeError, ValueError) as exc:
        raise RxError(f"invalid metering calibration: {exc}") from exc
    return spec


def meter_of(rx: Prescription) -> MeterCheck | None:
    m = (rx.params or {}).get("meter")
    return None if not m else MeterSpec(**m).check()


def job_attention(
    session: Session, rx: Prescription, ver: PrescriptionVersion, machine: Machine
) -> dict[str, Any]:
    """Cells of a version that need the sender's confirmation before a job goes to ``machine``.

    A cell counts when its stored flags say no data / outside the meter range, or
    when the job's machine (its calibration, width and speed range, seed 001
    eq. 1-3) cannot meter its rate although the prescription was checked against
    another meter or none. Returns count, area and the first seq.
    """
    seq, rates, flags, _ = load_rates(session, ver.id)
    plan = session.get(Plan, rx.plan_id)
    if plan is None:
        raise LookupError(f"prescription {rx.id}: plan is gone")
    aseq, area = load_seq_area(session, plan.id)
    if not np.array_equal(aseq, seq):
        raise RxError("the plan's cells do not match the prescription's rates")
    spec = MeterSpec(
        dict(machine.calibration), machine.width_m, machine.speed_min_m_s, machine.speed_max_m_s
    )
    _, meter_flags, _ = check_meter_range(rates, spec.check())
    mask = ((flags & ATTENTION_MASK) != 0) | (meter_flags != 0)
    return {
        "count": int(mask.sum()),
        "area_m2": round(float(np.asarray(area)[mask].sum()), 3),
        "no_data": int(((flags & FLAG_BITS["no_data"]) != 0).sum()),
        "out_of_meter_range": int(
            (
                ((flags & (FLAG_BITS["below_meter_range"] | FLAG_BITS["above_meter_range"])) != 0)
                | (meter_flags != 0)
            ).sum()
        ),
        "above_nutrient_ceiling": int(((flags & FLAG_BITS["above_nutrient_ceiling"]) != 0).sum()),
        "at_curve_limit": int(((flags & FLAG_BITS["at_curve_limit"]) != 0).sum()),
        "seq": [int(x) for x in seq[mask][:50]],
        "meter": spec.describe(),
    }
