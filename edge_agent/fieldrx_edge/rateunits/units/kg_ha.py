"""kg/ha of product: the unit the agronomy counts in, sent as mass per area (DDI 6/7)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

from fieldrx_edge.rateunits.registry import Quantity, RateUnit, register


@register
class KgPerHa(RateUnit):
    name: ClassVar[str] = "kg/ha"
    label: ClassVar[str] = "kg/ha (mass)"
    quantity: ClassVar[Quantity] = "mass"
    order: ClassVar[int] = 0
    # ISO 11783-11 DDI 6 / 7, 1 mg/m^2: 1 kg/ha = 1e6 mg / 1e4 m^2 = 100 mg/m^2
    ddi_setpoint: ClassVar[int] = 6
    ddi_actual: ClassVar[int] = 7
    bits_per_unit: ClassVar[float] = 100.0

    def kg_per_unit(self, lot: Mapping[str, float]) -> float:
        return 1.0
