"""l/ha of a liquid product, sent as volume per area (DDI 1/2): l/ha = kg/ha / density."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

from fieldrx_edge.rateunits.registry import LotValue, Quantity, RateUnit, register


@register
class LitresPerHa(RateUnit):
    name: ClassVar[str] = "l/ha"
    label: ClassVar[str] = "l/ha (liquid, by volume)"
    quantity: ClassVar[Quantity] = "volume"
    order: ClassVar[int] = 10
    # the liquids a sprayer meters lie well within 0.05-5 kg/l (UAN-28 is 1.28)
    lot: ClassVar[tuple[LotValue, ...]] = (LotValue("density_kg_l", "density", "kg/l", 0.05, 5.0),)
    # ISO 11783-11 DDI 1 / 2, 0.01 mm^3/m^2: 1 l/ha = 1e6 mm^3 / 1e4 m^2 = 100 mm^3/m^2
    ddi_setpoint: ClassVar[int] = 1
    ddi_actual: ClassVar[int] = 2
    bits_per_unit: ClassVar[float] = 10_000.0

    def kg_per_unit(self, lot: Mapping[str, float]) -> float:
        return lot["density_kg_l"]
