"""The one list of rate units: each unit is a class in ``rateunits/units/`` that registers
itself here.

A prescription's rates are stored and reasoned about as kg/ha of product: the nutrient
balance (seed 001 eq. 19-21), the meter's range (eq. 1-3), product tonnes and costs all
count mass. A rate unit is how the agronomist prescribes and how machines take the rates:
kg/ha as they are, l/ha for a liquid sent to a volume-rate implement. A unit that is not
mass converts through values of the product lot (``LotValue``: a liquid's density): one
unit per ha is ``kg_per_unit(lot)`` kg/ha. ISO 11783 carries each unit on its own pair of
process-data DDIs (setpoint and actual, ISO 11783-11), at its own resolution
(``bits_per_unit``: DDI value per 1 unit/ha).

Everything that lists or converts units asks this module: the API's accepted values and
the prescription form (``describe``; ``registry_json`` is the browser's copy, which
``scripts/gen-api.sh`` writes to ``frontend/src/api/generated/rate-units.json``), the job
package's check, the ISOXML writer and reader, the Task Controller's choice of setpoint,
the agent's records. Adding a unit is
adding a module to ``rateunits/units/``.

Standard library only: the server and the agent share it.
"""

from __future__ import annotations

import importlib
import json
import math
import pkgutil
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

UNITS_PACKAGE = "fieldrx_edge.rateunits.units"
DEFAULT_UNIT = "kg/ha"
Quantity = Literal["mass", "volume", "count"]


class RateUnitError(ValueError):
    """An unknown unit, or a lot that lacks (or has an impossible) value a unit needs; the
    message names the value and the range."""


@dataclass(frozen=True)
class LotValue:
    """One value of the product lot a unit needs to turn its rates into kg/ha."""

    key: str  # the product's field: "density_kg_l"
    label: str  # what the form shows: "density"
    unit: str  # "kg/l"
    lo: float  # plausible range, inclusive: a value outside is a typing error
    hi: float

    def describe(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "label": self.label,
            "unit": self.unit,
            "min": self.lo,
            "max": self.hi,
        }


class RateUnit:
    """A rate unit; subclasses set the class attributes and ``kg_per_unit``."""

    name: ClassVar[str]  # as the API, files and machines name it: "kg/ha"
    label: ClassVar[str]  # for forms: "kg/ha (mass)"
    quantity: ClassVar[Quantity]
    order: ClassVar[int] = 100
    lot: ClassVar[tuple[LotValue, ...]] = ()
    # True: the unit counts seeds, so its product is a seed lot, never a fertiliser (a
    # product with nutrients is refused, and no nutrient figures are worked out)
    seed_lot: ClassVar[bool] = False
    # ISO 11783-11 process data of the quantity: setpoint and actual per-area DDIs, and the
    # DDI value of 1 unit/ha (its resolution turned around)
    ddi_setpoint: ClassVar[int]
    ddi_actual: ClassVar[int]
    bits_per_unit: ClassVar[float]

    def kg_per_unit(self, lot: Mapping[str, float]) -> float:
        """kg/ha of product in 1 unit/ha, from a lot that ``check_lot`` accepted."""
        raise NotImplementedError

    def check_lot(
        self, lot: Mapping[str, Any] | None, what: str = "the product", only_given: bool = False
    ) -> dict[str, float]:
        """The lot values this unit needs, checked; ``RateUnitError`` names the missing or
        implausible one and where it was looked for (``what``). ``only_given``: check the
        values that are there, and let a missing one pass (a lot stated in part)."""
        got = lot or {}
        out: dict[str, float] = {}
        for v in self.lot:
            raw = got.get(v.key)
            if raw is None or raw == "":
                if only_given:
                    continue
                raise RateUnitError(
                    f"rate unit {self.name} needs the {v.label} of {what} "
                    f"({v.key}, {v.lo:g}-{v.hi:g} {v.unit})"
                )
            try:
                x = float(raw)
            except (TypeError, ValueError):
                raise RateUnitError(
                    f"rate unit {self.name}: the {v.label} of {what} ({v.key}) {raw!r} is not"
                    " a number"
                ) from None
            if not (math.isfinite(x) and v.lo <= x <= v.hi):
                raise RateUnitError(
                    f"rate unit {self.name}: the {v.label} of {what} ({v.key}) {x:g} {v.unit}"
                    f" is outside {v.lo:g}-{v.hi:g} {v.unit}"
                )
            out[v.key] = x
        return out

    def known(self, lot: Mapping[str, Any] | None) -> bool:
        """Whether the lot holds every value the unit needs (then it converts to kg/ha)."""
        try:
            self.check_lot(lot)
        except RateUnitError:
            return False
        return True

    def to_kg_ha(self, rate: float, lot: Mapping[str, Any] | None) -> float:
        return rate * self.kg_per_unit(self.check_lot(lot))

    def from_kg_ha(self, rate_kg_ha: float, lot: Mapping[str, Any] | None) -> float:
        return rate_kg_ha / self.kg_per_unit(self.check_lot(lot))

    def describe(self) -> dict[str, Any]:
        """The unit as the API and the prescription form see it."""
        return {
            "name": self.name,
            "label": self.label,
            "quantity": self.quantity,
            "lot": [v.describe() for v in self.lot],
            "seed_lot": self.seed_lot,
            "ddi_setpoint": self.ddi_setpoint,
            "ddi_actual": self.ddi_actual,
        }


_UNITS: dict[str, RateUnit] = {}
_discovered: list[bool] = []


def register(cls: type[RateUnit]) -> type[RateUnit]:
    """Class decorator: the unit's one registration."""
    if cls.name in _UNITS and type(_UNITS[cls.name]) is not cls:
        raise ValueError(f"rate unit {cls.name!r} registered twice")
    _UNITS[cls.name] = cls()
    return cls


def _discover() -> None:
    if _discovered:
        return
    package = importlib.import_module(UNITS_PACKAGE)
    for info in pkgutil.iter_modules(package.__path__):
        importlib.import_module(f"{UNITS_PACKAGE}.{info.name}")
    _discovered.append(True)


def units() -> list[RateUnit]:
    """Every registered unit, in list order (kg/ha first)."""
    _discover()
    return sorted(_UNITS.values(), key=lambda u: (u.order, u.name))


def names() -> tuple[str, ...]:
    return tuple(u.name for u in units())


def unit_of(name: str | None) -> RateUnit:
    """The unit called ``name`` (None or "": kg/ha); ``RateUnitError`` names the known ones."""
    _discover()
    try:
        return _UNITS[name or DEFAULT_UNIT]
    except KeyError:
        raise RateUnitError(f"rate unit {name!r} is not one of {list(names())}") from None


def by_setpoint_ddi(ddi: int) -> RateUnit | None:
    """The unit whose setpoint DDI is ``ddi`` (None: no registered unit uses it)."""
    return next((u for u in units() if u.ddi_setpoint == ddi), None)


def convert(rate: float, src: RateUnit, dst: RateUnit, lot: Mapping[str, Any] | None) -> float:
    """A rate in ``src`` as ``dst`` through kg/ha: both units' lot values must be known."""
    if src is dst:
        return rate
    return dst.from_kg_ha(src.to_kg_ha(rate, lot), lot)


def converts(src: RateUnit, dst: RateUnit, lot: Mapping[str, Any] | None) -> bool:
    return src is dst or (src.known(lot) and dst.known(lot))


def registry_json() -> str:
    """Every unit as the browser's forms read it (``scripts/gen-api.sh`` writes it): the
    prescription form's unit menu and lot inputs come from here, not a hand-written list."""
    return json.dumps({"rate_units": [u.describe() for u in units()]}, indent=2) + "\n"
