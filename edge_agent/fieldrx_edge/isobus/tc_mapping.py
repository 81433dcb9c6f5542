"""How the Task Controller maps a client's pool to the job: which setpoint drives the rate
and in which unit, and where the implement states its working width.

The job's rates are in its unit, kg/ha or l/ha (``RateUnits``); the product's density
(kg/l), carried by the job package with the product, converts between them. An implement
offers a settable setpoint mass per area (DDI 6, 1 mg/m^2) or volume per area (DDI 1,
0.01 mm^3/m^2): the one that needs no conversion is preferred, the other is used when the
density is known, and a pool that can be driven by neither is named with the reason (the
TC then activates it and alarms; ISO 11783-10 has no activation error for "valid but this
TC has no conversion", and refusing a valid pool makes some clients give up for good).

1 kg/ha = 1e6 mg / 1e4 m^2 = 100 mg/m^2; 1 l/ha = 1e6 mm^3 / 1e4 m^2 = 100 mm^3/m^2,
i.e. 10 000 bits of DDI 1 (resolutions from the isobus.net data dictionary, DDIs 1 and 6).

Working width (DDI 67, mm) is looked for on the setpoint's element and then on its parents
(most pools put the rate on a bin and the width on the boom); it may be a property (a
constant in the pool) or process data (read with a request value command after
activation), ISO 11783-10 Annex A.4 / A.5.
"""

from __future__ import annotations

from dataclasses import dataclass

from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.ddop import ELEMENT_DEVICE, Binding, DeviceDescriptor, Element

RATE_UNITS = ("kg/ha", "l/ha")


@dataclass(frozen=True)
class RateUnits:
    """The job's rate unit and the product's density (None: unknown)."""

    unit: str = "kg/ha"
    density_kg_l: float | None = None

    def __post_init__(self) -> None:
        if self.unit not in RATE_UNITS:
            raise ValueError(f"rate unit {self.unit!r} is not one of {list(RATE_UNITS)}")
        if self.density_kg_l is not None and not 0.05 <= self.density_kg_l <= 5.0:
            raise ValueError(f"product density {self.density_kg_l} kg/l is outside 0.05-5")

    def converts(self, kind: str) -> bool:
        """Whether a ``kind`` ("mass"/"volume") implement can take the job's rates."""
        native = "mass" if self.unit == "kg/ha" else "volume"
        return kind == native or self.density_kg_l is not None


@dataclass
class RateMap:
    kind: str
    setpoint: Binding | None
    actual: Binding | None
    error: str = ""


def _first(bs: list[Binding]) -> Binding | None:
    return bs[0] if bs else None


def choose_rate(dd: DeviceDescriptor, units: RateUnits) -> RateMap:
    """The setpoint the job's rates drive (see module docstring)."""
    mass = _first(dd.find(pdm.DDI_SETPOINT_MASS_PER_AREA, settable=True))
    vol = _first(dd.find(pdm.DDI_SETPOINT_VOLUME_PER_AREA, settable=True))
    order = [("volume", vol), ("mass", mass)] if units.unit == "l/ha" else []
    order += [("mass", mass), ("volume", vol)]
    for kind, b in order:
        if b is not None and units.converts(kind):
            ddi = pdm.DDI_ACTUAL_MASS_PER_AREA if kind == "mass" else pdm.DDI_ACTUAL_VOLUME_PER_AREA
            return RateMap(kind, b, _first(dd.find(ddi)))
    if vol is not None:
        why = "volume-rate implement (DDI 1) and a kg/ha job without a product density"
        return RateMap("volume", None, None, why)
    if mass is not None:
        why = "mass-rate implement (DDI 6) and an l/ha job without a product density"
        return RateMap("mass", None, None, why)
    return RateMap("mass", None, None, "no settable setpoint mass or volume per area (DDI 6 / 1)")


def to_raw(kind: str, rate: float, units: RateUnits) -> int:
    """A job rate in the setpoint DDI's resolution."""
    d = units.density_kg_l or 1.0
    if kind == "mass":
        kg_ha = rate if units.unit == "kg/ha" else rate * d
        return int(round(kg_ha * pdm.MG_M2_PER_KG_HA))
    l_ha = rate if units.unit == "l/ha" else rate / d
    return int(round(l_ha * pdm.DDI1_BITS_PER_L_HA))


def from_raw(kind: str, raw: int, units: RateUnits) -> float:
    """A DDI 6 / DDI 2 value in the job's unit (inverse of ``to_raw``)."""
    d = units.density_kg_l or 1.0
    if kind == "mass":
        kg_ha = raw / pdm.MG_M2_PER_KG_HA
        return kg_ha if units.unit == "kg/ha" else kg_ha / d
    l_ha = raw / pdm.DDI1_BITS_PER_L_HA
    return l_ha if units.unit == "l/ha" else l_ha * d


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
