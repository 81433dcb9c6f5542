"""How the Task Controller maps a client's pool to the job: which setpoint drives the rate
and in which unit, and where the implement states its working width.

The job's rates are in its unit (``fieldrx_edge.rateunits``: kg/ha, l/ha, ...); the
product lot's values carried by the job package (a liquid's density, ...) convert between
units through kg/ha. An implement offers a settable setpoint per area in one quantity:
mass (DDI 6, 1 mg/m^2), volume (DDI 1, 0.01 mm^3/m^2), ... (each unit's DDIs and
resolution are in its class). The one that needs no conversion is preferred, another is
used when the lot converts to it, and a pool that can be driven by none is named with the
reason (the TC then activates it and alarms; ISO 11783-10 has no activation error for
"valid but this TC has no conversion", and refusing a valid pool makes some clients give
up for good).

Working width (DDI 67, mm) is looked for on the setpoint's element and then on its parents
(most pools put the rate on a bin and the width on the boom); it may be a property (a
constant in the pool) or process data (read with a request value command after
activation), ISO 11783-10 Annex A.4 / A.5.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.ddop import ELEMENT_DEVICE, Binding, DeviceDescriptor, Element
from fieldrx_edge.rateunits.registry import (
    DEFAULT_UNIT,
    RateUnit,
    RateUnitError,
    convert,
    converts,
    unit_of,
    units,
)


@dataclass(frozen=True)
class RateUnits:
    """The job's rate unit and its product lot: the density (None: unknown) and any other
    values a unit converts through."""

    unit: str = DEFAULT_UNIT
    density_kg_l: float | None = None
    values: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        unit_of(self.unit)  # RateUnitError (a ValueError) naming the known units
        if self.density_kg_l is not None and not 0.05 <= self.density_kg_l <= 5.0:
            raise ValueError(f"product density {self.density_kg_l} kg/l is outside 0.05-5")

    def lot(self) -> dict[str, float]:
        out = dict(self.values)
        if self.density_kg_l is not None:
            out["density_kg_l"] = self.density_kg_l
        return out

    def job_unit(self) -> RateUnit:
        return unit_of(self.unit)

    def implement_unit(self, kind: str) -> RateUnit:
        """The unit of a ``kind`` (quantity: "mass", "volume", ...) implement's setpoint."""
        found = next((u for u in units() if u.quantity == kind), None)
        if found is None:
            raise RateUnitError(f"no rate unit meters {kind}")
        return found

    def converts(self, kind: str) -> bool:
        """Whether a ``kind`` implement can take the job's rates."""
        return converts(self.job_unit(), self.implement_unit(kind), self.lot())


@dataclass
class RateMap:
    kind: str  # the setpoint's quantity ("mass", "volume", ...)
    setpoint: Binding | None
    actual: Binding | None
    error: str = ""


def _first(bs: list[Binding]) -> Binding | None:
    return bs[0] if bs else None


def _article(word: str) -> str:
    # units are read letter by letter ("an l/ha job", "a kg/ha job")
    return "an" if word[:1].lower() in "aefhilmnorsx" else "a"


def choose_rate(dd: DeviceDescriptor, units_: RateUnits) -> RateMap:
    """The setpoint the job's rates drive (see module docstring)."""
    job = units_.job_unit()
    offered = [(u, _first(dd.find(u.ddi_setpoint, settable=True))) for u in units()]
    offered = [(u, b) for u, b in offered if b is not None]
    offered.sort(key=lambda ub: ub[0] is not job)  # the job's own unit first
    lot = units_.lot()
    for u, b in offered:
        if converts(job, u, lot):
            return RateMap(u.quantity, b, _first(dd.find(u.ddi_actual)))
    if offered:
        u = offered[0][0]
        missing = [v.label for w in (job, u) for v in w.lot if v.key not in lot]
        why = (
            f"{u.quantity}-rate implement (DDI {u.ddi_setpoint}) and {_article(job.name)} "
            f"{job.name} job without a product {' or '.join(dict.fromkeys(missing))}"
        )
        return RateMap(u.quantity, None, None, why)
    ddis = " / ".join(str(u.ddi_setpoint) for u in units())
    names = " or ".join(u.quantity for u in units())
    return RateMap("mass", None, None, f"no settable setpoint {names} per area (DDI {ddis})")


def to_raw(kind: str, rate: float, units_: RateUnits) -> int:
    """A job rate in the setpoint DDI's resolution."""
    u = units_.implement_unit(kind)
    return int(round(convert(rate, units_.job_unit(), u, units_.lot()) * u.bits_per_unit))


def from_raw(kind: str, raw: int, units_: RateUnits) -> float:
    """An actual-rate DDI value in the job's unit (inverse of ``to_raw``)."""
    u = units_.implement_unit(kind)
    return convert(raw / u.bits_per_unit, u, units_.job_unit(), units_.lot())


def width_binding(dd: DeviceDescriptor, element_id: int) -> Binding | None:
    """DDI 67 of ``element_id`` or of the nearest element above it (module docstring)."""
    seen: set[int] = set()
    eid = element_id
    while eid not in seen:
        seen.add(eid)
        for b in dd.find(pdm.DDI_ACTUAL_WORKING_WIDTH):
            if b.element_id == eid:
                return b
        el = dd.by_id.get(eid)
        if not isinstance(el, Element) or el.element_type == ELEMENT_DEVICE:
            return None
        eid = el.parent_id
    return None
